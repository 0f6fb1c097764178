"""Streaming runs: crash safety (real SIGKILL), resume, fingerprints, corrupt blocks, dask."""

from __future__ import annotations

import math
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
import runs

from engine import runner
from engine.grid import Tiling
from engine.io import manifest as io_manifest
from engine.io.netcdf import read_info
from engine.plan import plan_from_survey
from engine.runner import RunError, run_survey
from engine.surveyfile import parse_survey

ROOT = Path(__file__).resolve().parent.parent

# 4 x 100 x 33 x 100 = 1.32e6 points in 32 blocks of one storage chunk each
SURVEY = runs.gravity_survey("runner test")
SMALL = runs.gravity_survey("runner test", energy=10, lz=10)
#: The survey killed mid-run: 4 x 40 x 33 x 100 = 528,000 points in 16 blocks
KILLED = runs.gravity_survey("runner test", energy=40)
CHUNK = 1 << 16


def _env() -> dict[str, str]:
    return runs.env()


def _cli(*args: str) -> list[str]:
    return runs.cli(*args)


_same_content = runs.same_content


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory):
    """An uninterrupted run of KILLED (in this process)."""
    out = tmp_path_factory.mktemp("ref") / "ref.nc"
    run_survey(parse_survey(KILLED), out, block_points=CHUNK)
    return out


def test_sigkill_mid_run_then_resume_gives_identical_file(tmp_path, reference_run, capsys):
    (tmp_path / "s.toml").write_text(KILLED)
    parts = tmp_path / "out.nc.parts"
    # the option's old spelling, still accepted: the file must equal the --block-points one
    cmd = _cli("run", "s.toml", "-o", "out.nc", "-q", "--chunk-points", str(CHUNK))
    kills = 0
    for target in (2, 6, 11):  # kill three times at increasing progress (of 16 blocks)
        proc = subprocess.Popen(cmd, cwd=tmp_path, env=_env(), stderr=subprocess.PIPE)
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None:
            if parts.is_dir() and len(list(parts.glob("b*.chunks"))) >= target:
                proc.send_signal(signal.SIGKILL)
                kills += 1
                break
            time.sleep(0.005)
        proc.wait(timeout=60)
        assert not (tmp_path / "out.nc").exists() or proc.returncode == 0
    assert kills >= 2, "the run finished before it could be killed"
    stored = len(list(parts.glob("b*.chunks")))
    info = runs.here(tmp_path, capsys, "info", "out.nc")
    assert info.returncode == 0 and "unfinished" in info.stdout, info.stdout + info.stderr
    done = subprocess.run(
        cmd,
        cwd=tmp_path,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert not parts.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.nc", "s.toml"]
    _same_content(tmp_path / "out.nc", reference_run)
    assert stored >= 3


def _kill_after(n: int):
    count = {"n": 0}

    def hook(index: int) -> None:
        count["n"] += 1
        if count["n"] >= n:
            raise KeyboardInterrupt  # stands for a crash after n stored blocks

    return hook


def test_resume_refuses_another_survey_or_engine_version(tmp_path, monkeypatch):
    out = tmp_path / "o.nc"
    s = parse_survey(SMALL.replace("num = 33", "num = 330"))
    with pytest.raises(KeyboardInterrupt):
        run_survey(s, out, block_points=CHUNK, on_block=_kill_after(1))
    other = parse_survey(SMALL.replace("num = 33", "num = 330").replace("runner test", "x"))
    with pytest.raises(RunError, match="another survey"):
        run_survey(other, out, block_points=CHUNK)
    monkeypatch.setattr(io_manifest, "__version__", "9.9.9")  # the version the store records
    with pytest.raises(RunError, match="engine version"):
        run_survey(s, out, block_points=CHUNK)
    assert not out.exists()


def test_corrupt_block_is_reported_and_recomputed(tmp_path):
    s = parse_survey(SMALL.replace("num = 33", "num = 330"))
    ref = run_survey(s, tmp_path / "ref.nc", block_points=CHUNK)
    assert ref.blocks_total >= 3
    out = tmp_path / "o.nc"
    with pytest.raises(KeyboardInterrupt):
        run_survey(s, out, block_points=CHUNK, on_block=_kill_after(2))
    blocks = sorted((tmp_path / "o.nc.parts").glob("b*.chunks"))
    assert len(blocks) == 2
    blocks[0].write_bytes(blocks[0].read_bytes()[:100])  # truncated: a torn write
    (tmp_path / "o.nc.parts" / "b00000099.npz.tmp").write_bytes(b"stale")
    warnings: list[str] = []
    stats = run_survey(s, out, block_points=CHUNK, warn=warnings.append)
    assert any("corrupt" in w and blocks[0].name in w for w in warnings)
    assert stats.blocks_reused == 1
    _same_content(out, tmp_path / "ref.nc")


def test_completed_output_is_not_recomputed_and_info_reports_it(tmp_path, capsys):
    s = parse_survey(SMALL)
    out = tmp_path / "o.nc"
    stats = run_survey(s, out)
    with pytest.raises(runner.AlreadyComplete):
        run_survey(s, out)
    info = read_info(out)
    assert info["complete"] and info["attrs"]["survey_fingerprint"] == io_manifest.fingerprint(
        plan_from_survey(s)
    )
    assert sum(info["counts"].values()) == stats.points
    assert info["counts"]["bounded"] == int(stats.counts[1])
    from engine import cli

    assert cli.main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "complete" in text and "runner test" in text and "[axes.alpha]" in text
    assert cli.main(["info", str(tmp_path / "missing.nc")]) == 2


def test_validate_prints_size_and_time(tmp_path, capsys):
    from engine import cli

    (tmp_path / "s.toml").write_text(SURVEY)
    assert cli.main(["validate", str(tmp_path / "s.toml")]) == 0
    out = capsys.readouterr().out
    assert "1,320,000 points" in out and "MB" in out and "time" in out
    assert list(tmp_path.iterdir()) == [tmp_path / "s.toml"]


def _needed_mb(err: str) -> tuple[float, float, float]:
    """(total, blocks, output) [MB] of a refusal for lack of disk space."""
    m = re.search(
        r"needs up to ([0-9.]+) MB of disk \(([0-9.]+) [kM]B for the blocks still to compute "
        r"\+ ([0-9.]+) MB for the output",
        err,
    )
    assert m, err
    unit = 1.0 if " MB for the blocks" in err else 1e-3
    return float(m.group(1)), float(m.group(2)) * unit, float(m.group(3))


def _padded(shape: tuple[int, ...], chunk: tuple[int, ...]) -> int:
    """Values stored for a grid of ``shape`` in chunks of ``chunk``: the chunks at the end of
    an axis whole, as HDF5 and Zarr store them."""
    return math.prod(-(-n // c) * c for n, c in zip(shape, chunk, strict=True))


#: Bytes a point of the closed form's per-point variables (orbit_class int8, six float64).
POINT = 1 + 6 * 8


def test_refuses_a_grid_too_large_for_the_disk(tmp_path, capsys, monkeypatch):
    """The check counts the blocks and the output merged beside them, as they are stored:
    4 x 100 x 33 x 100 points in chunks of 4 x 25 x 17 x 25 hold 4 x 100 x 34 x 100 values
    (the last h chunk padded), 49 bytes each, in the blocks and in the output, which also
    holds r_circ and V_min on (alpha, h, Lz) and up to ~2.5 MB of metadata."""
    from engine import cli

    (tmp_path / "s.toml").write_text(SURVEY)
    monkeypatch.setattr(runner.shutil, "disk_usage", lambda p: SimpleNamespace(free=1000))
    assert cli.main(["run", str(tmp_path / "s.toml"), "-o", str(tmp_path / "o.nc")]) == 2
    err = capsys.readouterr().err
    tiling = Tiling.for_grid((4, 100, 33, 100))
    assert tiling.chunk == (4, 25, 17, 25)
    values = POINT * _padded(tiling.shape, tiling.chunk) / 1e6
    families = 2 * 8 * 4 * 33 * 100 / 1e6
    total, blocks, output = _needed_mb(err)
    assert values <= blocks <= values * 1.01 + 0.25, err  # framing, journal, manifest
    assert values + families <= output <= values * 1.01 + families + 2.5, err
    assert abs(total - (blocks + output)) <= 1.0
    assert "blocks still to compute" in err and "output merged beside them" in err
    assert "1 kB free" in err and "--force" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_space_check_counts_only_the_blocks_still_to_compute(tmp_path, capsys, monkeypatch):
    """A resumed run needs room for its missing blocks and the output, not for the blocks it
    already stored (after a disk-full stop the rerun is not refused by the same check)."""
    from engine import cli

    s = parse_survey(SMALL.replace("num = 33", "num = 330"))
    (tmp_path / "s.toml").write_text(SMALL.replace("num = 33", "num = 330"))
    out = tmp_path / "o.nc"
    with pytest.raises(KeyboardInterrupt):
        run_survey(s, out, block_points=CHUNK, on_block=_kill_after(2))
    args = ["run", str(tmp_path / "s.toml"), "-o", str(out), "-q"]
    monkeypatch.setattr(runner.shutil, "disk_usage", lambda p: SimpleNamespace(free=10**6))
    assert cli.main(args) == 2
    need_now, blocks, _ = _needed_mb(capsys.readouterr().err)
    tiling = Tiling.for_grid(s.shape, CHUNK)
    stored = [int(p.stem[1:]) for p in (tmp_path / "o.nc.parts").glob("b*.chunks")]
    assert len(stored) == 2
    left = [i for i in range(tiling.nblocks) if i not in stored]
    sizes = [tuple(x.stop - x.start for x in tiling.slices(i)) for i in left]
    want = POINT * sum(_padded(b, tiling.chunk) for b in sizes) / 1e6
    assert want <= blocks <= want * 1.01 + 0.25
    free = int((need_now + 0.01) * 1e6)
    monkeypatch.setattr(runner.shutil, "disk_usage", lambda p: SimpleNamespace(free=free))
    assert cli.main(args) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.nc", "s.toml"]


def test_chunk_points_flag_must_be_positive(tmp_path, capsys):
    from engine import cli

    with pytest.raises(SystemExit) as e:
        cli.main(["run", "x.toml", "--chunk-points", "0"])
    assert e.value.code == 2
    assert "--chunk-points" in capsys.readouterr().err


def test_block_points_flag_must_be_positive(tmp_path, capsys):
    from engine import cli

    with pytest.raises(SystemExit) as e:
        cli.main(["run", "x.toml", "--block-points", "0"])
    assert e.value.code == 2
    assert "--block-points" in capsys.readouterr().err


def _peak_rss_mb(tmp_path: Path, *surveys: str) -> list[float]:
    """The peak resident memory [MB] of one fresh interpreter after running each survey in
    turn (ru_maxrss only grows: each figure is the peak so far)."""
    code = f"""
import resource, sys
from engine.surveyfile import parse_survey
from engine.runner import run_survey
for i, path in enumerate(sys.argv[1:]):
    run_survey(parse_survey(open(path).read()), path + ".nc", block_points={CHUNK})
    print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""
    paths = []
    for i, text in enumerate(surveys):
        paths.append(tmp_path / f"s{i}.toml")
        paths[-1].write_text(text)
    proc = subprocess.run(
        [sys.executable, "-c", code, *map(str, paths)],
        env=_env(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    return [int(line) / 1024 for line in proc.stdout.split()[-len(surveys) :]]


def test_peak_memory_is_bounded_by_the_block_not_the_grid(tmp_path):
    """A 1.32e6-point survey (9 bytes x 9 variables per point: 98 MB of results) peaks within
    a few blocks' worth (64k points, ~5 MB each) of a 13,200-point one run just before it in
    the same interpreter."""
    small, large = _peak_rss_mb(tmp_path, SMALL, SURVEY)
    assert large - small < 40, (small, large)


def test_complevel_changes_storage_not_values(tmp_path):
    import netCDF4

    s = parse_survey(SMALL)
    run_survey(s, tmp_path / "z1.nc", compression="zlib")
    run_survey(s, tmp_path / "z0.nc", complevel=0)
    with netCDF4.Dataset(tmp_path / "z1.nc") as a, netCDF4.Dataset(tmp_path / "z0.nc") as b:
        assert a["period"].filters()["zlib"] and a["period"].filters()["complevel"] == 1
        assert not b["period"].filters()["zlib"]
    _same_content(tmp_path / "z1.nc", tmp_path / "z0.nc")
    with pytest.raises(RunError, match="complevel"):
        run_survey(s, tmp_path / "bad.nc", complevel=12)

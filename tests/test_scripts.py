"""Every script in scripts/ runs: each in its --tiny mode (seconds on a warm compile cache), in a
fresh interpreter, writing into a temporary folder; the two helper modules through their
functions. heyoka and Chromium may be absent: the scripts then say so and run the rest."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "scripts"
sys.path.insert(0, str(SCRIPTS))

import figure_cli  # noqa: E402
import readme_block  # noqa: E402

#: script -> (extra arguments, with {tmp} for the temporary folder; text its output must hold).
TINY = {
    "bench_effects.py": ([], "generic scalar run kernel / hand-written DP5"),
    "bench_exact.py": ([], "load average"),
    "bench_fates.py": ([], "2-thread speedup of the fate map"),
    "bench_integrators.py": ([], "heyoka"),
    "bench_slide.py": ([], "2-thread speedup"),
    "bench_storage.py": ([], "Zarr / netCDF wall time, same round"),
    "bytes_per_variable.py": ([], "bytes/point"),
    "energy_drift.py": (["--out", "{tmp}/drift.png"], "wrote"),
    "fate_figures.py": (["--out", "{tmp}"], ""),
    "figures.py": (["--out", "{tmp}"], ""),
    "integrator_peers.py": ([], "scipy DOP853"),
    "look_figures.py": (["--out", "{tmp}"], "wrote"),
    "slide_figures.py": (["--out", "{tmp}"], "launches in"),
    "work_precision.py": (["--out", "{tmp}/wp.nc", "--png", "{tmp}/wp.png"], "wrote"),
}
#: Modules the scripts import, not scripts themselves (figure_cli and readme_block tested below
#: through their functions; bench_common through the benchmarks' tiny runs above).
HELPERS = {"figure_cli.py", "readme_block.py", "bench_common.py"}


def test_every_script_is_run_here():
    assert {p.name for p in SCRIPTS.glob("*.py")} == set(TINY) | HELPERS


@pytest.mark.parametrize("script", sorted(TINY))
def test_script_runs_in_its_tiny_mode(script, tmp_path):
    extra, expect = TINY[script]
    args = [a.format(tmp=tmp_path) for a in extra]
    res = subprocess.run(
        [sys.executable, str(SCRIPTS / script), "--tiny", *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    assert expect in res.stdout, res.stdout[-2000:]
    if "{tmp}" in " ".join(extra):
        assert any(p.suffix in (".png", ".nc") for p in tmp_path.rglob("*")), "nothing written"


def test_readme_block_replaces_only_its_block(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("a\n<!-- t: start -->\nold\n<!-- t: end -->\nb\n")
    readme_block.update_readme("t", "new", readme)
    assert readme.read_text() == "a\n<!-- t: start -->\nnew\n<!-- t: end -->\nb\n"
    with pytest.raises(SystemExit, match="no <!-- u: start -->"):
        readme_block.update_readme("u", "x", readme)


def test_figure_cli_runs_a_command_and_stops_on_failure(tmp_path, capsys):
    small = figure_cli.shrunk(ROOT / "surveys" / "slip_map.toml", tmp_path)
    assert "num = 3" in small.read_text()
    figure_cli.conesurvey("validate", small)
    assert "valid" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="conesurvey validate failed with status 2"):
        figure_cli.conesurvey("validate", tmp_path / "missing.toml")


def test_the_benchmarks_timing_loop_interleaves_and_keeps_the_best():
    """bench_common.interleaved: each round calls every function once, in turn; the best time
    of each by each clock (a fake clock here: its readings are the test's own numbers)."""
    from bench_common import first_calls, interleaved, verdict

    order = []
    ticks = iter([0.0, 5.0, 5.0, 6.0, 10.0, 12.0, 12.0, 19.0, 20.0, 23.0, 23.0, 24.0])
    fns = {"a": lambda: order.append("a"), "b": lambda: order.append("b")}
    best = interleaved(fns, 3, (lambda: next(ticks),))
    assert order == ["a", "b"] * 3
    assert best == {"a": (2.0,), "b": (1.0,)}  # a: 5, 2, 3; b: 1, 7, 1
    seconds, results = first_calls({"x": lambda: 42})
    assert results == {"x": 42} and seconds["x"] >= 0.0
    assert (verdict(2.0, 2.0), verdict(1.9, 2.0)) == ("met", "MISSED")


def test_bench_storage_times_the_three_ways_through_the_page_cache(tmp_path):
    """``bench_storage.py --page-cache``: the rows docs/output.md ("The page cache") quotes,
    each once in --tiny (64 MiB), the files it wrote removed."""
    args = ["--page-cache", "--tiny", "--dir", str(tmp_path)]
    res = subprocess.run(
        [sys.executable, str(SCRIPTS / "bench_storage.py"), *args],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    for how in ("cache", "given back", "O_DIRECT"):
        assert re.search(rf"{how}: [\d.]+ s wall, [\d.]+ s system, [\d.]+ GB/s", res.stdout), (
            res.stdout
        )
    assert not list(tmp_path.rglob("*.tmp")), "a timed file was left behind"

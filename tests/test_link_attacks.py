"""Links, devices and a user's files where conesurvey writes: a hard link planted at
``OUT.lock`` is never written through (``run`` and ``convert``), ``--overwrite`` never replaces a
FIFO or a device node (``convert``, ``plot``, ``report``, as ``run``), and files a user puts in
``OUT.parts`` are left alone."""

from __future__ import annotations

import os
import stat

import pytest
import runs

from engine.runner import run_survey
from engine.surveyfile import parse_survey

SURVEY = runs.free_fall_survey("link attacks")


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    d = tmp_path_factory.mktemp("result")
    run_survey(parse_survey(SURVEY), d / "r.nc")
    return d / "r.nc"


@pytest.fixture
def work(tmp_path, monkeypatch):
    (tmp_path / "s.toml").write_text(SURVEY)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def victim(work):
    p = work / "victim.txt"
    p.write_text("precious\n")
    return p


# --- 5. a hard link at OUT.lock ------------------------------------------------------------------


def test_run_never_writes_through_a_hard_linked_lock(work, capsys):
    v = victim(work)
    os.link(v, work / "out.nc.lock")
    r = runs.here(work, capsys, "run", "s.toml", "-o", "out.nc", "-q")
    assert r.returncode == 2 and "hard link" in r.stderr, r
    assert v.read_text() == "precious\n"
    assert not (work / "out.nc").exists()


@pytest.mark.parametrize("which", ["out.zarr.lock", "r.nc.lock"])
def test_convert_never_writes_through_a_hard_linked_lock(work, capsys, result, which):
    pytest.importorskip("zarr")
    (work / "r.nc").write_bytes(result.read_bytes())
    v = victim(work)
    os.link(v, work / which)
    r = runs.here(work, capsys, "convert", "r.nc", "out.zarr")
    assert r.returncode == 2 and "hard link" in r.stderr, r
    assert v.read_text() == "precious\n"
    assert not (work / "out.zarr").exists()


# --- 6. --overwrite never replaces a FIFO or a device ---------------------------------------


def _fifo(p):
    os.mkfifo(p)


def _device(p):
    if os.geteuid() != 0:
        pytest.skip("creating a device node needs root")  # the FIFO case still runs
    os.mknod(p, 0o666 | stat.S_IFCHR, os.makedev(1, 3))  # a /dev/null of our own


def _special(p) -> bool:
    mode = os.lstat(p).st_mode
    return stat.S_ISFIFO(mode) or stat.S_ISCHR(mode)


@pytest.mark.parametrize("plant", [_fifo, _device])
@pytest.mark.parametrize("target", ["out.zarr", "out.png", "out.html"])
def test_overwrite_never_replaces_a_fifo_or_a_device(work, capsys, result, plant, target):
    (work / "r.nc").write_bytes(result.read_bytes())
    plant(work / target)
    if target == "out.zarr":
        pytest.importorskip("zarr")
        args = ("convert", "r.nc", target, "--overwrite")
    elif target == "out.png":
        pytest.importorskip("matplotlib")
        args = ("plot", "r.nc", "-o", target, "--overwrite")
    else:
        args = ("report", "r.nc", "-o", target, "--overwrite")
    r = runs.here(work, capsys, *args)
    assert r.returncode in (1, 2) and "refusing to replace it" in r.stderr, r
    assert "Traceback" not in r.stderr
    assert _special(work / target)


# --- 8. files a user puts in OUT.parts ---------------------------------------------------------


class Stop(Exception):
    pass


def _stop(i: int) -> None:
    raise Stop


@pytest.mark.parametrize("out", ["out.nc", "out.zarr"])
def test_a_users_files_in_the_parts_directory_are_left_alone(work, capsys, out):
    if out.endswith(".zarr"):
        pytest.importorskip("zarr")
    survey = parse_survey(runs.free_fall_survey("parts", energy=40))
    with pytest.raises(Stop):
        run_survey(survey, work / out, block_points=16, on_block=_stop)
    parts = work / f"{out}.parts"
    (parts / "notes.txt").write_text("mine\n")
    stats = run_survey(survey, work / out, block_points=16, warn=print)
    assert stats.blocks_reused >= 1
    assert (parts / "notes.txt").read_text() == "mine\n"
    assert sorted(os.listdir(parts)) == ["notes.txt"]
    assert "notes.txt" in capsys.readouterr().out


# --- 13. convert: a source without a checksum; a killed conversion's temporary -----------------

KILL_IN_CONVERT = """
import os, signal, sys
import engine.io.convert as c
from engine.cli import main
def killed(*args, **kwargs):  # the output is written, not yet renamed
    os.kill(os.getpid(), signal.SIGKILL)
c._check_source = killed
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("out", ["out.zarr", "out2.nc"])
def test_a_killed_conversions_temporary_is_removed_by_the_next(work, capsys, result, out):
    import subprocess
    import sys

    pytest.importorskip("zarr")
    src = "r.nc" if out.endswith(".zarr") else "r.zarr"
    if src == "r.nc":
        (work / "r.nc").write_bytes(result.read_bytes())
    else:
        assert runs.here(work, capsys, "convert", str(result), "r.zarr").returncode == 0
    proc = subprocess.run(
        [sys.executable, "-c", KILL_IN_CONVERT, "convert", src, out],
        cwd=work, env=runs.env(), capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == -9, proc.stderr
    left = [n for n in os.listdir(work) if n.startswith(out + ".") and n.endswith(".tmp")]
    assert len(left) == 1, os.listdir(work)
    r = runs.here(work, capsys, "convert", src, out)
    assert r.returncode == 0, r.stderr
    assert not [n for n in os.listdir(work) if n.endswith(".tmp")], os.listdir(work)


def test_a_source_without_a_checksum_is_converted_as_unverified(work, capsys, result):
    import netCDF4

    pytest.importorskip("zarr")
    (work / "r.nc").write_bytes(result.read_bytes())
    with netCDF4.Dataset(work / "r.nc", "a") as nc:
        nc.delncattr("content_checksum")  # stripped: damage could hide behind a fresh one
    r = runs.here(work, capsys, "convert", "r.nc", "out.zarr")
    assert r.returncode == 0 and "unverified source" in r.stdout, r
    r = runs.here(work, capsys, "convert", "out.zarr", "back.nc")  # the state is carried
    assert r.returncode == 0, r
    for path in ("out.zarr", "back.nc"):
        info = runs.here(work, capsys, "info", path)
        assert "unverified" in info.stdout or _attr(work / path), info.stdout


def _attr(path) -> bool:
    from engine.io.results import open_result

    with open_result(path) as res:
        return "not verified" in str(res.ds.attrs.get("conesurvey_unverified_source", ""))


# --- 7. output names checked before anything is written ----------------------------------------


@pytest.mark.parametrize("name", [b"out\xff.nc", b"a" * 241 + b".nc", b"b" * 236 + b".zarr"])
def test_an_output_name_that_cannot_be_written_is_refused_first(work, name):
    import subprocess

    if name.endswith(b".zarr"):
        pytest.importorskip("zarr")
    args = [*map(os.fsencode, runs.cli("run", "s.toml", "-q")), b"-o", name]
    proc = subprocess.run(args, cwd=work, env=runs.env(), capture_output=True, timeout=300)
    err = proc.stderr.decode(errors="replace")
    assert proc.returncode == 2 and "output name" in err, err
    assert "s.toml:" not in err and "Traceback" not in err, err  # the survey is not blamed
    assert runs.listing(work) == ["s.toml"]

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

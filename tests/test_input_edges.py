"""Input edges of the command line (issue 11): files that are not regular, outputs that are the
survey, texts the output cannot hold, and definitions ``validate`` must refuse like ``run``.

Each case runs the command (in a subprocess where a bug could hang: FIFOs and devices) and
checks the exit status, the one-line message and that nothing was written."""

from __future__ import annotations

import os
import subprocess

import pytest
import runs

SURVEY = runs.free_fall_survey("edges")


@pytest.fixture
def workdir(tmp_path):
    (tmp_path / "s.toml").write_text(SURVEY)
    return tmp_path


def refused(cwd, *args, timeout=60, capsys=None):
    """Run the command (here if ``capsys``); it must exit 2 with one error line and no
    traceback."""
    proc = (
        runs.run(cwd, *args, timeout=timeout) if capsys is None else runs.here(cwd, capsys, *args)
    )
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    assert proc.stderr.startswith("conesurvey: error: ") and "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1, proc.stderr
    return proc.stderr


@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_device_is_not_read(workdir, command):
    """/dev/zero would be read until memory runs out: refused at once, nothing written."""
    err = refused(workdir, command, "/dev/zero", timeout=30)
    assert "/dev/zero is a device" in err
    assert runs.listing(workdir) == ["s.toml"]


@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_fifo_does_not_hang(workdir, command):
    os.mkfifo(workdir / "pipe.toml")
    err = refused(workdir, command, "pipe.toml", "-q" if command == "run" else "--", timeout=30)
    assert "pipe.toml is a FIFO" in err
    assert runs.listing(workdir) == ["pipe.toml", "s.toml"]


def test_an_oversized_file_is_refused_after_reading_its_cap(workdir, capsys):
    (workdir / "big.toml").write_text(SURVEY + "#" * (5 << 20) + "\n")
    err = refused(workdir, "validate", "big.toml", capsys=capsys)
    assert "big.toml: larger than 4 MiB" in err


@pytest.mark.parametrize("spelling", ["s.toml", "./sub/../s.toml", "link.toml", "hard.toml"])
def test_the_output_may_not_be_the_survey_file(workdir, spelling, capsys):
    """Also with --overwrite, under another spelling, through a link or a hard link."""
    (workdir / "sub").mkdir()
    (workdir / "link.toml").symlink_to("s.toml")
    os.link(workdir / "s.toml", workdir / "hard.toml")
    before = runs.listing(workdir)
    err = refused(workdir, "run", "s.toml", "-o", spelling, "--overwrite", "-q", capsys=capsys)
    assert "is the survey file itself" in err
    assert (workdir / "s.toml").read_text() == SURVEY
    assert runs.listing(workdir) == before


def test_a_title_with_nul_is_refused_naming_the_key(workdir, capsys):
    (workdir / "nul.toml").write_text(SURVEY.replace('title = "edges"', 'title = "a\\u0000b"'))
    for command in ("validate", "run"):
        err = refused(workdir, command, "nul.toml", capsys=capsys)
        assert "nul.toml: title: must not contain NUL" in err
    assert runs.listing(workdir) == ["nul.toml", "s.toml"]


def test_validate_refuses_what_run_refuses_and_a_refused_run_leaves_no_debris(workdir, capsys):
    """The issue's case: rk45 with rtol = 0.01 passed validate, run refused it but left
    OUT.parts, and then refused the corrected survey as "another survey"."""
    bad = SURVEY.replace('title = "edges"', 'title = "edges"\nmethod = "rk45"\nrtol = 0.01')
    (workdir / "rk.toml").write_text(bad)
    for command in ("validate", "run"):
        extra = ["-q"] if command == "run" else []
        err = refused(workdir, command, "rk.toml", *extra, capsys=capsys)
        assert "rk.toml: rtol: must lie in [1e-14, 0.001] for the integrator rk45, got 0.01" in err
    assert runs.listing(workdir) == ["rk.toml", "s.toml"]
    (workdir / "rk.toml").write_text(bad.replace("rtol = 0.01", "rtol = 1e-6"))
    ok = runs.here(workdir, capsys, "run", "rk.toml", "-q")
    assert ok.returncode == 0, ok.stderr
    assert runs.listing(workdir) == ["rk.nc", "rk.toml", "s.toml"]


def test_a_method_that_cannot_honour_the_scene_is_refused_by_validate(workdir, capsys):
    text = SURVEY.replace("g = 0.0", "g = 0.0\nc_rr = 1e-3").replace(
        'title = "edges"', 'title = "edges"\nmethod = "symplectic"'
    )
    (workdir / "sy.toml").write_text(text)
    err = refused(workdir, "validate", "sy.toml", capsys=capsys)
    assert "sy.toml: method: method 'symplectic' cannot honour" in err
    assert "the scene's rolling_resistance" in err


@pytest.mark.parametrize(
    "scene", ["M = 1e308", "M = 5e-324", "a = 1e308", "k = 1e300"], ids=lambda s: s.split()[0]
)
def test_extreme_scene_values_give_a_result_or_a_clear_error(workdir, scene, capsys):
    """Over- and underflow of A, B, C (issue 9 owns the physics): here only no traceback."""
    (workdir / "x.toml").write_text(SURVEY.replace("g = 0.0", f"g = 9.81\n{scene}"))
    proc = runs.here(workdir, capsys, "run", "x.toml", "-q")  # an exception fails the test
    assert proc.returncode in (0, 2), proc.stderr
    assert "Traceback" not in proc.stderr


def test_info_of_a_fifo_or_device_does_not_hang(workdir):
    os.mkfifo(workdir / "out.nc")
    proc = subprocess.run(
        runs.cli("info", "out.nc"),
        cwd=workdir,
        env=runs.env(),
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr


def test_an_output_path_that_is_a_fifo_is_never_replaced(workdir):
    """(A device such as /dev/null is refused the same way: it is not a regular file.)"""
    os.mkfifo(workdir / "out.nc")
    err = refused(workdir, "run", "s.toml", "-o", "out.nc", "--overwrite", "-q", timeout=30)
    assert "out.nc is a FIFO (named pipe); give a file name" in err
    assert runs.listing(workdir) == ["out.nc", "s.toml"]
    assert not (workdir / "out.nc").is_file()

"""The conesurvey command line (in-process and as a subprocess) and the progress reporter."""

from __future__ import annotations

import io
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import engine
from engine import cli
from engine.progress import Progress, format_duration, format_rate

ROOT = Path(__file__).resolve().parent.parent

SURVEY = """\
title = "CLI test"

[scene]
g = 0.0

[axes.alpha]
values = [0.5, 1.0]

[axes.energy]
start = -0.3
stop = 0.3
num = 7

[axes.h]
values = [-2.0, 2.0]

[axes.Lz]
values = [-0.5, 0.5]
"""

BAD_SURVEY = SURVEY.replace("values = [0.5, 1.0]", "values = [0.5, 2.0]")


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "small.toml").write_text(SURVEY, encoding="utf-8")
    (tmp_path / "bad.toml").write_text(BAD_SURVEY, encoding="utf-8")
    return tmp_path


def listing(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


# --- help -------------------------------------------------------------------------------------


def test_help_texts(capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "usage: conesurvey" in out and "run" in out
    assert "example:" in out and "conesurvey run surveys/" in out
    with pytest.raises(SystemExit) as info:
        cli.main(["run", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for option in ("SURVEY.toml", "--output", "--overwrite", "--quiet", "[axes.energy]"):
        assert option in out


def test_no_command_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as info:
        cli.main([])
    assert info.value.code == 2
    assert "conesurvey: error:" in capsys.readouterr().err


# --- successful runs --------------------------------------------------------------------------


def test_run_default_output_and_summary(workdir, capsys):
    assert cli.main(["run", "small.toml"]) == 0
    captured = capsys.readouterr()
    out_path = workdir / "small.nc"
    assert listing(workdir) == ["bad.toml", "small.nc", "small.toml"]
    with xr.open_dataset(out_path) as ds:
        ds.load()
    assert ds.attrs["survey_definition"] == SURVEY
    assert ds.attrs["title"] == "CLI test"
    assert " conesurvey run small.toml " in ds.attrs["history"]

    out = captured.out
    assert "CLI test" in out
    assert "alpha 2 x energy 7 x h 2 x Lz 2 = 56 points" in out
    classes = ds.orbit_class.values.ravel()
    for code, name in enumerate(engine.CLASS_NAMES):
        n = int((classes == code).sum())
        assert re.search(rf"^  {name}\s+{n:,}\s+{n / classes.size:.4f}$", out, re.M), name
    for name in ("r_min", "r_max", "r_circ", "period", "apsidal_angle", "mu_required"):
        values = ds[name].values
        finite = values[np.isfinite(values)]
        assert re.search(
            rf"^  {name}\s+{finite.min():.6g}\s+{finite.max():.6g}\s+{ds[name].units}$", out, re.M
        ), name
    assert re.search(r"^  time\s+\d+\.\d\d s computing", out, re.M)
    assert f"output  {out_path}" in out
    assert "56/56 points" in captured.err  # final progress line (stderr is not a TTY here)


def test_run_explicit_output(workdir, capsys):
    (workdir / "sub").mkdir()
    assert cli.main(["run", "small.toml", "-o", "sub/x.nc"]) == 0
    assert listing(workdir / "sub") == ["x.nc"]
    assert not (workdir / "small.nc").exists()


def test_quiet_prints_nothing(workdir, capsys):
    assert cli.main(["run", "small.toml", "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    assert (workdir / "small.nc").exists()


def test_overwrite(workdir, capsys):
    (workdir / "small.nc").write_bytes(b"precious")
    assert cli.main(["run", "small.toml"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("conesurvey: error: output file exists: ")
    assert str(workdir / "small.nc") in err and "--overwrite" in err
    assert (workdir / "small.nc").read_bytes() == b"precious"

    assert cli.main(["run", "small.toml", "--overwrite", "-q"]) == 0
    with xr.open_dataset(workdir / "small.nc") as ds:
        assert ds.sizes["energy"] == 7
    assert listing(workdir) == ["bad.toml", "small.nc", "small.toml"]


# --- failures ---------------------------------------------------------------------------------


def test_invalid_survey_exit_2_and_no_output(workdir, capsys):
    assert cli.main(["run", "bad.toml"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("conesurvey: error: bad.toml: axes.alpha.values[1]: ")
    assert "2.0" in err
    assert listing(workdir) == ["bad.toml", "small.toml"]


def test_malformed_toml_exit_2(workdir, capsys):
    (workdir / "broken.toml").write_text("[axes\n", encoding="utf-8")
    assert cli.main(["run", "broken.toml"]) == 2
    err = capsys.readouterr().err
    assert "malformed TOML" in err and "line 1" in err
    assert not (workdir / "broken.nc").exists()


def test_missing_survey_file_exit_2(workdir, capsys):
    assert cli.main(["run", "absent.toml"]) == 2
    assert capsys.readouterr().err == "conesurvey: error: survey file not found: absent.toml\n"
    assert listing(workdir) == ["bad.toml", "small.toml"]


def test_survey_path_is_a_directory_exit_2(workdir, capsys):
    (workdir / "dir.toml").mkdir()
    assert cli.main(["run", "dir.toml"]) == 2
    assert "is a directory" in capsys.readouterr().err


def test_missing_output_directory_exit_2(workdir, capsys):
    assert cli.main(["run", "small.toml", "-o", "nowhere/x.nc"]) == 2
    assert "output directory does not exist" in capsys.readouterr().err


def test_output_path_is_a_directory_exit_2(workdir, capsys):
    (workdir / "out.nc").mkdir()
    assert cli.main(["run", "small.toml", "-o", "out.nc", "--overwrite"]) == 2
    assert "output path is a directory" in capsys.readouterr().err


def test_value_error_from_engine_exit_2(workdir, capsys, monkeypatch):
    """The engine refuses on the first point it computes, before anything is written."""
    from engine import runner

    def refuse(*args, **kwargs):
        raise ValueError("method rk45 needs something")

    monkeypatch.setattr(runner, "evaluate_block", refuse)
    assert cli.main(["run", "small.toml"]) == 2
    assert "conesurvey: error: small.toml: method rk45 needs something" in capsys.readouterr().err
    assert listing(workdir) == ["bad.toml", "small.toml"]


def test_interrupt_exit_130_keeps_blocks_for_resume(workdir, capsys, monkeypatch):
    from engine import backends

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    original = backends.evaluate_block
    monkeypatch.setattr(backends, "evaluate_block", interrupted)
    assert cli.main(["run", "small.toml"]) == 130
    err = capsys.readouterr().err
    assert "0/56 points" in err and "interrupted" in err and "resume" in err
    assert listing(workdir) == ["bad.toml", "small.nc.parts", "small.toml"]
    monkeypatch.setattr(backends, "evaluate_block", original)
    assert cli.main(["run", "small.toml", "-q"]) == 0  # resumes, then cleans up
    assert listing(workdir) == ["bad.toml", "small.nc", "small.toml"]


def test_write_failure_exit_1(workdir, capsys, monkeypatch):
    from engine.io import netcdf

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(netcdf, "merge", full_disk)
    assert cli.main(["run", "small.toml"]) == 1
    err = capsys.readouterr().err
    assert "conesurvey: error: cannot write" in err and "No space left on device" in err
    assert "the run is resumable: run the same command again" in err
    assert listing(workdir) == ["bad.toml", "small.nc.parts", "small.toml"]


# --- subprocess: the real entry points --------------------------------------------------------


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def test_python_m_engine_cli_bad_input(workdir):
    proc = subprocess.run(
        [sys.executable, "-m", "engine.cli", "run", "bad.toml", "-o", "bad.nc"],
        capture_output=True,
        text=True,
        env=_env(),
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("conesurvey: error: bad.toml: axes.alpha.values[1]")
    assert proc.stdout == ""
    assert listing(workdir) == ["bad.toml", "small.toml"]


def test_console_script_run_and_refuse_clobber(workdir):
    script = Path(sys.executable).parent / "conesurvey"
    exe = [str(script)] if script.exists() else [sys.executable, "-m", "engine.cli"]
    ok = subprocess.run(
        [*exe, "run", "small.toml"], capture_output=True, text=True, env=_env(), timeout=300
    )
    assert ok.returncode == 0, ok.stderr
    assert "56 points" in ok.stdout
    before = (workdir / "small.nc").read_bytes()
    again = subprocess.run(
        [*exe, "run", "small.toml"], capture_output=True, text=True, env=_env(), timeout=300
    )
    assert again.returncode == 0  # the same survey, already complete: nothing to do
    assert "nothing to do" in again.stdout
    other = workdir / "other.toml"
    other.write_text(SURVEY.replace("CLI test", "another survey"), encoding="utf-8")
    clash = subprocess.run(
        [*exe, "run", "other.toml", "-o", "small.nc"],
        capture_output=True,
        text=True,
        env=_env(),
        timeout=300,
    )
    assert clash.returncode == 2
    assert "output file exists" in clash.stderr
    assert (workdir / "small.nc").read_bytes() == before
    assert listing(workdir) == ["bad.toml", "other.toml", "small.nc", "small.toml"]


def test_console_script_is_registered():
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    # the launcher imports the package inside its Ctrl-C handler, then runs engine.cli.main
    assert 'conesurvey = "conesurvey_cli:main"' in text


# --- progress ---------------------------------------------------------------------------------


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_progress_log_lines_are_throttled_with_a_final_line():
    stream, clock = io.StringIO(), Clock()
    p = Progress(stream, tty=False, clock=clock)
    for i in range(1, 11):  # ten chunks, 0.5 s apart
        clock.t = 0.5 * i
        p(i * 100, 1000)
    p.close()
    lines = stream.getvalue().splitlines()
    # shown at t = 0.5 (first), 2.5, 4.5 (2 s apart) and the final one at 5.0
    assert [line.split()[1] for line in lines] == [
        "100/1,000",
        "500/1,000",
        "900/1,000",
        "1,000/1,000",
    ]
    assert lines[0] == "conesurvey: 100/1,000 points (10.0%), 200 points/s, 0:04 left"
    assert lines[-1] == "conesurvey: 1,000/1,000 points (100.0%), 200 points/s, done in 0:05"


def test_progress_close_shows_the_last_unshown_state():
    stream, clock = io.StringIO(), Clock()
    p = Progress(stream, tty=False, clock=clock)
    clock.t = 1.0
    p(10, 100)
    clock.t = 1.5
    p(20, 100)  # throttled
    p.close()
    p.close()  # idempotent
    lines = stream.getvalue().splitlines()
    assert len(lines) == 2 and "20/100" in lines[1]


def test_progress_tty_bar_updates_in_place(monkeypatch):
    monkeypatch.setattr(
        shutil, "get_terminal_size", lambda fallback=None: os.terminal_size((100, 24))
    )
    stream, clock = io.StringIO(), Clock()
    with Progress(stream, tty=True, clock=clock) as p:
        clock.t = 1.0
        p(250_000, 1_000_000)
        clock.t = 1.05  # within 0.1 s: not redrawn
        p(260_000, 1_000_000)
        clock.t = 3.0
        p(1_000_000, 1_000_000)
    text = stream.getvalue()
    assert text.endswith("\n") and text.count("\n") == 1
    frames = text[:-1].split("\r")[1:]
    assert len(frames) == 2
    assert all(len(f) == 99 for f in frames)
    bars = [re.match(r"conesurvey \[([#.]+)\]", f).group(1) for f in frames]
    width = len(bars[0])
    assert 8 <= width <= 40 and len(bars[1]) == width
    assert bars[0] == "#" * (width // 4) + "." * (width - width // 4)
    assert bars[1] == "#" * width
    assert "]  25%    250,000/1,000,000 points   250k/s  0:03 left" in frames[0]
    assert "] 100%  1,000,000/1,000,000 points   333k/s  done in 0:03" in frames[1]


def test_progress_tty_narrow_terminal_drops_the_bar():
    p = Progress(io.StringIO(), tty=True, clock=Clock())
    p(5, 10)
    line = p.bar_line(1.0, 40)
    assert "[" not in line and len(line) <= 39


def test_progress_tty_bar_fits_a_standard_terminal():
    p = Progress(io.StringIO(), tty=True, clock=Clock())
    p(123_456, 1_000_000)
    line = p.bar_line(1.0, 80)
    assert "[" in line and len(line) <= 79


def test_progress_follows_isatty():
    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    assert Progress(Tty()).tty is True
    assert Progress(io.StringIO()).tty is False


@pytest.mark.parametrize(
    ("seconds", "text"),
    [(0, "0:00"), (59.4, "0:59"), (61, "1:01"), (3725, "1:02:05"), (float("nan"), "?"), (-1, "?")],
)
def test_format_duration(seconds, text):
    assert format_duration(seconds) == text


@pytest.mark.parametrize(
    ("rate", "text"),
    [
        (950, "950 points/s"),
        (12_345, "12.3k points/s"),
        (1.2e6, "1.2M points/s"),
        (float("nan"), "? points/s"),
    ],
)
def test_format_rate(rate, text):
    assert format_rate(rate) == text
    assert format_rate(rate, "/s") == text.replace(" points/s", "/s")


# --- the output's name ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["out.txt", "out", "out.nc.bak"])
def test_an_output_whose_suffix_names_no_format_is_refused(workdir, capsys, name):
    """``-o out.txt`` wrote a netCDF file under that name; it is refused, naming the suffixes
    that pick a format, before anything is written."""
    assert cli.main(["run", "small.toml", "-o", name]) == 2
    err = capsys.readouterr().err
    assert f"output {name}:" in err and ".nc" in err and ".zarr" in err
    assert listing(workdir) == ["bad.toml", "small.toml"]

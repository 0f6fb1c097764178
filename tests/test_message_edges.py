"""Edges of the commands' messages: the standard output on a full device (``/dev/full``) is
one clear line and exit 1, never a traceback; ``--scheduler inproc://...`` is refused at once,
blaming the option, not the survey file."""

from __future__ import annotations

import os
import subprocess
import time

import pytest
import runs

SURVEY = runs.free_fall_survey("message edges")


@pytest.fixture
def work(tmp_path):
    (tmp_path / "s.toml").write_text(SURVEY)
    return tmp_path


def full(work, *args: str) -> subprocess.CompletedProcess:
    with open("/dev/full", "w") as stdout:
        return subprocess.run(
            runs.cli(*args), cwd=work, env=runs.env(), stdout=stdout, stderr=subprocess.PIPE,
            text=True, timeout=300,
        )  # fmt: skip


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
def test_stdout_on_a_full_device_is_one_line_not_a_traceback(work):
    run = full(work, "run", "s.toml", "-o", "out.nc")
    assert run.returncode == 1, run.stderr
    assert "Traceback" not in run.stderr and "resumable" not in run.stderr, run.stderr
    assert "cannot write the standard output: No space left on device" in run.stderr
    assert runs.listing(work) == ["out.nc", "s.toml"]  # the run itself finished
    info = full(work, "info", "out.nc")
    assert info.returncode == 1 and "Traceback" not in info.stderr, info.stderr
    assert info.stderr.count("\n") == 1, info.stderr


def test_an_inproc_scheduler_from_the_command_line_is_refused_at_once(work, capsys):
    t0 = time.monotonic()
    r = runs.here(work, capsys, "run", "s.toml", "-o", "out.nc", "--scheduler", "inproc://x")
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert "--scheduler 'inproc://x'" in r.stderr and "s.toml" not in r.stderr, r.stderr
    assert time.monotonic() - t0 < 8  # no 10 s connection timeout (in this process: no start)
    assert runs.listing(work) == ["s.toml"]


def test_info_escapes_terminal_control_bytes_in_a_title(work, capsys):
    """A title that would retitle the terminal and clear it is printed as escapes."""
    from engine.runner import run_survey
    from engine.surveyfile import parse_survey

    text = SURVEY.replace('"message edges"', '"x\\u001b]0;pwned\\u0007\\u001b[2J\\ry"')
    run_survey(parse_survey(text), work / "out.nc")
    r = runs.here(work, capsys, "info", "out.nc")
    assert r.returncode == 0, r.stderr
    assert "\x1b" not in r.stdout and "\x07" not in r.stdout and "\r" not in r.stdout
    assert "x\\x1b]0;pwned\\x07\\x1b[2J\\ry" in r.stdout, r.stdout

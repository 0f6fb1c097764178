"""A compile is announced (engine/_compiling.py): in a Python session from numba's own compile
events, on stderr, once for compiles that follow each other, with how long they took; silenced by
``engine.set_compile_notices(False)`` or ``CONESURVEY_COMPILE_NOTICES=0``; inside ``conesurvey
run``'s first block by the progress reporter alone (one notice, not two)."""

from __future__ import annotations

import io
import re
import subprocess
import sys
import threading
import time

import numba
import pytest
from runs import env

import engine
from engine import _compiling
from engine.progress import Progress

STARTED = "conesurvey: compiling kernels (first run only, cached)  0:00\n"
ENDED = re.compile(r"conesurvey: compiled kernels in 0:\d\d \(cached for later runs\)\n")


def fresh_kernel():
    """A numba function no process has compiled yet (numba compiles it at its first call)."""

    @numba.njit(cache=False)
    def total(n):
        s = 0.0
        for i in range(n):
            s += (i % 7) * 0.5
        return s

    return total


@pytest.fixture
def announced_at_once(monkeypatch):
    """Every compile announced as it starts (no delay), notices on, as the session had them;
    a notice an earlier test left in its grace is ended first (a fresh session has none)."""
    _compiling.settle()
    monkeypatch.setattr(_compiling, "COMPILE_DELAY", 0.0)
    before = engine.set_compile_notices(True)
    yield
    engine.set_compile_notices(before)


def stderr_until_ended(capsys, timeout: float = 30.0) -> str:
    """What was written on stderr once the notice ended (it ends a grace after the last
    compile, on a timer's thread)."""
    err = ""
    deadline = time.monotonic() + timeout
    while not ENDED.search(err) and time.monotonic() < deadline:
        time.sleep(0.05)
        err += capsys.readouterr().err
    time.sleep(0.2)  # nothing may follow
    return err + capsys.readouterr().err


def test_a_compile_is_announced_once_with_its_duration(announced_at_once, capsys):
    kernel = fresh_kernel()
    assert kernel(10) == 12.0
    err = stderr_until_ended(capsys)
    assert err.startswith(STARTED), err
    assert ENDED.fullmatch(err[len(STARTED) :]), err
    assert kernel(20) == kernel(20)  # compiled: nothing more to say
    time.sleep(0.2)
    assert capsys.readouterr().err == ""


def test_compiles_in_a_row_are_one_notice(announced_at_once, capsys, monkeypatch):
    """An API call compiles several entry points one after the other: one notice, with the
    time of them all, not one per entry point."""
    monkeypatch.setattr(_compiling, "GRACE", 2.0)
    assert fresh_kernel()(10) == 12.0
    assert fresh_kernel()(10) == 12.0
    err = stderr_until_ended(capsys)
    assert err.startswith(STARTED) and ENDED.fullmatch(err[len(STARTED) :]), err


def test_notices_can_be_silenced(announced_at_once, capsys):
    assert engine.set_compile_notices(False) is True
    assert fresh_kernel()(10) == 12.0
    time.sleep(0.2)
    assert capsys.readouterr().err == ""
    assert engine.set_compile_notices(True) is False
    with pytest.raises(ValueError, match="enabled must be True or False; got 'no'"):
        engine.set_compile_notices("no")


def test_a_run_announces_its_first_block_once(announced_at_once, capsys):
    """Inside the progress reporter's compile (``conesurvey run``) the reporter's notice is the
    only one: on its stream, with its label; none from the session's listener."""
    out = io.StringIO()
    with Progress(out, tty=False, label="conesurvey").compiling(delay=0.0):
        assert fresh_kernel()(10) == 12.0
    assert capsys.readouterr().err == ""
    text = out.getvalue()
    assert text.startswith(STARTED) and ENDED.fullmatch(text[len(STARTED) :]), text
    with _compiling.quiet():  # `conesurvey run -q`: no reporter, no notice
        assert fresh_kernel()(10) == 12.0
    time.sleep(0.2)
    assert capsys.readouterr().err == ""


def test_the_environment_variable_silences_the_notices():
    code = "import engine; print(engine.set_compile_notices(True))"
    proc = subprocess.run(
        [sys.executable, "-c", code],
        env=env(CONESURVEY_COMPILE_NOTICES="0"),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "False"  # the setting it replaced: off


def test_a_compile_during_a_run_ends_before_the_next_progress_line(
    announced_at_once, capsys, monkeypatch
):
    """A compile outside the reporter's first block (a later block's kernels) is announced
    by the session's notice; the reporter's next line comes after its end, not before."""
    monkeypatch.setattr(_compiling, "GRACE", 30.0)
    progress = Progress(sys.stderr, tty=False)
    assert fresh_kernel()(10) == 12.0
    progress(2, 2)
    err = capsys.readouterr().err
    lines = err.splitlines(keepends=True)
    assert lines[0] == STARTED and ENDED.fullmatch(lines[1]), err
    assert lines[2].startswith("conesurvey: 2/2 points (100.0%)") and len(lines) == 3, err


def test_a_notice_on_a_closed_stream_says_nothing_and_raises_nothing():
    """A test runner closes its captured stream, a pipe's reader leaves: the notice's thread
    and its end write nothing and raise nothing (no 'exception in thread' warning)."""
    stream = io.StringIO()
    notice = _compiling.Notice(stream, tty=True, delay=0.0)
    notice.start()
    time.sleep(0.05)
    stream.close()
    time.sleep(0.15)  # the thread redraws into the closed stream
    errors = []
    previous = threading.excepthook
    threading.excepthook = lambda args: errors.append(args.exc_value)
    try:
        took = notice.stop()
    finally:
        threading.excepthook = previous
    assert took >= 0.2 - 0.01 and errors == []
    assert notice._thread is not None and not notice._thread.is_alive()

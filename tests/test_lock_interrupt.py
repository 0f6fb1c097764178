"""A Ctrl-C while a run takes its output's lock (engine/io/lock.py): between the ``os.open``
that creates ``OUT.lock`` and the lock object that removes it, an interrupt left the file
behind. Each case sends a real SIGINT to this process at one moment of that window; the
interrupt still ends the call (KeyboardInterrupt), and nothing is left beside the output."""

from __future__ import annotations

import fcntl
import os
import signal
import threading

import pytest

from engine.io import lock as lock_mod
from engine.io.lock import OutputLock


def _interrupt_after(function):
    """``function`` that sends SIGINT to this process when its first call returns (one Ctrl-C)."""
    sent = []

    def wrapper(*args, **kwargs):
        result = function(*args, **kwargs)
        if not sent:
            sent.append(True)
            os.kill(os.getpid(), signal.SIGINT)
        return result

    return wrapper


class _InterruptingFcntl:
    """``fcntl`` whose ``flock`` is interrupted just after it took the lock."""

    LOCK_EX, LOCK_NB = fcntl.LOCK_EX, fcntl.LOCK_NB
    flock = staticmethod(_interrupt_after(fcntl.flock))


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(), reason="signals")
@pytest.mark.parametrize("moment", ["opened", "flocked", "checked", "recorded"])
def test_a_ctrl_c_while_the_lock_is_taken_leaves_no_lock_file(tmp_path, monkeypatch, moment):
    out = tmp_path / "out.nc"
    if moment == "opened":  # the first line of Python after os.open
        monkeypatch.setattr(lock_mod, "_not_own_file", _interrupt_after(lock_mod._not_own_file))
    elif moment == "flocked":
        monkeypatch.setattr(lock_mod, "fcntl", _InterruptingFcntl)
    elif moment == "checked":
        monkeypatch.setattr(lock_mod, "_same_file", _interrupt_after(lock_mod._same_file))
    else:
        monkeypatch.setattr(OutputLock, "_record", _interrupt_after(OutputLock._record))
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            OutputLock.acquire(out, "interrupted")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    monkeypatch.undo()
    with OutputLock.acquire(out, "after"):  # and the lock is free
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out.nc.lock"]
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(), reason="signals")
def test_a_ctrl_c_while_a_run_is_refused_still_ends_it(tmp_path, monkeypatch):
    """Refused (another run holds the lock) and interrupted while reading who holds it: the
    interrupt wins, and the holder's lock file stays."""
    out = tmp_path / "out.nc"
    with OutputLock.acquire(out, "holder"):
        monkeypatch.setattr(lock_mod, "_read_holder", _interrupt_after(lock_mod._read_holder))
        previous = signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            with pytest.raises(KeyboardInterrupt):
                OutputLock.acquire(out, "refused")
        finally:
            signal.signal(signal.SIGINT, previous)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out.nc.lock"]
    assert sorted(p.name for p in tmp_path.iterdir()) == []

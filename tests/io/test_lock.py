"""engine.io.lock: one holder per output, named to the others; never stale, never two."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time

import pytest
import runs

from engine.io import lock as lock_mod
from engine.io.lock import Locked, LockError, OutputLock, describe_holder, lock_path

HOLD = """
import sys, time
from pathlib import Path
from engine.io.lock import OutputLock
lock = OutputLock.acquire(Path(sys.argv[1]), "holder test")
print("held", flush=True)
time.sleep(float(sys.argv[2]))
"""


def _holder(out, seconds=60.0):
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(out), str(seconds)],
        env=runs.env(),
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_acquire_records_the_holder_and_release_removes_the_file(tmp_path):
    out = tmp_path / "o.nc"
    with OutputLock.acquire(out, "conesurvey run s.toml") as lock:
        assert lock.path == lock_path(out) == tmp_path / "o.nc.lock"
        holder = json.loads(lock.path.read_text())
        assert holder["pid"] == os.getpid() and holder["host"] == socket.gethostname()
        assert holder["command"] == "conesurvey run s.toml"
        assert time.strptime(holder["started"], "%Y-%m-%dT%H:%M:%SZ")
    assert list(tmp_path.iterdir()) == []


def test_a_second_taker_is_refused_and_told_who_holds_it(tmp_path):
    out = tmp_path / "o.nc"
    proc = _holder(out)
    try:
        with pytest.raises(Locked) as info:
            OutputLock.acquire(out)
        assert info.value.holder["pid"] == proc.pid
        text = describe_holder(info.value.holder)
        assert text.startswith(f"pid {proc.pid} on host {socket.gethostname()}, started 20")
    finally:
        proc.kill()
        proc.wait()


def test_a_killed_holder_leaves_no_stale_lock(tmp_path):
    """SIGKILL: the kernel drops the flock; the file (with the dead holder's text) stays and
    the next taker simply takes it."""
    out = tmp_path / "o.nc"
    proc = _holder(out)
    proc.kill()
    proc.wait()
    assert lock_path(out).exists()
    with OutputLock.acquire(out) as lock:
        assert json.loads(lock.path.read_text())["pid"] == os.getpid()


def test_the_lock_excludes_within_one_process_too(tmp_path):
    """flock is per open file: a second acquire in the same process is refused as well."""
    out = tmp_path / "o.nc"
    with OutputLock.acquire(out), pytest.raises(Locked):
        OutputLock.acquire(out)


def test_a_lock_file_removed_and_recreated_meanwhile_is_not_trusted(tmp_path, monkeypatch):
    """The race of removing a lock file: a taker that locked the old inode after its holder
    removed it must notice and take the new file instead."""
    out = tmp_path / "o.nc"
    path = lock_path(out)
    real_flock = lock_mod.fcntl.flock
    calls = []

    def flock_after_a_swap(fd, op):
        real_flock(fd, op)
        if not calls:  # the first time: the holder removes the file and another creates one
            calls.append(fd)
            os.unlink(path)
            path.write_text("")

    monkeypatch.setattr(lock_mod.fcntl, "flock", flock_after_a_swap)
    lock = OutputLock.acquire(out)
    try:
        assert os.fstat(lock.fd).st_ino == os.stat(path).st_ino
        assert len(calls) == 1
    finally:
        lock.release()


def test_a_planted_link_is_refused_and_its_target_untouched(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("precious")
    lock_path(tmp_path / "o.nc").symlink_to(victim)
    with pytest.raises(LockError, match="symbolic link"):
        OutputLock.acquire(tmp_path / "o.nc")
    assert victim.read_text() == "precious"


def test_a_file_system_without_locks_is_a_clear_error(tmp_path, monkeypatch):
    def no_locks(fd, op):
        raise OSError(37, "No locks available")

    monkeypatch.setattr(lock_mod.fcntl, "flock", no_locks)
    with pytest.raises(LockError, match="does not support locks"):
        OutputLock.acquire(tmp_path / "o.nc")


def test_describe_holder_says_what_is_known():
    assert describe_holder({}) == "holder not yet recorded"
    assert describe_holder({"pid": 7}) == "pid 7"
    assert describe_holder({"host": "h", "started": "T"}) == "on host h, started T"


def test_a_run_refused_just_after_the_lock_was_taken_still_names_the_holder(tmp_path):
    """The holder takes the flock, then writes who it is: a run refused in between waits for
    the record (here written 0.3 s late by a thread of this process holding the flock)."""
    import fcntl
    import threading

    out = tmp_path / "out.nc"
    fd = os.open(lock_path(out), os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    record = {"pid": 4242, "host": "node7", "started": "2026-01-02T03:04:05Z"}
    late = threading.Timer(0.3, lambda: os.pwrite(fd, json.dumps(record).encode(), 0))
    late.start()
    try:
        with pytest.raises(Locked) as info:
            OutputLock.acquire(out, "second")
        assert info.value.holder["pid"] == 4242 and info.value.holder["host"] == "node7"
    finally:
        late.join()
        os.close(fd)

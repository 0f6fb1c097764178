"""engine.io.hold against the kernel: real leases, real other processes, real mappings."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from engine.io import hold
from engine.io.hold import BUSY, HELD, NOT_HELD, HeldFiles, file_system

OPEN_FOR_WRITING = """
import errno, os, sys
try:
    os.close(os.open(sys.argv[1], os.O_WRONLY | os.O_NONBLOCK))
    print("opened")
except OSError as exc:
    print(errno.errorcode[exc.errno])
"""


def _other(code: str, *args: str) -> str:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          timeout=60, check=True).stdout.strip()  # fmt: skip


@pytest.fixture
def held_file(tmp_path):
    path = tmp_path / "f"
    path.write_bytes(b"the bytes")
    held = HeldFiles(4)
    fd = os.open(path, os.O_RDONLY)
    assert held.hold("f", fd) == HELD
    yield path, held
    held.release()


def test_the_file_systems_here_are_told_apart(tmp_path):
    assert file_system(os.stat(tmp_path).st_dev) in hold.LEASE_FILE_SYSTEMS
    assert file_system(os.stat("/proc").st_dev) == "proc"


def test_readers_leave_a_held_file_held(held_file):
    path, held = held_file
    assert _other("import sys; print(open(sys.argv[1], 'rb').read().decode())", str(path)) == (
        "the bytes"
    )
    assert held.intact("f", path)


def test_a_writer_is_kept_out_and_the_lease_shows_it(held_file):
    """Another process opening the file for writing without waiting is refused; the lease
    is broken from then on (the run checks the file again), and taken again once nobody
    writes."""
    path, held = held_file
    assert _other(OPEN_FOR_WRITING, str(path)) in ("EAGAIN", "EWOULDBLOCK")
    assert path.read_bytes() == b"the bytes"
    assert not held.intact("f", path)
    held.drop("f")
    assert held.hold("f", os.open(path, os.O_RDONLY)) == HELD and held.intact("f", path)


def test_a_name_that_leads_elsewhere_is_not_the_held_file(held_file, tmp_path):
    path, held = held_file
    (tmp_path / "g").write_bytes(b"the bytes")
    os.replace(tmp_path / "g", path)  # as an editor saves
    assert not held.intact("f", path)


def test_a_writable_mapping_makes_a_file_busy(tmp_path):
    """A shared writable mapping in another process keeps the file open for writing: no
    lease is granted (the caller treats the file as changed)."""
    path = tmp_path / "m"
    path.write_bytes(b"x" * 4096)
    mapper = subprocess.Popen(
        [sys.executable, "-c", "import mmap, os, sys; fd = os.open(sys.argv[1], os.O_RDWR); "
         "m = mmap.mmap(fd, 4096); os.close(fd); print('mapped', flush=True); sys.stdin.read()",
         str(path)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert mapper.stdout.readline().strip() == "mapped"
        fd = os.open(path, os.O_RDONLY)
        try:
            assert HeldFiles(2).hold("m", fd) == BUSY
        finally:
            os.close(fd)
    finally:
        mapper.stdin.close()
        mapper.wait(timeout=60)


def test_where_leases_do_not_hold_nothing_is_held(tmp_path, monkeypatch):
    """A file system not in the list (NFS, FUSE, overlay: writes that do not open the file
    here), or no descriptor left: not held, so the commit hashes the file again."""
    path = tmp_path / "f"
    path.write_bytes(b"b")
    fd = os.open(path, os.O_RDONLY)
    try:
        monkeypatch.setattr(hold, "file_system", lambda dev: "nfs4")
        assert HeldFiles(2).hold("f", fd) == NOT_HELD
        monkeypatch.undo()
        assert HeldFiles(0).hold("f", fd) == NOT_HELD
    finally:
        os.close(fd)


def test_release_lets_a_waiting_writer_in(held_file):
    path, held = held_file
    held.release()
    assert _other(OPEN_FOR_WRITING, str(path)) == "opened"

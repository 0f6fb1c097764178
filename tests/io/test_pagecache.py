"""The page cache. DirectWriter: the bytes of a file written past the cache are exactly those
given, in whatever pieces; its whole pages go with O_DIRECT where the file system takes it (the
descriptor's flags say so), the rest through the cache; a refusal at any point falls back to
the cache from where it stands, and any other error is raised. flushing: a file being written is
flushed every so often, and with ``drop`` its flushed pages leave the cache (``mincore``)."""

from __future__ import annotations

import ctypes
import errno
import fcntl
import mmap
import os
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.io import pagecache
from engine.io.atomic import write_unsynced
from engine.io.pagecache import ALIGN, STAGE, DirectWriter

#: Sizes around the edges that matter: a page, the staging buffer.
EDGES = [0, 1, ALIGN - 1, ALIGN, ALIGN + 1, STAGE - 1, STAGE, STAGE + 1]


def _takes_direct(directory) -> bool:
    """Whether the file system of ``directory`` takes a direct write of one aligned page (tmpfs
    and some others may refuse the flag or the write)."""
    path = directory / "probe"
    if pagecache.O_DIRECT == 0:  # not Linux
        return False
    page = mmap.mmap(-1, ALIGN)  # page-aligned memory
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | pagecache.O_DIRECT, 0o600)
        try:
            return os.write(fd, page) == ALIGN
        finally:
            os.close(fd)
    except OSError:
        return False
    finally:
        page.close()
        path.unlink(missing_ok=True)


def _write(path, pieces: list[bytes], *, flags: bool = True) -> DirectWriter:
    """``pieces`` written to ``path`` by a DirectWriter; with ``flags``, its ``direct`` checked
    against the descriptor's flags (not where O_DIRECT is only pretended)."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        w = DirectWriter(fd)
        if flags and w.direct:  # the kernel's flags, not ours
            assert fcntl.fcntl(fd, fcntl.F_GETFL) & pagecache.O_DIRECT
        for piece in pieces:
            assert w.write(piece) == len(piece)
        w.close()
        os.fsync(fd)
    finally:
        os.close(fd)
    return w


@settings(max_examples=40, deadline=None)
@given(st.lists(st.one_of(st.sampled_from(EDGES), st.integers(0, 3 * ALIGN)), max_size=12))
def test_the_file_holds_exactly_what_was_written(tmp_path_factory, sizes):
    where = tmp_path_factory.mktemp("direct")
    pieces = [os.urandom(n) for n in sizes]
    w = _write(where / "f", pieces)
    data = b"".join(pieces)
    assert (where / "f").read_bytes() == data
    whole = len(data) - len(data) % ALIGN
    assert w.direct_bytes == (whole if _takes_direct(where) else 0)


def test_a_file_system_that_refuses_o_direct_gets_the_same_bytes(tmp_path, monkeypatch):
    real = fcntl.fcntl

    def refuse(fd, cmd, arg=0):
        if cmd == fcntl.F_SETFL and arg & pagecache.O_DIRECT:
            raise OSError(errno.EINVAL, "Invalid argument")
        return real(fd, cmd, arg)

    monkeypatch.setattr(pagecache.fcntl, "fcntl", refuse)
    pieces = [os.urandom(n) for n in (STAGE + 5, 3, ALIGN)]
    w = _write(tmp_path / "f", pieces)
    assert not w.direct and w.direct_bytes == 0
    assert (tmp_path / "f").read_bytes() == b"".join(pieces)


def test_a_direct_write_refused_midway_goes_on_through_the_cache(tmp_path, monkeypatch):
    """The second direct write refused (as a disk with larger blocks would): that write and
    the rest go through the cache, the file is whole. O_DIRECT is only pretended here (its
    flag not set), so that this runs on any file system."""
    real, calls = os.pwrite, []

    def second_refused(fd, data, offset):
        calls.append(offset)
        if len(calls) == 2:
            raise OSError(errno.EINVAL, "Invalid argument")
        return real(fd, data, offset)

    monkeypatch.setattr(DirectWriter, "_set_direct", lambda self, on: on)
    monkeypatch.setattr(pagecache.os, "pwrite", second_refused)
    pieces = [os.urandom(STAGE), os.urandom(STAGE + 7)]
    w = _write(tmp_path / "f", pieces, flags=False)
    assert w.direct_bytes == STAGE and not w.direct
    assert calls == [0, STAGE, STAGE, 2 * STAGE]  # the refused write again, then the tail
    assert (tmp_path / "f").read_bytes() == b"".join(pieces)


def test_a_full_disk_is_raised_not_fallen_back_from(tmp_path, monkeypatch):
    def full(fd, data, offset):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(pagecache.os, "pwrite", full)
    fd = os.open(tmp_path / "f", os.O_RDWR | os.O_CREAT, 0o600)
    try:
        w = DirectWriter(fd)
        with pytest.raises(OSError) as info:
            w.write(os.urandom(STAGE))
        assert info.value.errno == errno.ENOSPC
    finally:
        os.close(fd)


def test_write_unsynced_direct_has_the_size_and_digest_of_a_cached_write(tmp_path):
    pieces = [b"header", os.urandom(STAGE + 123), os.urandom(ALIGN)]

    def fill(f):
        for piece in pieces:
            f.write(piece)

    got = {}
    for direct in (False, True):
        written = write_unsynced(tmp_path / f"{direct}.bin", fill, sequential=True, direct=direct)
        written.finish()
        got[direct] = (written.size, written.digest, (tmp_path / f"{direct}.bin").read_bytes())
    assert got[True] == got[False]
    assert got[True][2] == b"".join(pieces)


def test_flushing_flushes_the_file_while_it_is_written(tmp_path, monkeypatch):
    path = tmp_path / "out.nc.tmp"
    path.write_bytes(b"")
    flushed: list[int] = []
    monkeypatch.setattr(pagecache.os, "fdatasync", lambda fd: flushed.append(os.fstat(fd).st_ino))
    with pagecache.flushing(path, every=0.01):
        with open(path, "ab") as f:
            f.write(b"x" * 1000)
        time.sleep(0.3)
    n = len(flushed)
    assert n >= 2 and set(flushed) == {path.stat().st_ino}
    time.sleep(0.05)
    assert len(flushed) == n  # stopped with the context


def test_flushing_ignores_a_failed_flush(tmp_path, monkeypatch):
    path = tmp_path / "out.nc.tmp"
    path.write_bytes(b"")

    def fails(fd):
        raise OSError(errno.EIO, "I/O error")

    monkeypatch.setattr(pagecache.os, "fdatasync", fails)
    with pagecache.flushing(path, every=0.01):
        time.sleep(0.05)  # the final fsync of the file is the one that reports errors


def _resident_share(path) -> float:
    """The share of ``path``'s pages in the page cache now (Linux ``mincore`` on a mapping of
    the file, which reads nothing)."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mmap.restype = ctypes.c_void_p
    libc.mmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_int,
                          ctypes.c_int, ctypes.c_long]  # fmt: skip
    size = path.stat().st_size
    pages = -(-size // mmap.PAGESIZE)
    vec = (ctypes.c_ubyte * pages)()
    with open(path, "rb") as f:
        addr = libc.mmap(None, size, mmap.PROT_READ, mmap.MAP_SHARED, f.fileno(), 0)
        assert addr not in (None, ctypes.c_void_p(-1).value), ctypes.get_errno()
        try:
            ok = libc.mincore(ctypes.c_void_p(addr), ctypes.c_size_t(size), vec)
            assert ok == 0, ctypes.get_errno()
        finally:
            libc.munmap(ctypes.c_void_p(addr), ctypes.c_size_t(size))
    return sum(v & 1 for v in vec) / pages


def test_flushing_with_drop_gives_the_flushed_pages_back(tmp_path):
    """A file written once (the netCDF output) keeps only its last second or so in the cache
    when flushed with ``drop``. The check that the measure sees pages at all is made on a file
    just written and not yet flushed: its pages are dirty, and the kernel cannot evict a dirty
    page before writing it back, so they are there even on a machine short of memory (where a
    flushed, clean page may be reclaimed at once, as on a loaded CI machine)."""
    seen = tmp_path / "seen.tmp"
    with open(seen, "wb") as f:
        f.write(os.urandom(8 << 20))
        f.flush()  # to the kernel, not to the disk
        assert _resident_share(seen) > 0.95
    path = tmp_path / "out.nc.tmp"
    path.write_bytes(b"")
    with pagecache.flushing(path, every=0.01, drop=True):
        with open(path, "ab") as f:
            f.write(os.urandom(8 << 20))
        time.sleep(0.3)
        share = _resident_share(path)
    assert share < 0.05


def test_without_fcntl_or_pwrite_the_file_goes_through_the_cache(tmp_path, monkeypatch):
    """As on Windows (no ``fcntl``, no ``os.pwrite``): no direct write, the same bytes."""
    monkeypatch.setattr(pagecache, "fcntl", None)
    monkeypatch.delattr(pagecache.os, "pwrite")
    pieces = [os.urandom(n) for n in (STAGE + 3, ALIGN - 1, 5)]
    w = _write(tmp_path / "f", pieces)
    assert not w.direct and w.direct_bytes == 0
    assert (tmp_path / "f").read_bytes() == b"".join(pieces)

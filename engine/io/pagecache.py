"""How the files of a run use the page cache: files written once and not read back go past it
(``O_DIRECT``: :class:`DirectWriter`), and a file written over minutes is flushed every second
and its pages given back (:func:`flushing`, :func:`drop_cached`).

A streamed netCDF run writes each block's chunks twice: into the output, and into the block
file it resumes from (:mod:`engine.io.blocks`), which a run that is not killed never reads.
Through the page cache, every byte is copied into a cache page; on a virtual machine whose
host takes back free memory (virtio-balloon free page reporting, as on this project's 2-core
VM) that copy costs several times more when it lands in memory freed minutes before than in a
page the cache recycles. docs/output.md ("The page cache") has the measurements, which
``scripts/bench_storage.py --page-cache`` prints.

:class:`DirectWriter` is the ``write`` of such a file: it copies what it is given into one
page-aligned buffer (the same pages every time) and writes the buffer with ``O_DIRECT`` in
whole pages; the last partial page goes through the cache (``O_DIRECT`` needs whole aligned
blocks). Where the file system or the operating system refuses ``O_DIRECT`` (tmpfs, macOS,
Windows), or a direct write is refused as misaligned, it writes through the cache instead,
from where it stands: the bytes in the file are the same either way. Durability is the
caller's fsync, as for any file (``O_DIRECT`` bypasses the cache, not the disk's own).
"""

from __future__ import annotations

import contextlib
import errno
import mmap
import os
import threading
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # Windows: no O_DIRECT either; every file goes through the cache
    fcntl = None  # type: ignore[assignment]

__all__ = ["ALIGN", "FLUSH_SECONDS", "DirectWriter", "drop_cached", "flushing"]

#: How often a file being written is flushed to the disk meanwhile (:func:`flushing`) [s].
FLUSH_SECONDS = 1.0
#: Open flags where the system has them (0 elsewhere); engine.io.atomic takes them from here.
O_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
O_CLOEXEC = getattr(os, "O_CLOEXEC", 0)

#: Alignment of a direct write's offset, length and memory [bytes]: the page size, a multiple
#: of every disk's logical block size in use (512 or 4096).
ALIGN = mmap.PAGESIZE
#: Size of the staging buffer [bytes]: each direct write is one of these (a multiple of ALIGN).
STAGE = 8 << 20
O_DIRECT = getattr(os, "O_DIRECT", 0)
#: errno of a direct open or write that means "not here": write through the cache.
REFUSED = frozenset({errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP})

_stages = threading.local()  # one staging buffer per thread, reused: its pages stay resident


def _pwrite(fd: int, data: memoryview, offset: int) -> int:
    """``os.pwrite``, or a seek and a write where there is none (Windows)."""
    if hasattr(os, "pwrite"):
        return os.pwrite(fd, data, offset)
    os.lseek(fd, offset, os.SEEK_SET)
    return os.write(fd, data)


def _stage() -> mmap.mmap:
    buf = getattr(_stages, "buf", None)
    if buf is None:
        buf = _stages.buf = mmap.mmap(-1, STAGE)  # anonymous: page-aligned
    return buf


class DirectWriter:
    """The sequential ``write`` of the open regular file ``fd`` (at offset 0, empty) with
    ``O_DIRECT`` where it is taken; :meth:`close` writes what is left (the descriptor stays
    open: the caller fsyncs and closes it). ``direct`` says whether the file is being written
    past the cache, ``direct_bytes`` how many of its bytes were."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.buf = _stage()
        self.fill = 0  # bytes staged in buf
        self.offset = 0  # bytes in the file
        self.direct_bytes = 0
        self.direct = O_DIRECT != 0 and fcntl is not None and self._set_direct(True)

    def _set_direct(self, on: bool) -> bool:
        flags = fcntl.fcntl(self.fd, fcntl.F_GETFL)
        try:
            fcntl.fcntl(self.fd, fcntl.F_SETFL, flags | O_DIRECT if on else flags & ~O_DIRECT)
        except OSError as exc:
            if on and exc.errno in REFUSED:
                return False
            raise
        return on

    def write(self, data: bytes | bytearray | memoryview) -> int:
        view = memoryview(data).cast("B")
        done = 0
        while done < len(view):
            n = min(len(view) - done, STAGE - self.fill)
            self.buf[self.fill : self.fill + n] = view[done : done + n]
            self.fill += n
            done += n
            if self.fill == STAGE:
                self._flush(STAGE)
        return done

    def _flush(self, n: int) -> None:
        """Write the first ``n`` staged bytes (whole pages while direct) and keep the rest."""
        view = memoryview(self.buf)
        try:
            written = 0
            while written < n:
                written += self._write(view[written:n])
        finally:
            view.release()
        rest = self.fill - n
        if rest:
            self.buf.move(0, n, rest)
        self.fill = rest

    def _write(self, view: memoryview) -> int:
        while True:
            try:
                n = _pwrite(self.fd, view, self.offset)
            except OSError as exc:  # a direct write refused (misaligned here): the cache
                if not (self.direct and exc.errno in REFUSED):
                    raise
                self.direct = self._set_direct(False)
                continue
            if n <= 0:
                raise OSError(errno.EIO, "a write wrote nothing")
            self.offset += n
            self.direct_bytes += n if self.direct else 0
            return n

    def close(self) -> None:
        """Write what is staged: its whole pages directly, the last partial page through the
        cache."""
        whole = self.fill - self.fill % ALIGN if self.direct else 0
        if whole:
            self._flush(whole)
        if self.fill:
            if self.direct:
                self.direct = self._set_direct(False)
            self._flush(self.fill)


def drop_cached(fd: int) -> None:
    """Let the kernel drop the file's clean (flushed) pages from its cache: for what is not
    read again soon (the netCDF output as it is written, a Zarr chunk file this process
    stamped, the last page of a block file), so that the next writes reuse those pages."""
    advise = getattr(os, "posix_fadvise", None)
    if advise is not None:
        with contextlib.suppress(OSError):
            advise(fd, 0, 0, os.POSIX_FADV_DONTNEED)


@contextlib.contextmanager
def flushing(path: Path, every: float = FLUSH_SECONDS, *, drop: bool = False) -> Iterator[None]:
    """While inside, the file ``path`` (being written by someone else) is flushed to the disk
    every ``every`` seconds on a thread of its own, so that the final :func:`fsync_path`
    finds little left to write and the disk works while the data is computed. With ``drop``,
    the pages each flush wrote are then given back to the kernel (:func:`drop_cached`): a
    file written once keeps a few seconds of itself in the cache, not all of it. Best effort:
    an error of these flushes is ignored (the final fsync is the one that counts)."""
    try:
        fd = os.open(path, os.O_RDONLY | O_NOFOLLOW | O_CLOEXEC)
    except OSError:
        yield
        return
    stop, sync = threading.Event(), getattr(os, "fdatasync", os.fsync)

    def flush() -> None:
        while not stop.wait(every):
            try:
                sync(fd)
            except OSError:
                return
            if drop:
                drop_cached(fd)

    thread = threading.Thread(target=flush, name="conesurvey-flush", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        os.close(fd)

"""Files a run holds from the moment it checked their bytes to its commit: read leases.

A Zarr run checks each file of its store once: a chunk file right after writing it (its bytes
read back and compared with the ones written), a block a resume keeps when it hashes it against
the journal, the metadata and small arrays at the commit. From then on until the store is
renamed into place it *holds* the file: a read-only descriptor stays open with a read lease on
it (``fcntl(F_SETLEASE, F_RDLCK)``, Linux). The kernel grants a read lease only while no
process has the file open for writing (a shared writable mapping counts: it keeps its
descriptor's write access), and breaks it as soon as any process, root included, opens the
file for writing or truncates it; the opener waits until the holder lets go (at most
``/proc/sys/fs/lease-break-time``, 45 s by default), or is refused with ``EWOULDBLOCK`` if it
opened with ``O_NONBLOCK``. A held file whose lease is intact at the commit, and whose name
still leads to the held inode, therefore holds the bytes that were checked, whatever the file
system's clock, a mapping or a race did: it is not read again. One whose lease was broken is
checked again (a new lease, then its bytes), and refused while a writer has it open.

Leases are taken only where every write to a file goes through this kernel
(:data:`LEASE_FILE_SYSTEMS`: local disks and memory); on NFS, FUSE, overlay or CIFS another
host, a daemon or the layer below could write without opening the file here. There, and past
the descriptors the process may open (:class:`HeldFiles` raises the soft limit up to the hard
one first), a file is not held: the commit reads it again and hashes it. The lease break is
not signalled to the run (SIGURG, ignored by default, and no owner): the run looks at its
leases when it commits. docs/guarantees.md says what this rests on.
"""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import threading
import time
from dataclasses import dataclass

try:
    import fcntl
    import resource
except ImportError:  # Windows: no leases; every file is hashed again at the commit
    fcntl = None  # type: ignore[assignment]
    resource = None  # type: ignore[assignment]

__all__ = ["BUSY", "HELD", "LEASE_FILE_SYSTEMS", "NOT_HELD", "HeldFiles", "file_system"]

#: File systems on which every write to a file goes through this kernel's open (leases hold).
LEASE_FILE_SYSTEMS = frozenset({"ext2", "ext3", "ext4", "xfs", "tmpfs", "ramfs", "f2fs"})
#: What :meth:`HeldFiles.hold` did: held; not held (the commit hashes the file again); busy
#: (another process has the file open for writing, or a writable mapping of it).
HELD, NOT_HELD, BUSY = "held", "not held", "busy"
#: Pauses [s] before a busy file is taken for one another process holds open for writing.
_RETRIES = (0.001, 0.005, 0.02, 0.05)
#: Descriptors left to the rest of the process when the run holds its files.
RESERVE = 512
_F_SETLEASE = getattr(fcntl, "F_SETLEASE", None)
_F_GETLEASE = getattr(fcntl, "F_GETLEASE", None)
_F_SETSIG = getattr(fcntl, "F_SETSIG", None)
_F_SETOWN = getattr(fcntl, "F_SETOWN", None)
_F_RDLCK = getattr(fcntl, "F_RDLCK", 0)


def file_system(dev: int) -> str | None:
    """The type of the mounted file system whose device is ``dev`` (``st_dev``), from
    ``/proc/self/mountinfo``; None where that cannot be told."""
    want = f"{os.major(dev)}:{os.minor(dev)}"
    try:
        with open("/proc/self/mountinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                fields = line.split()
                if len(fields) > 2 and fields[2] == want and "-" in fields:
                    return fields[fields.index("-") + 1]
    except OSError:
        return None
    return None


def _lease(fd: int) -> str:
    """Take a read lease on the read-only descriptor ``fd``: HELD, BUSY or NOT_HELD."""
    if _F_SETLEASE is None:
        return NOT_HELD
    try:
        if _F_SETSIG is not None:  # a break, before the owner is cleared, is ignored
            fcntl.fcntl(fd, _F_SETSIG, signal.SIGURG)
        fcntl.fcntl(fd, _F_SETLEASE, _F_RDLCK)
    except OSError as exc:
        return BUSY if exc.errno in (errno.EAGAIN, errno.EBUSY) else NOT_HELD
    if _F_SETOWN is not None:
        with contextlib.suppress(OSError):
            fcntl.fcntl(fd, _F_SETOWN, 0)  # nobody is signalled when it breaks
    return HELD


def _intact(fd: int) -> bool:
    try:
        return fcntl.fcntl(fd, _F_GETLEASE) == _F_RDLCK
    except (OSError, TypeError):
        return False


@dataclass(frozen=True)
class _Held:
    fd: int
    dev: int
    ino: int
    size: int


def _open_descriptors() -> int:
    try:
        return len(os.listdir("/proc/self/fd"))
    except OSError:
        return 64


def _room(want: int) -> int:
    """How many descriptors the run may keep open for ``want`` files: the soft limit raised
    toward the hard one if that is needed, less those open and :data:`RESERVE`."""
    if resource is None:
        return 0
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    busy = _open_descriptors() + RESERVE
    if soft != resource.RLIM_INFINITY and soft < busy + want:
        new = busy + want if hard == resource.RLIM_INFINITY else min(hard, busy + want)
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, new), hard))
            soft = max(soft, new)
    return max(0, min(want, soft - busy)) if soft != resource.RLIM_INFINITY else want


class HeldFiles:
    """The files a run holds, by key (a path relative to its store): a read-only descriptor
    each, with a read lease on it. ``want``: how many files the run may hold (the
    descriptors are reserved when the first is held). Thread-safe."""

    def __init__(self, want: int) -> None:
        self._want = want
        self._room: int | None = None
        self._files: dict[str, _Held] = {}
        self._lock = threading.Lock()
        self._fs: dict[int, bool] = {}

    def _leasable(self, dev: int) -> bool:
        if dev not in self._fs:
            self._fs[dev] = file_system(dev) in LEASE_FILE_SYSTEMS
        return self._fs[dev]

    def hold(self, key: str, fd: int) -> str:
        """Take a lease on the read-only descriptor ``fd`` of ``key``'s file, before its bytes
        are checked (a write after this breaks it). HELD: the descriptor is now this table's
        (closed by :meth:`release`); NOT_HELD or BUSY: the caller keeps it."""
        st = os.fstat(fd)
        with self._lock:
            if self._room is None:
                self._room = _room(self._want)
            if key in self._files or self._room <= 0 or not self._leasable(st.st_dev):
                return NOT_HELD
            self._room -= 1
        got = _lease(fd)
        for pause in _RETRIES:  # a fork elsewhere in the process shares writable descriptors
            if got != BUSY:  # until its exec (closed there): busy for a moment, not for long
                break
            time.sleep(pause)
            got = _lease(fd)
        with self._lock:
            if got == HELD:
                self._files[key] = _Held(fd, st.st_dev, st.st_ino, st.st_size)
            else:
                self._room += 1
        return got

    def held(self, key: str) -> bool:
        return key in self._files

    def intact(self, key: str, path: str | os.PathLike[str]) -> bool:
        """Whether ``key`` is held, its lease unbroken, and ``path`` (not followed) is still
        the held file, of the size it had."""
        h = self._files.get(key)
        if h is None or not _intact(h.fd):
            return False
        try:
            st = os.lstat(path)
        except OSError:
            return False
        return (st.st_dev, st.st_ino, st.st_size) == (h.dev, h.ino, h.size)

    def drop(self, key: str) -> None:
        """Let go of ``key`` (its descriptor closed, its lease gone)."""
        with self._lock:
            h = self._files.pop(key, None)
            if h is not None:
                self._room = (self._room or 0) + 1
        if h is not None:
            os.close(h.fd)

    def keys(self) -> list[str]:
        return list(self._files)

    def release(self) -> None:
        """Let go of every file (a writer waiting for one of them then goes on)."""
        with self._lock:
            files, self._files = self._files, {}
            self._room = None
        for h in files.values():
            with contextlib.suppress(OSError):
                os.close(h.fd)

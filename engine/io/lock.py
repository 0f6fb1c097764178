"""An exclusive lock per output: one run at a time computes, merges, renames and cleans up.

The lock is ``flock(LOCK_EX | LOCK_NB)`` on ``OUT.lock``, a file beside the output, held for the
whole run. The file holds who has it (pid, host, start time: JSON) so that a refused run can
name the holder. What this relies on (README, "Guarantees"):

- the kernel releases an ``flock`` when its holder exits, however it dies (SIGKILL included):
  a lock is never stale, and there is no pid/host guessing;
- on Linux NFS clients ``flock`` is carried out as a POSIX byte-range lock on the server
  (NFSv4 natively, NFSv3 through lockd/NLM), so two hosts exclude each other; a mount with
  ``nolock`` or ``local_lock=flock|all`` makes the lock host-local. Lustre needs the ``flock``
  mount option (``localflock`` is host-local; without either, locking fails and the run is
  refused). On a file system that cannot lock at all the run is refused with a message;
- the lock file is removed by its holder before it lets go (a Ctrl-C while the lock is being
  taken is held back until the holder exists, so it cannot leave the file behind); a run that
  locked a file that was meanwhile removed (its inode is no longer the path's) drops it and
  tries again, so two runs never both hold "the" lock.

The process that runs the survey holds the lock and alone creates, journals, merges, renames and
removes files. Dask workers write only into a Zarr run: each writes the chunk files of the
blocks it computed into the unfinished store that the lock holder created (a netCDF run's
workers send their results back instead); a block counts once its receipt reaches the lock
holder's journal. So the lock needs to work where the client runs, on the output's directory,
and a worker needs the store's file system, not the lock.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import signal
import socket
import stat
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from types import FrameType, TracebackType
from typing import Any

from .atomic import O_CLOEXEC, O_NOFOLLOW

try:
    import fcntl
except ImportError:  # Windows: no flock
    fcntl = None  # type: ignore[assignment]

__all__ = ["LockError", "Locked", "OutputLock", "describe_holder", "lock_path"]

#: errno values of flock() that mean "this file system does not lock".
NO_LOCKS = frozenset({errno.ENOLCK, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EINVAL})
_MAX_HOLDER_BYTES = 4096
#: How long [s] a refused run waits for the lock's holder to record who it is.
HOLDER_WAIT = 2.0


class LockError(Exception):
    """The output's lock cannot be taken (the message says why)."""


class Locked(LockError):
    """Another run holds the lock; ``holder`` is what it wrote (pid, host, started), maybe {}."""

    def __init__(self, path: Path, holder: dict[str, Any]) -> None:
        self.path = path
        self.holder = holder
        super().__init__(f"another run holds {path} ({describe_holder(holder)})")


def lock_path(out: Path) -> Path:
    """The lock file of the output ``out``: ``OUT.lock`` beside it."""
    return out.with_name(out.name + ".lock")


def describe_holder(holder: dict[str, Any]) -> str:
    """``pid 123 on host node7, started 2025-01-02T03:04:05Z`` (what is known of it)."""
    if not holder:
        return "holder not yet recorded"
    parts = []
    if "pid" in holder:
        parts.append(f"pid {holder['pid']}")
    if "host" in holder:
        parts.append(f"on host {holder['host']}")
    text = " ".join(parts) or "holder unknown"
    if "started" in holder:
        text += f", started {holder['started']}"
    return text


def _read_holder(fd: int) -> dict[str, Any]:
    with contextlib.suppress(OSError, ValueError):
        doc = json.loads(os.pread(fd, _MAX_HOLDER_BYTES, 0).decode("utf-8"))
        if isinstance(doc, dict):
            return {k: doc[k] for k in ("pid", "host", "started", "command") if k in doc}
    return {}


@dataclass
class OutputLock:
    """The held lock of one output (use :meth:`acquire`; release with :meth:`release` or as a
    context manager). Releasing removes the lock file."""

    path: Path
    fd: int | None

    @classmethod
    def acquire(cls, out: Path, command: str = "conesurvey") -> OutputLock:
        """Take the lock of ``out`` without waiting: :class:`Locked` if another run has it,
        :class:`LockError` if it cannot be taken here (a link, a file system without locks).

        A Ctrl-C (SIGINT) is held back from creating ``OUT.lock`` until the lock object that
        removes it exists, then delivered: if it ends the call, the lock is released first, so
        an interrupt leaves no lock file behind."""
        lock = None
        try:
            with _interrupts_held():
                lock = cls._take(lock_path(out), command)
        except BaseException:
            if lock is not None:
                lock.release()
            raise
        return lock

    @classmethod
    def _take(cls, path: Path, command: str) -> OutputLock:
        for _ in range(100):
            try:
                fd = os.open(path, os.O_RDWR | os.O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0o644)
            except OSError as exc:
                if exc.errno == errno.ELOOP:
                    raise LockError(f"{path} is a symbolic link; refusing to use it") from None
                raise LockError(f"cannot create the lock file {path}: {exc.strerror}") from None
            if problem := _not_own_file(fd):
                os.close(fd)
                raise LockError(f"{path} is {problem}; refusing to use it (remove it)")
            if fcntl is None:
                os.close(fd)
                raise LockError("locking an output needs flock (POSIX); not available here")
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_holder(fd)
                # The holder writes who it is just after it takes the lock: a run that loses a
                # race by microseconds waits up to HOLDER_WAIT seconds to name it.
                deadline = time.monotonic() + HOLDER_WAIT
                while not holder and time.monotonic() < deadline:
                    time.sleep(0.02)
                    holder = _read_holder(fd)
                os.close(fd)
                raise Locked(path, holder) from None
            except OSError as exc:
                os.close(fd)
                if exc.errno in NO_LOCKS:
                    raise LockError(
                        f"the file system of {path.parent} does not support locks "
                        f"({exc.strerror}); write the output on a local disk or an NFS mount "
                        "with locking"
                    ) from None
                raise
            if _same_file(fd, path):
                lock = cls(path, fd)
                lock._record(command)
                return lock
            os.close(fd)  # locked a file its holder had just removed: try again
        raise LockError(f"cannot take the lock {path}: it keeps being replaced")

    def _record(self, command: str) -> None:
        """Write who holds the lock (best effort: the flock is the lock, not the text)."""
        holder = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "started": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "command": command[:500],
        }
        assert self.fd is not None
        with contextlib.suppress(OSError):
            os.ftruncate(self.fd, 0)
            os.pwrite(self.fd, json.dumps(holder).encode(), 0)

    def release(self) -> None:
        """Remove the lock file, then let go of the lock (idempotent)."""
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            if _same_file(self.fd, self.path):
                os.unlink(self.path)
        os.close(self.fd)
        self.fd = None

    def __enter__(self) -> OutputLock:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.release()


@contextlib.contextmanager
def _interrupts_held() -> Iterator[None]:
    """A SIGINT in the block is held back and handed to the handler it was meant for when the
    block ends (in the main thread, where Python runs signal handlers; elsewhere nothing)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[FrameType | None] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(frame))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught and callable(previous):
            previous(signal.SIGINT, caught[0])
        elif caught and previous == signal.SIG_DFL:
            os.kill(os.getpid(), signal.SIGINT)


def _not_own_file(fd: int) -> str:
    """What the open lock file is if it is not a plain file of its own ("" if it is): a hard
    link planted there would have its other name's contents replaced by the holder's record."""
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        return "not a regular file"
    if st.st_nlink != 1:
        return f"a hard link ({st.st_nlink} names for one file)"
    return ""


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` (not followed) is still the file open as ``fd``."""
    try:
        st = os.stat(path, follow_symlinks=False)
    except FileNotFoundError:
        return False
    here = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (here.st_dev, here.st_ino)

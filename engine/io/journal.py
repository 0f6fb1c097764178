"""The journal of a streamed run's blocks, and the thread that makes block files durable.

The journal (``OUT.parts/journal``) has one line per committed block: its index, the size and
SHA-256 of its file, and a check of the line itself (the first 16 hex digits of the line's
own SHA-256), so that a torn last line (a run killed mid-append) is recognised and ignored
(:func:`read_journal`). A block counts only if its file matches its last journal line.

Block files are written on a thread of their own, so that a run never waits for the disk. A
streamed run compresses each block on its own thread (:meth:`engine.io.blocks.BlockStore.commit`)
and hands it to :class:`Durability`, which does the rest in the order the blocks came: write
and hash the block's file under a temporary name (:func:`engine.io.atomic.write_unsynced`),
fsync it, rename it into place, fsync the directory, append the size and SHA-256 to the journal
and fsync the journal. Only then does the block count (the journal is the record a resume
trusts), and only then is ``on_durable(index)`` called, on that thread.

The thread is at most ``depth`` blocks behind: :meth:`Durability.submit` waits for room, which
bounds both the memory the queued blocks hold and what a killed run loses (the blocks in
flight: the one being computed and at most ``depth`` queued ones; a temporary file left by a
kill is removed by the next run, :meth:`engine.io.blocks.BlockStore.scan`).

An error on the thread (a full disk, an ``on_durable`` that raises) stops it: the blocks still
queued are dropped, never written, and the error is raised by the next :meth:`submit` or by
:meth:`close`, on the run's thread. So a block is journaled only with every block submitted
before it.
"""

from __future__ import annotations

import hashlib
import os
import threading
from collections import deque
from collections.abc import Callable
from pathlib import Path

from . import OutputError
from .atomic import O_CLOEXEC, O_NOFOLLOW, NotRegularFile, Written, read_regular

__all__ = [
    "DEPTH",
    "JOURNAL",
    "Durability",
    "append_journal",
    "journal_line",
    "journal_lines",
    "read_journal",
]

JOURNAL = "journal"
_MAX_JOURNAL_BYTES = 1 << 30

#: Blocks the thread may be behind by (each held in memory until its file is written: its
#: compressed chunks, a few tens of MB on the 10^8-point survey).
DEPTH = 4


def journal_line(index: int, size: int, digest: str) -> bytes:
    """Block ``index``'s journal line: its file's size and SHA-256, and the line's check."""
    body = f"{index} {size} {digest}"
    return f"{body} {hashlib.sha256(body.encode()).hexdigest()[:16]}\n".encode()


def append_journal(root: Path, index: int, size: int, digest: str) -> None:
    """Append block ``index``'s line to the journal in ``root`` and fsync it."""
    fd = os.open(root / JOURNAL, os.O_WRONLY | os.O_APPEND | O_NOFOLLOW | O_CLOEXEC)
    try:
        os.write(fd, journal_line(index, size, digest))
        os.fsync(fd)
    finally:
        os.close(fd)


def journal_lines(root: Path) -> list[bytes]:
    """The whole lines of the journal in ``root`` (what follows the last newline is a torn
    line: left out); [] if there is no journal, OutputError if it is not a readable regular
    file. A netCDF run's journal and a Zarr run's (:mod:`engine.io.zarrstore`) alike."""
    try:
        data = read_regular(root / JOURNAL, _MAX_JOURNAL_BYTES, follow_links=False)
    except FileNotFoundError:
        return []
    except (NotRegularFile, ValueError) as exc:
        raise OutputError(f"{root / JOURNAL} is unreadable ({exc})") from None
    return data.split(b"\n")[:-1]


def read_journal(root: Path, nblocks: int) -> dict[int, tuple[int, str]]:
    """index -> (size, SHA-256) of the last valid journal line of each block (torn or damaged
    lines are skipped); {} if there is no journal."""
    entries: dict[int, tuple[int, str]] = {}
    for raw in journal_lines(root):
        parts = raw.split(b" ")
        if len(parts) != 4 or not all(p.isalnum() and p.isascii() for p in parts):
            continue
        try:
            index, size, digest = int(parts[0]), int(parts[1]), parts[2].decode()
        except ValueError:
            continue
        if journal_line(index, size, digest) == raw + b"\n" and 0 <= index < nblocks:
            entries[index] = (size, digest)
    return entries


class Durability:
    """The thread that writes block files, makes them durable and journals them, in order.

    Each submitted block comes as ``write()``, which writes its file under a temporary name
    (:func:`engine.io.atomic.write_unsynced`); the thread calls it, puts the file in place
    durably, then ``journal(index, size, digest)`` appends the block's line to the journal and
    makes it durable, then ``on_durable(index)`` is called. Use as a context manager: leaving
    it normally waits for every submitted block and raises the thread's error; leaving it on
    an error (the run's) still stores the submitted blocks, without calling ``on_durable``,
    and raises nothing of its own.
    """

    def __init__(
        self,
        journal: Callable[[int, int, str], None],
        on_durable: Callable[[int], None] | None = None,
        depth: int = DEPTH,
    ) -> None:
        self._journal = journal
        self._on_durable = on_durable
        self._depth = max(1, depth)
        self._queue: deque[tuple[int, Callable[[], Written]]] = deque()
        self._busy: set[int] = set()  # submitted, not yet journaled (nor dropped)
        self._closing = False
        self._quiet = False  # the run failed: no more on_durable calls
        self._error: BaseException | None = None
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="conesurvey-blocks", daemon=True)

    def __enter__(self) -> Durability:
        self._thread.start()
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: object, tb: object) -> None:
        self.close(failed=kind is not None)

    # -- the run's side --

    def submit(self, index: int, write: Callable[[], Written]) -> None:
        """Queue block ``index``, whose file ``write()`` writes; waits while ``depth`` blocks
        are queued. Raises the thread's error (the block is dropped then)."""
        with self._cond:
            self._cond.wait_for(lambda: len(self._queue) < self._depth or self._error is not None)
            if self._error is not None:
                raise self._error
            self._queue.append((index, write))
            self._busy.add(index)
            self._cond.notify_all()

    def wait(self, index: int) -> None:
        """Return once block ``index`` is journaled or will never be (the thread failed)."""
        with self._cond:
            self._cond.wait_for(lambda: index not in self._busy)

    def close(self, failed: bool = False) -> None:
        """Store every queued block and stop the thread; raise its error unless the run
        ``failed`` (then ``on_durable`` is not called any more, and the run's error is the one
        that counts)."""
        with self._cond:
            self._closing = True
            self._quiet = self._quiet or failed
            self._cond.notify_all()
        self._thread.join()
        if self._error is not None and not failed:
            raise self._error

    # -- the thread --

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._queue or self._closing)
                if not self._queue:
                    return
                index, write = self._queue[0]
            try:
                written = write()
                written.finish()
                self._journal(index, written.size, written.digest)
                with self._cond:
                    self._queue.popleft()
                    self._busy.discard(index)
                    self._cond.notify_all()
                    quiet = self._quiet
                if self._on_durable is not None and not quiet:
                    self._on_durable(index)
            except BaseException as exc:  # noqa: BLE001 (raised on the run's thread)
                with self._cond:
                    self._error = exc
                    self._queue.clear()  # dropped: never written, or removed by finish()
                    self._busy.clear()
                    self._cond.notify_all()
                return

"""A writer thread fed the blocks of a streamed run in index order, while they are computed.

HDF5 compresses on one thread, so a merge that starts after the last block is computed adds
its whole time to the run. :class:`BlockFeed` overlaps the two: the output file is written by
one thread (the only one that touches the file's library while it runs) in C order of blocks,
the order the content checksum is defined in (:mod:`engine.io.contents`), while the caller
goes on computing and committing blocks.

Where each block comes from:

- a block committed by this run is handed over in memory (:meth:`BlockFeed.put`) right after
  :meth:`engine.io.blocks.BlockStore.commit` stored it; the values written are those just
  stored. At most ``held`` blocks wait in memory: when they are all waiting, ``put`` waits for
  the writer (so memory stays bounded); a block that arrives before an earlier one (dask
  yields blocks in any order) is held too while ``held - 1`` or fewer wait (it never waits),
  else read back from the store when its turn comes;
- every other block (stored by an earlier run, or not held) is read from the store and checked
  against its journaled checksum as it is read (:meth:`engine.io.blocks.BlockStore.take`), by
  the writer, or, once the compute is over, by the caller (:meth:`BlockFeed.finish`), which
  then reads ahead of the writer so that reading and writing overlap.

A failure of the writer (a full disk, a block that changed on disk) does not stop the compute:
blocks go on being stored (they are what a rerun resumes from) and :meth:`finish` raises the
writer's error. Leaving the ``with`` block early (an error, KeyboardInterrupt) stops the
writer after the block it is writing and waits for it. README: "Large surveys: streaming,
resume, dask" and "Guarantees".
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Collection, Iterable
from types import TracebackType

import numpy as np

from .blocks import BlockStore

__all__ = ["BlockFeed", "Write", "feed"]

Arrays = dict[str, np.ndarray]
#: The writer's work for one block: ``write(index, arrays)``, called in index order.
Write = Callable[[int, Arrays], None]


class BlockFeed:
    """Feeds ``write`` (run on a thread of its own) every block of ``store`` in index order.

    ``stored``: the indices already committed when the feed starts (blocks of an earlier run);
    the others must be handed over with :meth:`put` as they are committed. Use as a context
    manager; call :meth:`finish` once every block is committed.
    """

    def __init__(self, store: BlockStore, write: Write, stored: set[int], held: int = 3) -> None:
        self.store = store
        self._write = write
        self._n = store.tiling.nblocks
        self._stored = set(stored)
        self._held: dict[int, Arrays] = {}
        self._max_held = max(1, held)
        self._frontier = 0  # every index below it is stored
        self._advance_frontier()
        self._reading: set[int] = set()  # being read by the caller (read-ahead)
        self._taken = -1  # the last index the writer took
        self._closed = False  # no more put()
        self._stopping = False
        self._error: BaseException | None = None
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="conesurvey-writer", daemon=True)

    # -- the caller's side --

    def __enter__(self) -> BlockFeed:
        self._thread.start()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if kind is not None:
            self.stop()

    def put(self, index: int, arrays: Arrays) -> None:
        """Hand over block ``index``, just committed to the store. Waits while ``held`` blocks
        wait for the writer; never waits once the writer has failed."""
        with self._cond:
            # Held if every block before it is stored (the writer gets to it in turn: waits for
            # room), or if it came ahead (dask) while there is room for one more beside it: a
            # block ahead never takes the last place, which the block in turn may need (else
            # it would wait for a writer that waits for it). It is marked stored only once it
            # is held: else the writer could read it back and the held copy would stay.
            hold = index == self._frontier
            if hold:
                self._cond.wait_for(self._room)
            else:
                hold = len(self._held) < self._max_held - 1
            if hold and self._error is None and not self._stopping:
                self._held[index] = arrays
            self._stored.add(index)
            self._advance_frontier()
            self._cond.notify_all()

    def finish(self) -> None:
        """Every block is committed: read the ones not handed over ahead of the writer, wait
        for it to write the last one, and raise its error if it failed."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        nxt = 0
        while True:
            with self._cond:
                self._cond.wait_for(self._room)
                nxt = max(nxt, self._taken + 1)
                while nxt < self._n and (nxt in self._held or nxt not in self._stored):
                    nxt += 1
                if nxt >= self._n or self._error is not None or self._stopping:
                    break
                self._reading.add(nxt)
            try:
                arrays = self.store.take(nxt)
            except BaseException as exc:
                with self._cond:
                    self._error = self._error or exc
                    self._reading.discard(nxt)
                    self._cond.notify_all()
                break
            with self._cond:
                self._reading.discard(nxt)
                self._held[nxt] = arrays
                self._cond.notify_all()
        self._thread.join()
        if self._error is not None:
            raise self._error

    def stop(self) -> None:
        """Abandon the feed: the writer stops after the block it is writing."""
        with self._cond:
            self._stopping = True
            self._held.clear()
            self._cond.notify_all()
        if self._thread.is_alive():
            self._thread.join()

    # -- the writer's side --

    def _room(self) -> bool:
        return len(self._held) < self._max_held or self._error is not None or self._stopping

    def _advance_frontier(self) -> None:
        while self._frontier in self._stored:
            self._frontier += 1

    def _ready(self, index: int) -> bool:
        if self._stopping or self._error is not None or index in self._held:
            return True
        return index not in self._reading and (index in self._stored or self._closed)

    def _run(self) -> None:
        try:
            for index in range(self._n):
                with self._cond:
                    self._cond.wait_for(lambda i=index: self._ready(i))
                    if self._stopping or self._error is not None:
                        return
                    self._taken = index
                    arrays = self._held.pop(index, None)
                    self._cond.notify_all()
                if arrays is None:  # not handed over: stored by an earlier run, or not held
                    arrays = self.store.take(index)
                if self._stopping:
                    return
                self._write(index, arrays)
        except BaseException as exc:
            with self._cond:
                self._error = exc
                self._held.clear()
                self._cond.notify_all()


def feed(
    store: BlockStore,
    write: Write,
    pending: Collection[int],
    incoming: Iterable[tuple[int, Arrays]],
    held: int = 3,
) -> None:
    """Call ``write`` on a writer thread for every block of ``store`` in index order, while
    iterating ``incoming`` (on this thread) computes the blocks still ``pending`` and yields
    each, ``(index, arrays as stored)``, once it is committed. Raises what ``incoming`` raises
    (after stopping the writer), else the writer's error, once every block is written."""
    stored = set(range(store.tiling.nblocks)) - set(pending)
    with BlockFeed(store, write, stored, held) as f:
        for index, arrays in incoming:
            f.put(index, arrays)
        f.finish()

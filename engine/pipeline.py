"""A local run's pipeline: blocks computed ahead of the run on a thread of their own, and
written behind it on another.

The run (:mod:`engine.runner`) takes one block at a time and stores it. Meanwhile the next
:data:`AHEAD` block(s) are computed in turn, each into a set of reused buffers
(:class:`engine.blockbuffers.Buffers`), so that the compute thread never waits for the run to
hand the last block on; with a writer (a Zarr store's chunks), each block is written on a
thread of its own up to :data:`AHEAD` blocks behind. Blocks come out in order, errors in block
order. Leaving early (an error, KeyboardInterrupt): the block being computed or written
finishes first, and the queued ones not yet started are dropped (a queued one the thread took
up meanwhile finishes too).
"""

from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

__all__ = ["AHEAD", "computed_ahead", "written_behind"]

Arrays = dict[str, np.ndarray]
Blocks = Iterator[tuple[int, Any]]

#: Blocks computed ahead of the run. One: two ahead measured the same on the 10^8-point
#: survey (27-34 s either way on 2 quiet cores) with ~40 MB more memory (docs/output.md,
#: "The write path at scale").
AHEAD = 1


def computed_ahead(
    compute: Callable[[int, Arrays | None], tuple[int, Arrays]],
    pending: list[int],
    buffers: Callable[[], Any],
) -> Blocks:
    """``compute(index, out)`` of each pending block, :data:`AHEAD` blocks ahead on a thread;
    ``out`` is a set of ``buffers()`` (made once: :class:`engine.blockbuffers.Buffers`) or
    None. A single block is computed here, into new arrays."""
    if len(pending) < 2:
        yield from (compute(i, None) for i in pending)
        return
    pool = ThreadPoolExecutor(1, thread_name_prefix="conesurvey-compute")
    sets = buffers()
    queued: deque[tuple[Future, Arrays | None]] = deque()
    indices = iter(pending)

    def submit() -> None:
        for i in itertools.islice(indices, 1):
            out = sets.take(busy=[b for _, b in queued if b is not None])
            queued.append((pool.submit(compute, i, out), out))

    try:
        for _ in range(AHEAD):
            submit()
        while queued:
            done = queued.popleft()[0].result()
            submit()
            yield done
    finally:
        for future, _ in queued:
            future.cancel()
        pool.shutdown(wait=True)


def written_behind(blocks: Blocks, write: Callable[[int, Arrays], Any]) -> Blocks:
    """(index, ``write(index, results)``) of each block of ``blocks``, written on a thread of
    its own up to :data:`AHEAD` blocks behind them, in order (a Zarr store's chunk files:
    encoded, fsynced and renamed while the next blocks are computed)."""
    pool = ThreadPoolExecutor(1, thread_name_prefix="conesurvey-chunks")
    queued: deque[tuple[int, Future]] = deque()
    try:
        for i, results in blocks:
            queued.append((i, pool.submit(write, i, results)))
            del results  # the buffers are the writer's until it is done
            if len(queued) > AHEAD:
                j, future = queued.popleft()
                yield j, future.result()
        while queued:
            j, future = queued.popleft()
            yield j, future.result()
    finally:
        for _, future in queued:
            future.cancel()
        pool.shutdown(wait=True)

"""Result buffers of a local run, reused from block to block.

A block's results are ~38 MB on the 10^8-point survey: new arrays for every block are memory
faulted in and zeroed by the kernel afresh (a tenth of that run's CPU time). The local backend
(:mod:`engine.backends`) computes each block into a set of :class:`Buffers` instead
(:func:`engine.backends.compute_block` with ``out``), given out again once the block is done
with.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Collection
from typing import TYPE_CHECKING

import numpy as np

from .evaluation import block_variables

if TYPE_CHECKING:
    from .grid import Tiling
    from .plan import RunPlan

__all__ = ["Buffers"]


class Buffers:
    """Sets of 1-D result buffers, each with room for the largest block of ``tiling``. A set
    is given out again only once nothing refers to its arrays: a block's results are views of
    them (:func:`engine.backends.compute_block`), held by the store, the writer and the feed
    until the block is written, and each view holds a reference to its buffer (CPython's
    reference counts). At most ``most`` sets; when all are in use, None (new arrays).
    A set handed to a block not computed yet has no views to count: the caller names such
    sets (``busy``), as the local backend (:mod:`engine.backends`) does for the blocks it
    queued."""

    def __init__(self, plan: RunPlan, tiling: Tiling, most: int = 8) -> None:
        self.names = block_variables(plan)
        self.points = math.prod(tiling.block)
        self.most = most
        self.sets: list[dict[str, np.ndarray]] = []
        self.free_refs = -1  # the reference count of an array of a set that nothing else holds

    def take(self, busy: Collection[dict[str, np.ndarray]] = ()) -> dict[str, np.ndarray] | None:
        """A set of buffers no block uses now (new if none is and there is room), or None.
        ``busy``: the sets given to blocks not computed yet (no view of them exists to count)."""
        for buffers in self.sets:
            if self._unused(buffers) and not any(b is buffers for b in busy):
                return buffers
        if len(self.sets) >= self.most:
            return None
        buffers = {n: np.empty(self.points, dt) for n, dt in self.names.items()}
        self.sets.append(buffers)
        if self.free_refs < 0:
            self.free_refs = max(self._counts(buffers))
        return buffers

    def _counts(self, buffers: dict[str, np.ndarray]) -> list[int]:
        return [sys.getrefcount(a) for a in buffers.values()]

    def _unused(self, buffers: dict[str, np.ndarray]) -> bool:
        return all(n <= self.free_refs for n in self._counts(buffers))

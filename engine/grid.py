"""Tiling of a 4-D survey grid (alpha, energy, h, Lz) into blocks.

A block is a rectangular hyperslab whose shape is a whole multiple of the netCDF storage
chunk, so every block fills whole chunks: streamed writes never re-compress a chunk, and the
in-memory survey and the streamed one compute the very same blocks (bit-identical results).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

#: Storage chunk target: 2^16 values (512 kB of float64) per chunk, balanced over the axes so
#: that slicing along any axis touches few chunks.
CHUNK_TARGET = 1 << 16
#: Default points per computed block (~0.5 s of exact-path work on 2 cores, ~70 MB of results).
BLOCK_POINTS = 1 << 20
#: Largest grid a survey may span: 2^40 (1.1e12) points, ~6 days of exact-path work on 2
#: cores and ~50 TB of results; larger grids are refused before anything is allocated.
MAX_GRID_POINTS = 1 << 40
#: Most blocks a run lists (the runner keeps one entry per block in memory).
MAX_BLOCKS = 1 << 22


def grid_too_large(counts: dict[str, int]) -> str | None:
    """Why a grid of ``counts`` points per axis cannot be run (None if it can): the size and
    what would fit, computed from the counts alone (constant time and memory)."""
    points = math.prod(counts.values())
    if points <= MAX_GRID_POINTS:
        return None
    shape = " x ".join(f"{name} {n:,}" for name, n in counts.items())
    return (
        f"the grid has {points:.3g} points ({shape}); a survey may span at most "
        f"{MAX_GRID_POINTS:,} (2^40) points: give fewer points on some axis "
        f"(by a factor {points / MAX_GRID_POINTS:.3g} at least)"
    )


def storage_chunks(shape: tuple[int, ...], target: int = CHUNK_TARGET) -> tuple[int, ...]:
    """Balanced chunk shape: halve the largest extent until the chunk holds <= target values."""
    chunk = list(shape)
    while math.prod(chunk) > target:
        i = max(range(len(chunk)), key=lambda j: chunk[j])
        chunk[i] = (chunk[i] + 1) // 2
    return tuple(chunk)


def block_shape(shape: tuple[int, ...], chunk: tuple[int, ...], points: int) -> tuple[int, ...]:
    """A multiple of ``chunk`` with at most max(points, prod(chunk)) values, grown from the
    last axis (so a block is as contiguous in C order as it can be)."""
    block = list(chunk)
    for i in reversed(range(len(shape))):
        while block[i] < shape[i]:
            grown = min(shape[i], block[i] * 2)
            grown = min(shape[i], -(-grown // chunk[i]) * chunk[i])
            if math.prod(block) // block[i] * grown > points:
                break
            block[i] = grown
    return tuple(block)


@dataclass(frozen=True)
class Tiling:
    """Blocks of a grid: ``shape`` split into ``block``-shaped hyperslabs (C order of blocks)."""

    shape: tuple[int, ...]
    chunk: tuple[int, ...]
    block: tuple[int, ...]

    @classmethod
    def for_grid(cls, shape: tuple[int, ...], points: int = BLOCK_POINTS) -> Tiling:
        if points < 1:
            raise ValueError(f"block points must be >= 1; got {points!r}")
        chunk = storage_chunks(shape)
        return cls(tuple(shape), chunk, block_shape(shape, chunk, points))

    @property
    def counts(self) -> tuple[int, ...]:
        """Number of blocks along each axis."""
        return tuple(-(-n // b) for n, b in zip(self.shape, self.block, strict=False))

    @property
    def nblocks(self) -> int:
        return math.prod(self.counts)

    @property
    def size(self) -> int:
        return math.prod(self.shape)

    def slices(self, index: int) -> tuple[slice, ...]:
        """The hyperslab of block ``index``."""
        pos = np.unravel_index(index, self.counts)
        return tuple(
            slice(p * b, min(n, (p + 1) * b))
            for p, b, n in zip(pos, self.block, self.shape, strict=False)
        )

    def points(self, index: int) -> int:
        return math.prod(s.stop - s.start for s in self.slices(index))

    def __iter__(self) -> Iterator[tuple[slice, ...]]:
        return (self.slices(i) for i in range(self.nblocks))

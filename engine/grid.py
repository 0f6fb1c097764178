"""Tiling of a 4-D survey grid (alpha, energy, h, Lz) into blocks, and the block computation.

A block is a rectangular hyperslab whose shape is a whole multiple of the netCDF storage
chunk, so every block fills whole chunks: streamed writes never re-compress a chunk, and the
in-memory survey and the streamed one compute the very same blocks (bit-identical results).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Storage chunk target: 2^16 values (512 kB of float64) per chunk, balanced over the axes so
#: that slicing along any axis touches few chunks.
CHUNK_TARGET = 1 << 16
#: Default points per computed block (~0.5 s of exact-path work on 2 cores, ~70 MB of results).
BLOCK_POINTS = 1 << 20
DIMS = ("alpha", "energy", "h", "Lz")


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
            raise ValueError(f"chunk points must be >= 1; got {points!r}")
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


def evaluate_block(spec: dict[str, Any], slices: tuple[slice, ...]) -> dict[str, np.ndarray]:
    """Results on one hyperslab of the grid, each array shaped like the slab.

    ``spec``: axes ``alpha``, ``energy``, ``h``, ``Lz`` (1-D float64), ``scene`` (Scene),
    ``method``, ``energy_relative``, ``circular_tol``, ``rtol``. With a relative energy axis the
    absolute energy (``energy_absolute``) is V_min + offset |V_min| from the slab's own V_min;
    where V has no minimum it is NaN and the point is classed forbidden.
    """
    from .api import VARIABLES, evaluate_flat, minimum_energy

    sub = [np.asarray(spec[d])[s] for d, s in zip(DIMS, slices, strict=False)]
    shape = tuple(x.size for x in sub)
    A, E, H, L = (x.reshape(-1) for x in np.meshgrid(*sub, indexing="ij"))
    scene = spec["scene"]
    e_abs = None
    if spec["energy_relative"]:
        vmin = minimum_energy(A, H, L, scene)
        e_abs = vmin + E * np.abs(vmin)
        E = e_abs
    res = evaluate_flat(
        A, E, H, L, scene, spec["method"], circular_tol=spec["circular_tol"], rtol=spec["rtol"]
    )
    if e_abs is not None:
        undefined = np.isnan(e_abs)
        if undefined.any():
            res["orbit_class"][undefined] = 0
            for name in VARIABLES:
                if name != "r_circ":
                    res[name][undefined] = np.nan
        res["energy_absolute"] = e_abs
    return {name: col.reshape(shape) for name, col in res.items()}

"""Tiling of survey grids into chunk-aligned blocks."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from engine.grid import CHUNK_TARGET, Tiling

shapes = st.tuples(*[st.integers(1, 60)] * 4)


@given(shapes, st.integers(1, 200_000))
def test_blocks_tile_the_grid_exactly_once(shape, points):
    t = Tiling.for_grid(shape, points)
    seen = np.zeros(shape, np.int8)
    for sl in t:
        seen[sl] += 1
    assert (seen == 1).all()
    assert math.prod(t.chunk) <= CHUNK_TARGET
    # blocks are whole multiples of the storage chunk (except where the grid ends)
    for b, c, n in zip(t.block, t.chunk, t.shape, strict=False):
        assert b % c == 0 or b == n
    assert math.prod(t.block) <= max(points, math.prod(t.chunk))


def test_large_grid_blocks_and_chunks():
    t = Tiling.for_grid((100, 100, 100, 100), 1 << 20)
    assert math.prod(t.block) <= 1 << 20
    assert t.size == 10**8
    assert sum(t.points(i) for i in range(t.nblocks)) == 10**8
    with pytest.raises(ValueError, match="block points"):
        Tiling.for_grid((2, 2, 2, 2), 0)

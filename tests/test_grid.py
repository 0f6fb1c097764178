"""Tiling of survey grids into chunk-aligned blocks."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import engine
from engine.grid import CHUNK_TARGET, Tiling, evaluate_block

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
    with pytest.raises(ValueError, match="chunk points"):
        Tiling.for_grid((2, 2, 2, 2), 0)


def test_block_results_equal_pointwise_evaluation():
    axes = dict(
        alpha=np.array([0.3, 0.7]),
        energy=np.array([10.0, 20.0, 30.0]),
        h=np.array([-1.0, 1.0]),
        Lz=np.array([0.2, 0.5, 0.9]),
    )
    spec = dict(
        axes,
        scene=engine.Scene(),
        method="exact",
        energy_relative=False,
        circular_tol=1e-12,
        rtol=1e-10,
    )
    block = evaluate_block(spec, (slice(1, 2), slice(0, 3), slice(0, 2), slice(1, 3)))
    assert block["period"].shape == (1, 3, 2, 2)
    ds = engine.evaluate(0.7, 20.0, 1.0, 0.9)
    assert int(ds.orbit_class) == 1
    assert block["period"][0, 1, 1, 1] == float(ds.period)

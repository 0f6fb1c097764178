"""engine.io.zarrchunks: a block's chunk files are the bytes zarr itself writes."""

from __future__ import annotations

import numpy as np
import pytest

zarr = pytest.importorskip("zarr")

from engine.io.zarrchunks import chunk_keys, codecs, encode, fill_value  # noqa: E402

SHAPE, CHUNK = (3, 5, 7, 11), (2, 2, 3, 4)


def zarrs_own(name, values, slab, complevel, separator):
    """The chunk files zarr writes for ``values`` at ``slab`` of an array of the store's kind
    whose chunk keys are separated by ``separator``."""
    mem: dict = {}
    arr = zarr.create_array(
        zarr.storage.MemoryStore(mem), name=name, shape=SHAPE, chunks=CHUNK,
        dtype=values.dtype, fill_value=fill_value(values.dtype),
        compressors=codecs(complevel), config={"write_empty_chunks": True},
        chunk_key_encoding={"name": "default", "separator": separator},
    )  # fmt: skip
    arr[slab] = values
    return {k: v.to_bytes() for k, v in mem.items() if not k.endswith("zarr.json")}


@pytest.mark.parametrize("separator", [".", "/"])  # new stores, stores made before 2026-11-27
@pytest.mark.parametrize("complevel", [5, 0])
@pytest.mark.parametrize(
    "slab",
    [
        (slice(0, 2), slice(0, 4), slice(0, 6), slice(0, 8)),  # whole chunks
        (slice(2, 3), slice(0, 4), slice(3, 7), slice(8, 11)),  # chunks hanging over the edges
    ],
)
def test_chunk_files_are_zarrs_own(slab, complevel, separator):
    rng = np.random.default_rng(7)
    shape = tuple(s.stop - s.start for s in slab)
    values = {
        "period": np.cumsum(rng.random(shape)).reshape(shape),  # smooth: Blosc shrinks it
        "orbit_class": rng.integers(0, 5, shape).astype(np.int8),
        "r_min": rng.random(shape).astype(np.float32),
    }
    values["period"][0, 0, 0, :2] = np.nan
    arrays = tuple((n, v.dtype.str) for n, v in values.items())
    got = encode(slab, CHUNK, arrays, values, complevel, separator)
    for name, v in values.items():
        own = zarrs_own(name, v, slab, complevel, separator)
        mine = {k: b for k, b in got.items() if k.startswith(f"{name}/")}
        assert sorted(mine) == sorted(own) == sorted(chunk_keys(name, slab, CHUNK, separator))
        assert all(mine[k] == own[k] for k in own), name

"""engine.io.chunkfile: block files that hold the compressed chunks the netCDF output gets.

A deflated run compresses each block once: the block file is its chunks, and the output gets
those very bytes (on the run and on resume, never compressed again); other compressions keep
``.npz`` files of the values. Scan, journal and corruption of ``.npz`` stores:
tests/io/test_blocks.py; whole runs killed and resumed: tests/test_runner.py.
"""

from __future__ import annotations

import hashlib
import json
import os

import h5py
import netCDF4
import numpy as np
import pytest
import runs

from engine.grid import Tiling
from engine.io import OutputError, deflate
from engine.io.blocks import BlockStore, block_file_bytes
from engine.io.chunkfile import ChunkCodec, StoredBlock, read_block, write_block
from engine.io.contents import verify_file
from engine.io.manifest import Manifest, read_manifest
from engine.io.results import open_result
from engine.plan import plan_from_survey
from engine.runner import run_survey
from engine.surveyfile import parse_survey

# 3 x 41 x 33 x 50 = 202,950 points: storage chunks (3, 21, 33, 25), blocks of 2 chunks
# (3, 21, 33, 50), the second hanging over the energy axis by one value
RUN = runs.gravity_survey("chunk blocks", alpha=(0.3, 0.8, 1.3), energy=41, h=33, lz=50)
BLOCK = 140_000
# The store's own tests: 3 x 20 x 33 x 40 in blocks of up to 8 chunks, hanging over every axis
SURVEY = runs.gravity_survey("chunk store", alpha=(0.3, 0.8, 1.3), energy=20, h=33, lz=40)
TILING = Tiling((3, 20, 33, 40), (2, 7, 10, 12), (2, 14, 20, 24))


def _stop_after(n: int):
    def hook(index: int) -> None:
        hook.seen += 1
        if hook.seen == n:
            raise KeyboardInterrupt

    hook.seen = 0
    return hook


def _data_chunks(path) -> dict[str, dict[tuple, bytes]]:
    """Every stored chunk of the output's 4-D variables, as HDF5 holds it."""
    found: dict[str, dict[tuple, bytes]] = {}
    with h5py.File(path, "r") as f:
        for name, dset in f.items():
            if isinstance(dset, h5py.Dataset) and dset.ndim == 4:
                found[name] = {}
                for i in range(dset.id.get_num_chunks()):
                    info = dset.id.get_chunk_info(i)
                    found[name][info.chunk_offset] = dset.id.read_direct_chunk(info.chunk_offset)[1]
    return found


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    """An uninterrupted run, with a copy of each block file taken as it was committed."""
    tmp = tmp_path_factory.mktemp("whole")
    out, kept = tmp / "whole.nc", {}

    def keep(index: int) -> None:
        path = next((tmp / "whole.nc.parts").glob(f"b{index:08d}.*"))
        kept[path.name] = path.read_bytes()

    run_survey(parse_survey(RUN), out, block_points=BLOCK, on_block=keep)
    return out, kept


def test_a_block_file_is_the_chunks_the_output_holds(whole):
    out, kept = whole
    assert sorted(kept) == ["b00000000.chunks", "b00000001.chunks"], sorted(kept)
    store_chunks = {}
    plan = plan_from_survey(parse_survey(RUN))
    tiling = Tiling.for_grid(plan.shape, BLOCK)
    assert tiling.chunk == (3, 21, 33, 25) and tiling.block == (3, 21, 33, 50)
    names = Manifest.new(plan, tiling).names
    for i in range(tiling.nblocks):
        slab = tiling.slices(i)
        block = read_block(kept[f"b{i:08d}.chunks"], ChunkCodec(1), names, slab, tiling.chunk)
        starts = list(deflate.chunk_starts(slab, tiling.chunk))
        for name, parts in block.chunks.items():
            assert len(parts) == len(starts) == 2
            store_chunks.setdefault(name, {}).update(zip(starts, parts, strict=True))
    output = _data_chunks(out)
    assert set(output) == set(names)
    assert output == store_chunks  # byte for byte, every chunk of every variable
    with netCDF4.Dataset(out) as nc:  # and what the chunks decode to is what the run computed
        assert verify_file(nc)[0]
        for i in (0, tiling.nblocks - 1):
            block = read_block(kept[f"b{i:08d}.chunks"], ChunkCodec(1), names, tiling.slices(i),
                               tiling.chunk)  # fmt: skip
            for name, values in block.items():
                assert np.array_equal(nc[name][tiling.slices(i)], values, equal_nan=True)


def test_a_resume_copies_the_stored_chunks_and_compresses_only_the_new_blocks(
    whole, tmp_path, monkeypatch
):
    out = tmp_path / "o.nc"
    with pytest.raises(KeyboardInterrupt):
        run_survey(parse_survey(RUN), out, block_points=BLOCK, on_block=_stop_after(1))
    assert runs.blocks_in(tmp_path / "o.nc.parts") == 1
    compressed = []
    real = deflate.compress_chunk

    def counted(values, level, shuffled=True):
        compressed.append(values.shape)
        return real(values, level, shuffled)

    monkeypatch.setattr("engine.io.deflate.compress_chunk", counted)
    monkeypatch.setattr("engine.io.chunkfile.compress_chunk", counted)
    stats = run_survey(parse_survey(RUN), out, block_points=BLOCK)
    assert stats.blocks_reused == 1
    # 1 block computed, 2 chunks of each of the 7 variables the blocks hold: the stored block
    # is copied into the output, not compressed again
    assert len(compressed) == 1 * 2 * 7, len(compressed)
    assert _data_chunks(out) == _data_chunks(whole[0])  # the same bytes as an uninterrupted run
    with netCDF4.Dataset(out) as nc, netCDF4.Dataset(whole[0]) as ref:
        assert nc.getncattr("content_checksum") == ref.getncattr("content_checksum")


def test_an_unfinished_run_of_chunk_blocks_opens_for_reading(whole, tmp_path):
    """plot and report read an unfinished run's blocks: the stored block's values, NaN for the
    block not computed yet."""
    out = tmp_path / "o.nc"
    with pytest.raises(KeyboardInterrupt):
        run_survey(parse_survey(RUN), out, block_points=BLOCK, on_block=_stop_after(1))
    tiling = Tiling.for_grid(plan_from_survey(parse_survey(RUN)).shape, BLOCK)
    done, todo = tiling.slices(0), tiling.slices(1)
    partial = open_result(out)
    with netCDF4.Dataset(whole[0]) as ref:
        got = partial.ds["r_max"].values
        assert np.array_equal(got[done], ref["r_max"][done], equal_nan=True)
        assert np.isnan(got[todo]).all()
        assert np.array_equal(partial.ds["orbit_class"].values[done], ref["orbit_class"][done])


@pytest.mark.parametrize("compression", ["none", "zstd"])
def test_other_compressions_keep_npz_blocks_of_the_values(tmp_path, compression):
    out = tmp_path / "o.nc"
    with pytest.raises(KeyboardInterrupt):
        run_survey(parse_survey(RUN), out, block_points=BLOCK, on_block=_stop_after(1),
                   compression=compression)  # fmt: skip
    parts = sorted(os.listdir(tmp_path / "o.nc.parts"))
    assert [p for p in parts if p.startswith("b")] == ["b00000000.npz"]
    assert read_manifest(tmp_path / "o.nc.parts").codec is None
    run_survey(parse_survey(RUN), out, block_points=BLOCK, compression=compression)
    with netCDF4.Dataset(out) as nc:
        assert verify_file(nc)[0]


def test_a_deflated_run_resumed_with_another_compression_decodes_its_blocks(whole, tmp_path):
    out = tmp_path / "o.nc"
    with pytest.raises(KeyboardInterrupt):
        run_survey(parse_survey(RUN), out, block_points=BLOCK, on_block=_stop_after(2))
    run_survey(parse_survey(RUN), out, block_points=BLOCK, compression="none")
    with netCDF4.Dataset(out) as nc, netCDF4.Dataset(whole[0]) as ref:
        assert nc["r_min"].filters()["zlib"] is False
        assert nc.getncattr("content_checksum") == ref.getncattr("content_checksum")


# --- the store, without a run ---------------------------------------------------------------


@pytest.fixture
def store(tmp_path):
    plan = plan_from_survey(parse_survey(SURVEY))
    return BlockStore.create(tmp_path / "o.nc.parts", Manifest.new(plan, TILING, ChunkCodec(1)))


def _block(store, index, seed=0):
    rng = np.random.default_rng(seed)
    shape = tuple(s.stop - s.start for s in store.tiling.slices(index))
    out = {}
    for name, dt in store.names.items():
        out[name] = (rng.integers(0, 4, shape) if dt.kind in "iu" else rng.random(shape)).astype(dt)
    out[next(n for n, dt in store.names.items() if dt.kind == "f")][0, 0, 0, :3] = np.nan
    return out


def test_commit_and_load_give_back_the_values_and_the_chunks(store):
    index = store.tiling.nblocks - 1  # hangs over three axes: edge chunks padded
    arrays = _block(store, index)
    stored = store.commit(index, arrays)
    assert isinstance(stored, StoredBlock) and stored.codec == ChunkCodec(1)
    data = store.path(index).read_bytes()
    assert store.path(index).name == f"b{index:08d}.chunks"
    assert store.journal[index] == (len(data), hashlib.sha256(data).hexdigest())
    assert len(stored.chunks[next(iter(arrays))]) == 4  # (1, 6, 13, 16) in (2, 7, 10, 12)
    assert len(data) <= block_file_bytes(store.names, store.tiling.points(index), 4)
    back = store.load(index)
    assert back.chunks == stored.chunks
    for name, values in arrays.items():
        assert back[name].dtype == values.dtype
        assert np.array_equal(back[name], values, equal_nan=True)
    # the chunk bytes are what HDF5's shuffle and deflate filters store for the padded chunk
    slab, chunk = store.tiling.slices(index), store.tiling.chunk
    name = next(iter(arrays))
    for (start, part), data in zip(deflate.chunk_parts(slab, chunk, arrays[name]),
                                   stored.chunks[name], strict=True):  # fmt: skip
        assert part.shape == chunk and start[0] >= slab[0].start
        assert np.array_equal(deflate.decompress_chunk(data, part.dtype, chunk), part,
                              equal_nan=True)  # fmt: skip


def test_a_changed_chunk_block_is_caught_by_scan_and_load(store):
    store.commit(0, _block(store, 0))
    store.commit(1, _block(store, 1))
    path = store.path(1)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    path.write_bytes(bytes(data))
    found = store.scan()
    assert found.good == {0} and found.bad == {path.name: "its checksum does not match the journal"}
    with pytest.raises(OutputError, match="changed since it was written"):
        store.load(1)


def test_a_block_of_the_other_kind_is_not_one_of_the_store(store):
    store.commit(0, _block(store, 0))
    (store.root / "b00000001.npz").write_bytes(b"an npz block of another store")
    found = store.scan()
    assert found.good == {0} and found.stray == ["b00000001.npz"]


@pytest.mark.parametrize(
    ("damage", "why"),
    [
        (lambda d: b"XXXXXXXX" + d[8:], "not a chunk block file"),
        (lambda d: d[:-1], "do not fill the file"),
        (lambda d: d + b"\0", "do not fill the file"),
        (lambda d: d.replace(b'"level":1', b'"level":2', 1), "not compressed as the store's"),
        (lambda d: d.replace(b"orbit_class", b"orbit_clasz", 1), "variables are not the store's"),
    ],
)
def test_a_journaled_file_that_is_not_this_block_is_unreadable(store, damage, why):
    """A block file whose journal line matches (written by something else, or a journal
    forged to match) is still checked field by field as it is decoded."""
    store.commit(2, _block(store, 2))
    data = damage(store.path(2).read_bytes())
    with pytest.raises(OutputError, match=why):
        store.decode(2, data)


def test_a_chunk_that_does_not_inflate_to_its_values_is_unreadable(store):
    block = store.commit(0, _block(store, 0))
    name = next(iter(block))
    first = block.chunks[name][0]
    bad = StoredBlock(block, {**block.chunks, name: [first[:-4] + bytes(b ^ 0xFF for b in
                      first[-4:]), *block.chunks[name][1:]]}, block.codec)  # fmt: skip
    with open(store.root / "x", "wb") as f:
        write_block(f, bad)  # a wrong Adler-32 at the end of the first chunk
    with pytest.raises(OutputError, match="does not decompress"):
        store.decode(0, (store.root / "x").read_bytes())


def test_the_manifest_records_the_codec_and_refuses_a_bad_one(store):
    m = read_manifest(store.root)
    assert m.codec == ChunkCodec(1, True)
    doc = m.to_doc()
    assert doc["blocks"] == {"codec": "deflate", "level": 1, "shuffle": True}
    assert Manifest.from_doc(doc) == m
    for bad in ({"codec": "lz4", "level": 1, "shuffle": True}, {"codec": "deflate", "level": 0,
                "shuffle": True}, {"codec": "deflate", "level": 1}):  # fmt: skip
        forged = {**doc, "blocks": bad}
        body = {k: v for k, v in forged.items() if k != "check"}  # the documented self-check
        forged["check"] = hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()
        with pytest.raises(ValueError, match="blocks"):
            Manifest.from_doc(forged)

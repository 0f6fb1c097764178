"""Block files that hold a block's storage chunks compressed as the netCDF output stores them.

A streamed run whose output is written with deflate (``zlib``, the default) compresses each
block once: its chunks, shuffled and deflated as HDF5's filters store them
(:func:`engine.io.deflate.compress_chunk`, on every core), are the block file, hashed once as
it is written, and the very bytes the merge writes into the output (HDF5 direct chunk writes,
:meth:`engine.io.deflate.DirectChunks.copy`): a block read back on resume is copied, never
compressed again. A block file is ~0.6 of the values' size (the ``.npz`` of the values was
written, hashed and read again whole before).

File ``bNNNNNNNN.chunks`` (:data:`SUFFIX`)::

    b"CSCHNK01"                 8 bytes, the format
    header length               8 bytes, unsigned little-endian
    header                      JSON: {"level": L, "shuffle": S,
                                       "variables": [[name, dtype, [size of each chunk]], ...]}
    the chunks                  variable by variable (the store's order), each variable's
                                chunks in C order of their first index (those at the end of an
                                axis padded to the whole chunk, as HDF5 stores them)

The codec a store writes is recorded in its manifest (``"blocks"``: :meth:`ChunkCodec.to_doc`;
absent: ``.npz`` files of the values, :mod:`engine.io.npz`). Reading checks every field
against the block it should be (names, dtypes, number of chunks, sizes adding up to the file)
and that every chunk inflates to exactly its values.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Mapping
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any, BinaryIO

import numpy as np

from . import deflate
from .codecs import compression_keywords
from .deflate import chunk_parts, chunk_starts, compress_chunk, decompress_chunk

__all__ = [
    "MAGIC",
    "SUFFIX",
    "ChunkCodec",
    "StoredBlock",
    "block_codec",
    "read_block",
    "write_block",
]

MAGIC = b"CSCHNK01"
SUFFIX = ".chunks"
_LENGTH = struct.Struct("<Q")
_MAX_HEADER = 1 << 24


class StoredBlock(dict):  # type: ignore[type-arg]
    """A block as its store holds it: name -> values (C-contiguous, the store's dtypes), and
    where the store holds compressed chunks, ``chunks`` (name -> the bytes of each storage chunk,
    in the order of :func:`engine.io.deflate.chunk_parts`) and the ``codec`` that made them."""

    def __init__(
        self,
        arrays: Mapping[str, np.ndarray],
        chunks: dict[str, list[bytes]] | None = None,
        codec: ChunkCodec | None = None,
    ) -> None:
        super().__init__(arrays)
        self.chunks = chunks
        self.codec = codec


@dataclass(frozen=True)
class ChunkCodec:
    """Deflate at ``level`` (1-9), after HDF5's byte shuffle if ``shuffle``."""

    level: int
    shuffle: bool = True

    def to_doc(self) -> dict[str, Any]:
        return {"codec": "deflate", "level": self.level, "shuffle": self.shuffle}

    @classmethod
    def from_doc(cls, doc: Any) -> ChunkCodec:
        """The codec a manifest's ``"blocks"`` names; ValueError saying what is wrong."""
        if not isinstance(doc, dict) or set(doc) != {"codec", "level", "shuffle"}:
            raise ValueError(f"blocks must be {{codec, level, shuffle}}, got {doc!r}")
        lvl, shuf = doc["level"], doc["shuffle"]
        if doc["codec"] != "deflate" or not isinstance(shuf, bool):
            raise ValueError(f"blocks codec {doc!r} is not deflate with a shuffle flag")
        if not isinstance(lvl, int) or isinstance(lvl, bool) or not 1 <= lvl <= 9:
            raise ValueError(f"blocks level {lvl!r} is not an integer 1..9")
        return cls(lvl, shuf)

    def encode(
        self,
        slab: tuple[slice, ...],
        chunk: tuple[int, ...],
        arrays: Mapping[str, np.ndarray],
        pool: Executor,
    ) -> dict[str, list[bytes]]:
        """The compressed chunks of the block ``arrays`` at ``slab``, made on ``pool``."""
        jobs = {
            name: [
                pool.submit(compress_chunk, part, self.level, self.shuffle)
                for _, part in chunk_parts(slab, chunk, values)
            ]
            for name, values in arrays.items()
        }
        return {name: [j.result() for j in js] for name, js in jobs.items()}


def block_codec(compression: str, complevel: int | None) -> ChunkCodec | None:
    """The codec of the block files of a netCDF run written with ``compression`` at
    ``complevel``: deflate as the output's variables, where they are deflated and h5py can
    write their chunks directly; None (``.npz`` files of the values) otherwise."""
    kw = compression_keywords(compression, complevel)
    if kw.get("compression") != "zlib" or deflate.unavailable():
        return None
    return ChunkCodec(int(kw["complevel"]), bool(kw.get("shuffle", False)))


def write_block(f: BinaryIO, block: StoredBlock) -> None:
    """Write the block file of ``block`` (its ``chunks`` and ``codec``) to the binary file
    ``f``."""
    codec = block.codec
    if block.chunks is None or codec is None:
        raise ValueError("a block file holds compressed chunks: the block has none")
    header = {
        "level": codec.level,
        "shuffle": codec.shuffle,
        "variables": [
            [name, np.dtype(values.dtype).str, [len(c) for c in block.chunks[name]]]
            for name, values in block.items()
        ],
    }
    text = json.dumps(header, separators=(",", ":")).encode()
    f.write(MAGIC + _LENGTH.pack(len(text)) + text)
    for name in block:
        for data in block.chunks[name]:
            f.write(data)


def read_block(
    data: bytes,
    codec: ChunkCodec,
    names: Mapping[str, np.dtype],
    slab: tuple[slice, ...],
    chunk: tuple[int, ...],
) -> StoredBlock:
    """The block a block file's bytes ``data`` hold, which should be the block at ``slab`` of
    the variables ``names`` in storage chunks of ``chunk`` by ``codec``: its values decoded and
    its chunks as they are. ValueError saying what does not fit."""
    view = memoryview(data)
    if bytes(view[:8]) != MAGIC or len(view) < 16:
        raise ValueError("not a chunk block file")
    (n,) = _LENGTH.unpack(view[8:16])
    if n > min(_MAX_HEADER, len(view) - 16):
        raise ValueError("its header is cut off")
    try:
        header = json.loads(bytes(view[16 : 16 + n]))
        found = [(str(a), str(b), [int(s) for s in c]) for a, b, c in header["variables"]]
        same = header["level"] == codec.level and header["shuffle"] == codec.shuffle
    except (ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"its header is unreadable ({exc})") from None
    if not same:
        raise ValueError("its chunks are not compressed as the store's")
    expected = [(name, np.dtype(dt).str) for name, dt in names.items()]
    if [(a, b) for a, b, _ in found] != expected:
        raise ValueError("its variables are not the store's")
    shape = tuple(s.stop - s.start for s in slab)
    count = math.prod(-(-n // c) for n, c in zip(shape, chunk, strict=True))
    sizes = [c for _, _, c in found]
    if any(len(c) != count or min(c, default=1) < 1 for c in sizes):
        raise ValueError(f"it does not hold {count} chunks of each variable")
    if 16 + n + sum(map(sum, sizes)) != len(view):
        raise ValueError("its chunks do not fill the file")
    at = 16 + n
    arrays, chunks = {}, {}
    for (name, dtype), lengths in zip(names.items(), sizes, strict=True):
        values = np.empty(shape, dtype)
        parts = []
        for start, size in zip(chunk_starts(slab, chunk), lengths, strict=True):
            part = bytes(view[at : at + size])
            at += size
            decoded = decompress_chunk(part, dtype, chunk, codec.shuffle)
            local = tuple(
                slice(o - s.start, min(o + c, s.stop) - s.start)
                for o, s, c in zip(start, slab, chunk, strict=True)
            )
            values[local] = decoded[tuple(slice(0, sl.stop - sl.start) for sl in local)]
            parts.append(part)
        arrays[name], chunks[name] = values, parts
    return StoredBlock(arrays, chunks, codec)

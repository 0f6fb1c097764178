"""The bytes of a Zarr store's chunks: how its data variables are compressed, their fill
value, the keys of a block's chunk files, and the files themselves.

:func:`encode` makes the chunk files of a block without zarr's array machinery (an array
object per variable per block cost ~4x the compression itself): each chunk's values as
little-endian bytes, compressed by the numcodecs Blosc that zarr's ``BloscCodec`` uses, on
every core (:func:`engine.io.deflate.compress_pool`; Blosc releases the GIL). The bytes are
those zarr writes for the same values (tests/io/test_zarrchunks.py compares them with zarr's
own), so any Zarr reader decodes them with the codecs the store's metadata declares.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from typing import Any

import numpy as np

from .deflate import chunk_parts, compress_pool

__all__ = [
    "BLOSC",
    "SEPARATOR",
    "chunk_key",
    "chunk_key_encoding",
    "chunk_keys",
    "codecs",
    "encode",
    "fill_value",
]

#: Blosc (lz4, level 5, byte shuffle): 1.57x on survey blocks at ~600 MB/s on one core, where
#: netCDF's zlib 1 + shuffle gives 1.63x at ~33 MB/s (README, "Scale out: Zarr output").
BLOSC = {"cname": "lz4", "clevel": 5, "shuffle": "shuffle"}

#: The separator of the chunk keys of a new store (chunk key encoding "default"): "." keeps a
#: variable's chunk files in its own directory, ``r_min/c.0.3.2.1``. With "/" (stores made
#: before 2026-11-27) each chunk file sat in directories of its own, ``r_min/c/0/3/2/1``: up to
#: three directories made and opened per chunk file, and with the files made one after another
#: that was ~3/4 of the Zarr writer's time (docs/output.md, "Zarr stores"). A resumed store
#: keeps its own.
SEPARATOR = "."


def chunk_key_encoding(separator: str = SEPARATOR) -> dict[str, Any]:
    """The ``chunk_key_encoding`` of a data variable's metadata (Zarr v3 "default")."""
    return {"name": "default", "separator": separator}


def codecs(complevel: int) -> list[Any]:
    """The compressors of a data variable: Blosc (:data:`BLOSC`), none for ``complevel`` 0."""
    if complevel == 0:
        return []
    from zarr.codecs import BloscCodec

    return [BloscCodec(**BLOSC)]


@functools.cache
def _blosc(dtype: str, complevel: int) -> Any:
    """The numcodecs Blosc that zarr's ``BloscCodec(**BLOSC)`` encodes an array of ``dtype``
    with (its type size set from the dtype, as zarr does with numcodecs >= 0.16); None for
    ``complevel`` 0 (no compressor)."""
    if complevel == 0:
        return None
    import numcodecs
    from numcodecs import Blosc
    from packaging.version import Version

    config = {**BLOSC, "shuffle": Blosc.SHUFFLE, "blocksize": 0}
    if Version(numcodecs.__version__) >= Version("0.16"):  # packaging: a dependency of zarr
        config["typesize"] = np.dtype(dtype).itemsize
    return Blosc(**config)


def _chunk_file(part: np.ndarray, dtype: np.dtype, codec: Any) -> bytes:
    raw = np.ascontiguousarray(part, dtype=dtype.newbyteorder("<"))
    return raw.tobytes() if codec is None else bytes(codec.encode(raw))


def fill_value(dtype: np.dtype) -> Any:
    """Zarr's fill value of a variable (never read: every chunk is written): NaN for floats,
    netCDF's default fill for integers (not a flag value). It is not a CF ``_FillValue``."""
    if dtype.kind == "f":
        return np.nan
    return {1: -127, 2: -32767, 4: -2147483647, 8: -9223372036854775806}[dtype.itemsize]


def chunk_key(name: str, index: Iterable[int], separator: str = SEPARATOR) -> str:
    """The key of the chunk of variable ``name`` at chunk ``index`` (encoding "default")."""
    return f"{name}/c{separator}" + separator.join(str(i) for i in index)


def chunk_keys(
    name: str, slab: tuple[slice, ...], chunk: tuple[int, ...], separator: str = SEPARATOR
) -> list[str]:
    """The keys of the chunk files of variable ``name`` that the hyperslab ``slab`` covers
    (chunk key encoding "default" with ``separator``)."""
    ranges = [range(s.start // c, -(-s.stop // c)) for s, c in zip(slab, chunk, strict=True)]
    return [
        chunk_key(name, (r[p] for r, p in zip(ranges, pos, strict=True)), separator)
        for pos in np.ndindex(*(len(r) for r in ranges))
    ]


def encode(
    slab: tuple[slice, ...],
    chunk: tuple[int, ...],
    arrays: tuple[tuple[str, str], ...],
    values: dict[str, np.ndarray],
    complevel: int,
    separator: str = SEPARATOR,
) -> dict[str, bytes]:
    """The chunk files (key -> bytes) of the block ``values`` at the hyperslab ``slab`` of
    every variable of ``arrays`` ((name, dtype) pairs), chunks of shape ``chunk``: the bytes
    zarr writes for them (little-endian values, then Blosc as :func:`codecs` declares; an edge
    chunk padded with the fill value), keyed with ``separator``."""
    jobs = {}
    pool = compress_pool()
    for name, dtype in arrays:
        dt = np.dtype(dtype)
        codec = _blosc(dt.str, complevel)
        for start, part in chunk_parts(slab, chunk, values[name], fill_value(dt)):
            index = (s // c for s, c in zip(start, chunk, strict=True))
            jobs[chunk_key(name, index, separator)] = pool.submit(_chunk_file, part, dt, codec)
    return {key: job.result() for key, job in jobs.items()}

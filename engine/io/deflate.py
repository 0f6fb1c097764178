"""Deflate chunks compressed on every core and written as HDF5 direct chunk writes.

HDF5 runs its filters on the thread that writes, one chunk at a time: through netCDF4, zlib
level 1 with shuffle writes ~60-80 MB/s, a fifth of what the compute produces. The same bytes
can be made outside HDF5: a chunk through HDF5's shuffle filter is its values' bytes regrouped
by byte position (byte ``j`` of every value, then byte ``j + 1``, ...; a no-op for 1-byte
types), and through its deflate filter a zlib stream (RFC 1950). :class:`DirectChunks` makes
both in numpy and a deflate library on a thread pool (both release the GIL), then hands each
finished chunk to ``H5Dwrite_chunk`` through h5py. The file is an ordinary netCDF-4 file whose
variables declare the shuffle and deflate filters (defined by netCDF4 before): every
netCDF-4/HDF5 reader decodes it with its built-in filters.

The deflate library: ISA-L (the ``isal`` package: Intel's Intelligent Storage Acceleration
Library, BSD, wheels for Linux, macOS and Windows) for levels 1-3, ~8x zlib's speed at level 1
with ~10 % less ratio; Python's ``zlib`` for levels 4-9 and where ``isal`` is not installed
(the same format, slower).
"""

from __future__ import annotations

import concurrent.futures
import itertools
import math
import os
import zlib
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

try:
    from isal import isal_zlib
except ImportError:  # pragma: no cover - isal is a dependency; zlib writes the same format
    isal_zlib = None

__all__ = [
    "DirectChunks",
    "chunk_parts",
    "chunk_starts",
    "compress_chunk",
    "compress_pool",
    "decompress_chunk",
    "shuffle",
    "unavailable",
]

#: HDF5's filter ids (H5Zpublic.h): deflate and shuffle.
_DEFLATE, _SHUFFLE = 1, 2


def unavailable() -> str:
    """Why chunks cannot be written directly here ("" if they can): h5py is missing."""
    try:
        import h5py  # noqa: F401
    except ImportError as exc:
        return f"h5py is not installed ({exc})"
    return ""


def shuffle(values: np.ndarray) -> bytes:
    """The bytes HDF5's shuffle filter makes of the C-ordered ``values``."""
    arr = np.ascontiguousarray(values)
    size = arr.dtype.itemsize
    if size == 1:
        return arr.tobytes()
    return arr.reshape(-1).view(np.uint8).reshape(-1, size).T.tobytes()


def compress_chunk(values: np.ndarray, level: int, shuffled: bool = True) -> bytes:
    """One chunk as HDF5's (shuffle and) deflate filters at ``level`` store it."""
    raw = shuffle(values) if shuffled else np.ascontiguousarray(values).tobytes()
    if isal_zlib is not None and 1 <= level <= 3:
        return isal_zlib.compress(raw, level)
    return zlib.compress(raw, level)


def decompress_chunk(
    data: bytes, dtype: np.dtype, shape: tuple[int, ...], shuffled: bool = True
) -> np.ndarray:
    """The values of a chunk :func:`compress_chunk` made (ValueError if ``data`` is not a zlib
    stream of exactly that many values)."""
    dtype = np.dtype(dtype)
    n = math.prod(shape)
    try:
        raw = (isal_zlib or zlib).decompress(data)
    except Exception as exc:  # isal and zlib raise their own errors
        raise ValueError(f"a chunk does not decompress ({exc})") from None
    if len(raw) != n * dtype.itemsize:
        raise ValueError(f"a chunk holds {len(raw)} bytes, not {n * dtype.itemsize}")
    flat = np.frombuffer(raw, np.uint8)
    if shuffled and dtype.itemsize > 1:
        flat = flat.reshape(dtype.itemsize, n).T.copy()
    return flat.view(dtype).reshape(shape)


def chunk_parts(
    slab: tuple[slice, ...], chunk: tuple[int, ...], values: np.ndarray, fill: Any = 0
) -> Iterator[tuple[tuple[int, ...], np.ndarray]]:
    """(first index, values) of every storage chunk of the block ``values`` at ``slab``, in C
    order; a chunk at the end of an axis that hangs over it is padded to the whole chunk with
    ``fill`` (zeros, as HDF5 stores it; Zarr pads with the array's fill value)."""
    for start in chunk_starts(slab, chunk):
        at = zip(start, slab, chunk, strict=True)
        local = tuple(slice(o - s.start, o - s.start + c) for o, s, c in at)
        part = values[local]
        if part.shape != chunk:  # an edge chunk: HDF5 stores it whole
            full = np.full(chunk, fill, values.dtype)
            full[tuple(slice(0, n) for n in part.shape)] = part
            part = full
        yield start, part


def chunk_starts(slab: tuple[slice, ...], chunk: tuple[int, ...]) -> Iterator[tuple[int, ...]]:
    """The first index of every storage chunk in ``slab`` (a whole multiple of chunks)."""
    ranges = [range(s.start, s.stop, c) for s, c in zip(slab, chunk, strict=True)]
    return itertools.product(*ranges)


class DirectChunks:
    """Writes blocks of the deflate-compressed variables ``names`` of the netCDF-4 file
    ``path`` (defined, closed) as direct chunk writes; chunks are compressed on ``threads``
    threads (default: every core). Use as a context manager (it opens and closes the file).

    ValueError if a variable's filters are not deflate, optionally after shuffle (the file
    was not defined for it)."""

    def __init__(self, path: Path, names: Mapping[str, np.dtype], threads: int | None = None):
        import h5py

        self._file = h5py.File(path, "r+")
        self._pool = concurrent.futures.ThreadPoolExecutor(
            threads or _cores(), thread_name_prefix="conesurvey-deflate"
        )
        self._vars: dict[str, tuple[Any, int, bool]] = {}
        try:
            for name in names:
                dset = self._file[name]
                self._vars[name] = (dset, *_pipeline(dset))
        except BaseException:
            self.close()
            raise

    def __enter__(self) -> DirectChunks:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._pool.shutdown(wait=True)
        self._file.close()

    def write(self, name: str, slab: tuple[slice, ...], values: np.ndarray) -> None:
        """Write the block ``values`` of variable ``name`` at ``slab`` (whole chunks; those at
        the end of an axis may hang over it, as HDF5's own do)."""
        self.submit(name, slab, values)()

    def submit(self, name: str, slab: tuple[slice, ...], values: np.ndarray) -> Callable[[], None]:
        """Start compressing the chunks of :meth:`write` on the pool; returns the call that
        writes them, in order, as they finish (the caller may hash meanwhile, and submit
        every variable of a block first so that the pool never waits for the writer)."""
        dset, level, shuffled = self._vars[name]
        jobs = [
            (start, self._pool.submit(compress_chunk, part, level, shuffled))
            for start, part in chunk_parts(slab, dset.chunks, values)
        ]

        def finish() -> None:
            try:
                for start, job in jobs:
                    dset.id.write_direct_chunk(start, job.result())
            finally:  # a failed write: the chunks not written yet are not compressed either
                for _, job in jobs:
                    job.cancel()

        return finish

    def copies(self, name: str, codec: Any, chunk: tuple[int, ...]) -> bool:
        """Whether chunks compressed by ``codec`` (its ``level`` and ``shuffle``; None: not
        compressed) in storage chunks of ``chunk`` are what variable ``name`` stores (then
        :meth:`copy` writes them as they are)."""
        dset, lvl, shuf = self._vars[name]
        if codec is None:
            return False
        return (lvl, shuf, tuple(dset.chunks)) == (codec.level, codec.shuffle, tuple(chunk))

    def copy(self, name: str, slab: tuple[slice, ...], chunks: list[bytes]) -> Callable[[], None]:
        """The call that writes ``chunks`` (compressed already, in the order of
        :func:`chunk_parts`) of variable ``name`` at ``slab`` as they are: nothing is
        compressed again."""
        dset = self._vars[name][0]
        starts = list(chunk_starts(slab, dset.chunks))
        if len(starts) != len(chunks):
            raise ValueError(f"{name}: {len(chunks)} chunks for the {len(starts)} of the block")

        def finish() -> None:
            for start, data in zip(starts, chunks, strict=True):
                dset.id.write_direct_chunk(start, data)

        return finish


_POOL: list[concurrent.futures.ThreadPoolExecutor] = []


def compress_pool() -> concurrent.futures.ThreadPoolExecutor:
    """A thread pool of one thread per core, shared by everything that compresses chunks
    outside a :class:`DirectChunks` (the block files of a run, :mod:`engine.io.chunkfile`)."""
    if not _POOL:
        _POOL.append(
            concurrent.futures.ThreadPoolExecutor(_cores(), thread_name_prefix="conesurvey-zip")
        )
    return _POOL[0]


def _cores() -> int:
    """The cores this process may run on (a container's or a batch job's share)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def _pipeline(dset: Any) -> tuple[int, bool]:
    """(deflate level, shuffled) of an h5py dataset whose filters are [shuffle,] deflate."""
    plist = dset.id.get_create_plist()
    filters = [plist.get_filter(i) for i in range(plist.get_nfilters())]
    ids = [f[0] for f in filters]
    if ids not in ([_SHUFFLE, _DEFLATE], [_DEFLATE]):
        raise ValueError(f"{dset.name}: filters {ids} are not [shuffle,] deflate")
    return int(filters[-1][2][0]), ids[0] == _SHUFFLE

"""Disk space: the free bytes of a file system, and upper bounds of what a run and a result take,
from the layout they are stored in (each backend's sizes are these).

What is counted (docs/guarantees.md, "Every refusal comes before anything is written"):

- every storage chunk whole: HDF5 and Zarr store the chunks at the end of an axis padded to the
  whole chunk (a 65-long axis in chunks of 9 stores 72), compressed or not (deflate and Blosc
  grow what they cannot shrink by less than :data:`CHUNK_OVERHEAD`);
- each variable on the dims it is stored on (r_circ and V_min on (alpha, h, Lz), in chunks of
  their own), the axes, the metadata (:data:`VARIABLE_OVERHEAD` a variable, the survey text as
  often as it is stored, :data:`FIXED`);
- each file in whole allocation units of its file system (a Zarr store is a file per chunk),
  and a directory entry per file;
- what a run keeps beside its output: the block files of a netCDF run (the values of a block's
  whole chunks), a store's journal, manifest, commit record and the root written twice.
"""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..grid import storage_chunks
from ..schema import variable_dims

if TYPE_CHECKING:
    from ..grid import Tiling
    from .planshape import RunPlan

__all__ = [
    "CHUNK_OVERHEAD",
    "allocation_unit",
    "block_files_bytes",
    "free_bytes",
    "netcdf_bytes",
    "output_bytes",
    "store_bytes",
]

#: What a stored chunk may take beyond its values [bytes]: deflate's stored blocks (5 bytes a
#: 64 kB), Blosc's header and block offsets, HDF5's entry in the chunk index.
CHUNK_OVERHEAD = 1024
#: A variable's metadata [bytes]: an HDF5 object header with its attributes, a Zarr array's
#: ``zarr.json``.
VARIABLE_OVERHEAD = 64 << 10
#: A file's own metadata, the global attributes but the survey text, margins [bytes].
FIXED = 1 << 20
#: A directory entry (name, inode number, record) [bytes], counted per file.
ENTRY = 64
#: A manifest beside the survey text in it [bytes].
MANIFEST = 64 << 10
#: A journal line (a block's size, checksums, statistics) [bytes].
JOURNAL_LINE = 4096


def free_bytes(directory: Path) -> int:
    """Free bytes on the file system of ``directory`` (0 where that cannot be read)."""
    try:
        return shutil.disk_usage(directory).free
    except OSError:
        return 0


def allocation_unit(directory: Path) -> int:
    """The unit a file of ``directory``'s file system takes space in [bytes] (4096 where it
    cannot be read)."""
    try:
        st = os.statvfs(directory)
        return max(512, st.f_frsize or st.f_bsize)
    except (OSError, AttributeError):
        return 4096


def _on_disk(size: int, unit: int) -> int:
    return -(-size // unit) * unit + ENTRY


def _chunks(shape: tuple[int, ...], chunk: tuple[int, ...]) -> int:
    return math.prod(-(-n // c) for n, c in zip(shape, chunk, strict=True))


def _variables(
    names: Mapping[str, Any], tiling: Tiling, dims: tuple[str, ...]
) -> list[tuple[int, tuple[int, ...], tuple[int, ...]]]:
    """(itemsize, shape, storage chunk) of each variable: on the grid in the tiling's chunks,
    one on fewer dims (:func:`engine.schema.variable_dims`) in chunks of its own shape."""
    out = []
    for name, dt in names.items():
        vdims = variable_dims(name, dims)
        if vdims == tuple(dims):
            out.append((np.dtype(dt).itemsize, tiling.shape, tiling.chunk))
        else:
            shape = tuple(tiling.shape[dims.index(d)] for d in vdims)
            out.append((np.dtype(dt).itemsize, shape, storage_chunks(shape)))
    return out


def _text(plan: RunPlan) -> int:
    return len((plan.source_text or "").encode()) + len((plan.title or "").encode())


def netcdf_bytes(plan: RunPlan, tiling: Tiling, unit: int) -> int:
    """Upper bound [bytes] of the netCDF file of ``plan``'s run in ``tiling``."""
    data = sum(
        size * math.prod(chunk) * _chunks(shape, chunk)
        + CHUNK_OVERHEAD * _chunks(shape, chunk)
        + VARIABLE_OVERHEAD
        for size, shape, chunk in _variables(plan.variables, tiling, tuple(plan.dims))
    )
    axes = 8 * sum(tiling.shape) + VARIABLE_OVERHEAD * len(tiling.shape)
    return _on_disk(data + axes + _text(plan) + FIXED, unit)


def block_files_bytes(plan: RunPlan, tiling: Tiling, pending: list[int], unit: int) -> int:
    """Upper bound [bytes] of the block files of ``pending`` blocks (each block's whole chunks,
    as a ``.chunks`` file holds them, or its values, as an ``.npz``), their journal lines and
    the manifest."""
    names = {n: dt for n, dt in plan.variables.items()
             if variable_dims(n, tuple(plan.dims)) == tuple(plan.dims)}  # fmt: skip
    itemsizes = sum(np.dtype(dt).itemsize for dt in names.values())
    total = 0
    for i in pending:
        chunks = _chunks(tuple(s.stop - s.start for s in tiling.slices(i)), tiling.chunk)
        values = itemsizes * math.prod(tiling.chunk) * chunks
        framing = (CHUNK_OVERHEAD * chunks + 512) * len(names) + 512
        total += _on_disk(values + framing, unit) + JOURNAL_LINE
    return total + _on_disk(_text(plan) + MANIFEST, unit)


def store_bytes(plan: RunPlan, tiling: Tiling, pending: list[int], unit: int) -> int:
    """Upper bound [bytes] of what a Zarr run of ``plan`` still writes: a file per chunk of
    the ``pending`` blocks, and in full the axes, the variables on fewer dims, every array's
    metadata, the root (written twice at the commit, with the survey text and the
    consolidated metadata), the commit record, the manifest and the journal."""
    dims = tuple(plan.dims)
    grid = [(s, c) for s, shape, c in _variables(plan.variables, tiling, dims)
            if shape == tiling.shape]  # fmt: skip
    total = 0
    for i in pending:
        chunks = _chunks(tuple(s.stop - s.start for s in tiling.slices(i)), tiling.chunk)
        total += sum(chunks * _on_disk(s * math.prod(c) + CHUNK_OVERHEAD, unit) for s, c in grid)
        total += JOURNAL_LINE
    fewer = [(s, shape, c) for s, shape, c in _variables(plan.variables, tiling, dims)
             if shape != tiling.shape]  # fmt: skip
    total += sum(_chunks(shape, c) * _on_disk(s * math.prod(c) + CHUNK_OVERHEAD, unit)
                 for s, shape, c in fewer)  # fmt: skip
    total += sum(_on_disk(8 * n, unit) for n in tiling.shape)
    arrays = len(plan.variables) + len(dims)
    total += arrays * _on_disk(VARIABLE_OVERHEAD, unit)
    root = arrays * VARIABLE_OVERHEAD + _text(plan) + FIXED
    return total + 3 * _on_disk(root, unit) + _on_disk(_text(plan) + MANIFEST, unit)


def output_bytes(
    names: Mapping[str, np.dtype], shape: tuple[int, ...], chunk: tuple[int, ...] | None = None
) -> int:
    """Upper bound [bytes] of a result with the variables ``names`` over a grid of ``shape``
    stored in chunks of ``chunk`` (default: a run's, :func:`engine.grid.storage_chunks`):
    every chunk whole with :data:`CHUNK_OVERHEAD`, the axes, the metadata."""
    chunk = chunk or storage_chunks(shape)
    n = _chunks(shape, chunk)
    data = sum(np.dtype(dt).itemsize for dt in names.values()) * math.prod(chunk) * n
    meta = (CHUNK_OVERHEAD * n + VARIABLE_OVERHEAD) * len(names) + 8 * sum(shape)
    return int(data * 1.01) + meta + FIXED

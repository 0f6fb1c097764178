"""Disk space: the free bytes of a file system, and an upper bound of a result's size (the same
for every backend; each backend's ``output_bytes`` is this one)."""

from __future__ import annotations

import math
import shutil
from collections.abc import Mapping
from pathlib import Path

import numpy as np

__all__ = ["free_bytes", "output_bytes"]


def free_bytes(directory: Path) -> int:
    """Free bytes on the file system of ``directory`` (0 where that cannot be read)."""
    try:
        return shutil.disk_usage(directory).free
    except OSError:
        return 0


def output_bytes(names: Mapping[str, np.dtype], shape: tuple[int, ...]) -> int:
    """Upper bound [bytes] of a result with the variables ``names`` over a grid of ``shape``:
    the values uncompressed (zlib and zstd grow incompressible data by < 0.5 %, blosc stores it
    as is plus 16 bytes a chunk), the axes, 1 % and 1 MB for metadata (HDF5's chunk indices and
    attributes, a store's file system blocks, the survey definition)."""
    points = math.prod(shape)
    data = sum(np.dtype(dt).itemsize for dt in names.values()) * points + 8 * sum(shape)
    return int(data * 1.01) + (1 << 20)

"""Block files in numpy's ``.npz`` format (an uncompressed zip of ``.npy`` members), written
from the arrays' own memory.

``np.savez`` sends every array through :mod:`zipfile` in 16 MiB copies and takes the zip's
CRC-32 with zlib's: on a streamed run's blocks (38 MB each) that was a sixth of the write
path's CPU time. :func:`write_npz` writes the same format, which ``np.load`` reads (checking
each member's CRC), with no copy of the values and the CRC by ISA-L's ``crc32`` where the
``isal`` package is installed (zlib's otherwise). Members of 4 GiB or more (the zip64
extension) are left to ``np.savez``.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Mapping
from typing import BinaryIO

import numpy as np

try:
    from isal.isal_zlib import crc32
except ImportError:  # pragma: no cover - isal is a dependency; zlib gives the same CRC
    crc32 = zlib.crc32

__all__ = ["write_npz"]

_LOCAL = struct.Struct("<IHHHHHIIIHH")  # local file header (30 bytes + the name)
_CENTRAL = struct.Struct("<IHHHHHHIIIHHHHHII")  # central directory entry (46 bytes + the name)
_END = struct.Struct("<IHHHHIIH")  # end of central directory (22 bytes)
_VERSION = 20  # zip 2.0: stored members
_DATE = 0x21  # 1980-01-01, the zip epoch (the time fields say nothing here)
_LIMIT = 0xFFFFFFFF  # beyond it: zip64, np.savez's


def write_npz(f: BinaryIO, arrays: Mapping[str, np.ndarray]) -> None:
    """Write ``arrays`` (name -> array) to the binary file ``f`` (at its start) as an ``.npz``
    that ``np.load`` reads back, member ``NAME.npy`` for each, in order."""
    members = []
    for name, arr in arrays.items():
        values = np.ascontiguousarray(arr)
        head = io.BytesIO()
        np.lib.format.write_array_header_1_0(head, np.lib.format.header_data_from_array_1_0(values))
        members.append((f"{name}.npy".encode(), head.getvalue(), values.reshape(-1).view(np.uint8)))
    total = sum(30 + 46 + len(n) + len(h) + d.size for n, h, d in members)
    if total >= _LIMIT:
        np.savez(f, **arrays)
        return
    central = []
    offset = 0
    for name, head, data in members:
        crc = crc32(data, crc32(head))
        size = len(head) + data.size
        f.write(_LOCAL.pack(0x04034B50, _VERSION, 0, 0, 0, _DATE, crc, size, size, len(name), 0))
        f.write(name)
        f.write(head)
        f.write(data.data)
        central.append((name, crc, size, offset))
        offset += _LOCAL.size + len(name) + size
    start = offset
    for name, crc, size, at in central:
        entry = (0x02014B50, _VERSION, _VERSION, 0, 0, 0, _DATE, crc, size, size, len(name))
        f.write(_CENTRAL.pack(*entry, 0, 0, 0, 0, 0, at))
        f.write(name)
        offset += _CENTRAL.size + len(name)
    f.write(_END.pack(0x06054B50, 0, 0, len(central), len(central), offset - start, start, 0))

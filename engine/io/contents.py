"""The content checksum of a result file: SHA-256 over every variable's values and attributes.

A streamed run computes it while it merges the blocks and stores it in the global attribute
``content_checksum`` (``"sha256-v1:<hex>"``); ``conesurvey info --verify`` reads the file
again and recomputes it (:func:`verify_file`). Definition (scheme ``sha256-v1``):

- each variable, in the order of its name: SHA-256 of its name, dtype, shape and attributes
  (:func:`_header`), then of its values as little-endian bytes in C order, taken one block at a
  time for the 4-D variables (blocks of the shape in the global attribute
  ``content_checksum_block``, in C order of blocks; the order the merge writes them) and whole
  for the others;
- the file: SHA-256 of the global attributes except ``history`` (tools append to it) and the
  checksum itself, then of each variable's name and digest.

Scheme ``sha256-blocks-v1`` is the same except that a variable's values are hashed one block at
a time and the variable's digest is taken over the 32-byte SHA-256 of each block (in C order of
blocks; a 1-D variable is one block): the writers of a Zarr store hash the blocks they write,
and the run that commits the store combines their digests without reading any value
(:mod:`engine.io.zarr`). Both schemes are verified the same way, in either format.

The value does not depend on the file's storage chunks, compression or layout, only on what a
reader gets back. Reading is done one block of one variable at a time (bounded memory). A
chunk that fails to decompress is reported as damage, like a value that differs.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..grid import Tiling
from ..schema import GRID_DIMS

__all__ = [
    "BLOCK_SCHEME",
    "CHECKSUM_ATTR",
    "CHECKSUM_BLOCK_ATTR",
    "SCHEME",
    "ContentHasher",
    "block_digest",
    "verify_file",
]

#: Global attribute holding the checksum (with the scheme as a prefix).
CHECKSUM_ATTR = "content_checksum"
#: Global attribute: the block shape the 4-D variables are hashed in.
CHECKSUM_BLOCK_ATTR = "content_checksum_block"
SCHEME = "sha256-v1"
#: The scheme of results written block by block by several writers (Zarr stores).
BLOCK_SCHEME = "sha256-blocks-v1"
_UNHASHED = ("history", CHECKSUM_ATTR)


def _canonical(value: Any) -> bytes:
    """An attribute value as bytes that say its type: text as UTF-8, numbers with dtype."""
    if isinstance(value, str):
        return b"s" + value.encode("utf-8", "surrogatepass")
    arr = np.asarray(value)
    if arr.dtype.kind in "US":
        return b"t" + repr(arr.tolist()).encode("utf-8", "surrogatepass")
    le = arr.dtype.newbyteorder("<") if arr.dtype.byteorder in "<>=" else arr.dtype
    return b"a" + le.str.encode() + repr(arr.shape).encode() + arr.astype(le).tobytes()


def _attrs_digest(attrs: Mapping[str, Any], skip: tuple[str, ...] = ()) -> bytes:
    h = hashlib.sha256()
    for key in sorted(attrs):
        if key in skip:
            continue
        h.update(key.encode("utf-8", "surrogatepass") + b"\0")
        h.update(hashlib.sha256(_canonical(attrs[key])).digest())
    return h.digest()


def _header(name: str, var: Any) -> bytes:
    dtype = np.dtype(var.dtype)
    le = dtype.newbyteorder("<") if dtype.byteorder in "<>=" else dtype
    attrs = {k: var.getncattr(k) for k in var.ncattrs()}
    return b"\0".join(
        [name.encode(), le.str.encode(), repr(tuple(var.shape)).encode(), _attrs_digest(attrs)]
    )


def _values(arr: np.ndarray) -> np.ndarray:
    """``arr`` C-contiguous and little-endian (hashable through the buffer protocol)."""
    dt = arr.dtype
    le = dt.newbyteorder("<") if dt.byteorder in "<>=" else dt
    return np.ascontiguousarray(arr, dtype=le)


def block_digest(values: np.ndarray) -> bytes:
    """SHA-256 of one block of values (scheme ``sha256-blocks-v1``)."""
    return hashlib.sha256(_values(values)).digest()


class ContentHasher:
    """The checksum of a file being written: :meth:`add` every variable's values in the order
    of the definition (4-D ones block by block in C order), then :meth:`finish`. With
    ``scheme = BLOCK_SCHEME`` a block's digest may be added instead (:meth:`add_digest`)."""

    def __init__(self, block: tuple[int, ...], scheme: str = SCHEME) -> None:
        if scheme not in (SCHEME, BLOCK_SCHEME):
            raise ValueError(f"unknown content checksum scheme {scheme!r}")
        self.block = tuple(int(b) for b in block)
        self.scheme = scheme
        self._data: dict[str, Any] = {}

    def add(self, name: str, values: np.ndarray) -> None:
        """Hash the next block (or the whole) of variable ``name``."""
        if self.scheme == BLOCK_SCHEME:
            self.add_digest(name, block_digest(values))
        else:
            self._data.setdefault(name, hashlib.sha256()).update(_values(values))

    def add_digest(self, name: str, digest: bytes) -> None:
        """Add the :func:`block_digest` of the next block of ``name`` (``sha256-blocks-v1``)."""
        if self.scheme != BLOCK_SCHEME or len(digest) != 32:
            raise ValueError("block digests are 32-byte SHA-256 of scheme sha256-blocks-v1")
        self._data.setdefault(name, hashlib.sha256()).update(digest)

    def finish(self, nc: Any) -> str:
        """The checksum of the open netCDF4 Dataset ``nc``, whose values were all added."""
        total = hashlib.sha256(_attrs_digest(_global_attrs(nc), _UNHASHED))
        for name in sorted(nc.variables):
            h = hashlib.sha256(_header(name, nc.variables[name]))
            h.update(self._data.get(name, hashlib.sha256()).digest())
            total.update(name.encode() + b"\0" + h.digest())
        return f"{self.scheme}:{total.hexdigest()}"


def _global_attrs(nc: Any) -> dict[str, Any]:
    return {k: nc.getncattr(k) for k in nc.ncattrs()}


def verify_file(nc: Any) -> tuple[bool, str]:
    """(ok, what was found) for the open netCDF4 Dataset ``nc``: every value is read again and
    the checksum recomputed. Damage (a chunk that does not decompress, a value or attribute
    that differs) is reported, never raised."""
    attrs = _global_attrs(nc)
    recorded = attrs.get(CHECKSUM_ATTR)
    scheme = recorded.partition(":")[0] if isinstance(recorded, str) else None
    if scheme not in (SCHEME, BLOCK_SCHEME):
        return False, "no content checksum recorded (not written by a conesurvey run)"
    try:
        block = tuple(int(b) for b in np.asarray(attrs[CHECKSUM_BLOCK_ATTR]).ravel())
        if len(block) not in {len(d) for d in GRID_DIMS} or min(block) < 1:
            raise ValueError(block)
    except (KeyError, ValueError, TypeError, OverflowError):
        return False, f"the {CHECKSUM_BLOCK_ATTR} attribute is missing or damaged"
    hasher = ContentHasher(block, scheme)
    nc.set_auto_maskandscale(False)
    for name, var in nc.variables.items():
        slabs = (
            iter(Tiling(tuple(var.shape), block, block))
            if tuple(var.dimensions) in GRID_DIMS
            else iter([tuple(slice(None) for _ in var.shape)])
        )
        for slab in slabs:
            try:
                values = np.asarray(var[slab])
            except Exception as exc:  # HDF5 reports a damaged chunk as a RuntimeError
                where = ", ".join(f"{s.start}:{s.stop}" for s in slab if s.start is not None)
                return False, f"variable {name} [{where}] cannot be read ({exc})"
            hasher.add(name, values)
    if hasher.finish(nc) != recorded:
        return False, "the contents do not match the recorded checksum (the file is damaged)"
    return True, "every value and attribute matches the recorded checksum"

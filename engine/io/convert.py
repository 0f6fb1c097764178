"""A finished result from one format to the other: netCDF -> Zarr store, Zarr store -> netCDF.

The copy is exact: every variable with its values (bit for bit), dims, storage chunks and
attributes, the global attributes verbatim with one more ``history`` entry (the conversion).
Values are read and written one block at a time (the blocks of ``content_checksum_block``, so
memory stays at one block whatever the size). As they pass, they are hashed in the source's
content checksum scheme (:mod:`engine.io.contents`): the source's recorded checksum is verified
before the output appears (a damaged source gives an error and no output), and the output
records the checksum of what it holds, which is the source's own when the contents are the same
(they are for every conesurvey result). The output appears by one rename, complete
(:mod:`engine.io.atomic` for a netCDF file, :func:`engine.io.zarr.put_in_place` for a store).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import netCDF4
import numpy as np

from ..grid import BLOCK_POINTS, Tiling, block_shape
from ..schema import GRID_DIMS
from . import OutputError, WriteError
from . import zarr as zarr_io
from .atomic import fsync_path, replacing
from .cf import history_line
from .codecs import compression_keywords
from .contents import BLOCK_SCHEME, CHECKSUM_ATTR, CHECKSUM_BLOCK_ATTR, SCHEME, ContentHasher
from .formats import format_for

__all__ = [
    "UNVERIFIED_ATTR",
    "Converted",
    "convert",
    "output_bytes",
    "remove_temporaries",
    "to_netcdf",
    "to_zarr",
]

#: Global attribute of a result converted from a source without a content checksum: its
#: checksum covers what was read, and nothing says the source was sound. Carried by later
#: conversions.
UNVERIFIED_ATTR = "conesurvey_unverified_source"
UNVERIFIED_TEXT = (
    "converted from {source}, which had no content checksum: the source was not verified "
    "(its content_checksum covers what was read)"
)


@dataclass(frozen=True)
class Converted:
    """What :func:`convert` did: the source's recorded checksum (None if it had none) and the
    output's."""

    source_checksum: str | None
    checksum: str
    blocks: int


class _Source:
    """A finished result opened for reading through the netCDF4 interface (its format's
    ``open_view``: a netCDF file, or a Zarr store through
    :class:`engine.io.zarrlayout.ZarrView`)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        fmt = format_for(path)
        if fmt.open_view is None:
            raise OutputError(f"{path}: {fmt.label} results cannot be converted")
        try:
            self.ds: Any = fmt.open_view(path)
            self.ds.set_auto_maskandscale(False)
        except OutputError:
            raise
        except Exception as exc:  # a damaged or foreign file
            raise OutputError(f"{path} is not a readable result ({exc})") from None
        self.attrs = {k: self.ds.getncattr(k) for k in self.ds.ncattrs()}
        grids = [v for v in self.ds.variables.values() if tuple(v.dimensions) in GRID_DIMS]
        if not grids:
            self.close()
            raise OutputError(f"{path} is not a conesurvey survey (no variable over its axes)")
        first = grids[0]
        self.dims = tuple(first.dimensions)
        if problem := self._problem(dict(zip(self.dims, first.shape, strict=True))):
            self.close()
            raise OutputError(f"{path} is damaged: {problem}")
        self.tiling = self._tiling(tuple(first.shape), first.chunking())

    def _problem(self, sizes: dict[str, int]) -> str | None:
        """What makes the result's variables inconsistent with its grid of ``sizes`` (None if
        nothing): an axis missing or of another length, a variable on other dims."""
        for d in self.dims:
            axis = self.ds.variables.get(d)
            if axis is None:
                return f"its axis {d} is missing"
            if tuple(axis.dimensions) != (d,) or tuple(axis.shape) != (sizes[d],):
                return f"its axis {d} does not match the grid ({sizes[d]} values)"
        for name, var in self.ds.variables.items():
            dims, shape = tuple(var.dimensions), tuple(var.shape)
            if not set(dims) <= set(self.dims) or shape != tuple(sizes[d] for d in dims):
                return f"variable {name} is not on the grid's axes ({', '.join(dims)})"
        return None

    def _tiling(self, shape: tuple[int, ...], chunking: Any) -> Tiling:
        chunk = tuple(chunking) if isinstance(chunking, list | tuple) else shape
        try:
            block = tuple(int(b) for b in np.asarray(self.attrs[CHECKSUM_BLOCK_ATTR]).ravel())
            ok = len(block) == len(shape) and all(
                c <= b <= n and (b % c == 0 or b == n)
                for c, b, n in zip(chunk, block, shape, strict=True)
            )
        except (KeyError, ValueError, TypeError):
            ok = False
        return Tiling(shape, chunk, block if ok else block_shape(shape, chunk, BLOCK_POINTS))

    def variables(self) -> dict[str, Any]:
        return dict(self.ds.variables)

    def blocks(self, hasher: ContentHasher) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        """Every block's 4-D variables, in C order of blocks, hashed as they are read."""
        grids = [n for n, v in self.ds.variables.items() if tuple(v.dimensions) == self.dims]
        for i, slab in enumerate(self.tiling):
            block = {}
            for name in grids:
                try:
                    block[name] = np.asarray(self.ds.variables[name][slab])
                except Exception as exc:  # a chunk that does not decompress
                    why = f"{self.path}: variable {name} cannot be read ({exc})"
                    raise OutputError(why) from None
                hasher.add(name, block[name])
            yield i, block

    def close(self) -> None:
        if (close := getattr(self.ds, "close", None)) is not None:
            close()


def _var_attrs(var: Any) -> dict[str, Any]:
    return {k: var.getncattr(k) for k in var.ncattrs() if k != "_FillValue"}


def _check_source(src: _Source, hasher: ContentHasher, recorded: str | None) -> None:
    if recorded is not None and hasher.finish(src.ds) != recorded:
        raise OutputError(
            f"{src.path} is damaged: its contents do not match its recorded content checksum "
            "(conesurvey info --verify says where); nothing was written"
        )


def convert(
    source: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    command: str = "conesurvey convert",
    overwrite: bool = False,
) -> Converted:
    """Convert the finished result ``source`` to ``out`` (in the format of its name,
    :func:`engine.io.formats.format_for`). OutputError if the source cannot be read, is not
    finished or is damaged; FileExistsError if ``out`` exists and not ``overwrite``; nothing
    is left under ``out`` in any of these cases."""
    source, out = Path(source), Path(out)
    fmt = format_for(out)
    if fmt.write_copy is None:
        raise OutputError(f"cannot convert to {fmt.label} output ({out})")
    remove_temporaries(out)
    src = _Source(source)
    try:
        if "conesurvey_unfinished" in src.attrs:
            raise OutputError(f"{source} is an unfinished run's store; finish the run first")
        recorded = src.attrs.get(CHECKSUM_ATTR)
        scheme = recorded.partition(":")[0] if isinstance(recorded, str) else None
        attrs = {k: v for k, v in src.attrs.items() if k != CHECKSUM_ATTR}
        if scheme not in (SCHEME, BLOCK_SCHEME):  # nothing to verify: the output says so
            recorded, scheme = None, (BLOCK_SCHEME if fmt.directory else SCHEME)
            attrs.setdefault(UNVERIFIED_ATTR, UNVERIFIED_TEXT.format(source=source.name))
        hasher = ContentHasher(src.tiling.block, scheme)
        old = attrs.get("history")
        attrs["history"] = history_line(command) + (f"\n{old}" if old else "")
        attrs[CHECKSUM_BLOCK_ATTR] = np.asarray(src.tiling.block, np.int64)
        checksum = fmt.write_copy(src, out, attrs, hasher, recorded, overwrite)
    finally:
        src.close()
    return Converted(recorded, checksum, src.tiling.nblocks)


def remove_temporaries(out: Path) -> list[str]:
    """Remove what a killed conversion to ``out`` left beside it (``OUT.<12 hex>.tmp``, a file
    or a store of this user; a link is removed, not followed). Call it under ``out``'s lock.
    Returns the names removed."""
    pattern = re.compile(re.escape(out.name) + r"\.[0-9a-f]{12}\.tmp")
    removed = []
    with contextlib.suppress(OSError):
        for name in os.listdir(out.parent):
            p = out.parent / name
            if not pattern.fullmatch(name) or os.lstat(p).st_uid != os.getuid():
                continue
            if os.path.isdir(p) and not os.path.islink(p):
                shutil.rmtree(p)
            else:
                os.unlink(p)
            removed.append(name)
    return removed


def _axes(src: _Source, hasher: ContentHasher) -> dict[str, tuple[np.ndarray, dict[str, Any]]]:
    out = {}
    for d in src.dims:
        var = src.ds.variables[d]
        values = np.asarray(var[:])
        hasher.add(d, values)
        out[d] = (values, _var_attrs(var))
    return out


def _families(src: _Source, hasher: ContentHasher) -> dict[str, tuple]:
    """The variables on fewer dims than the grid (r_circ, V_min on (alpha, h, Lz)), read and
    hashed whole: name -> (values, dims, attributes, storage chunks)."""
    out = {}
    for name, var in src.variables().items():
        dims = tuple(var.dimensions)
        if name in src.dims or dims == src.dims or not set(dims) < set(src.dims):
            continue
        try:
            values = np.asarray(var[...])
        except Exception as exc:  # a chunk that does not decompress
            raise OutputError(f"{src.path}: variable {name} cannot be read ({exc})") from None
        hasher.add(name, values)
        chunks = var.chunking()
        chunks = tuple(chunks) if isinstance(chunks, list | tuple) else None
        out[name] = (values, dims, _var_attrs(var), chunks)
    return out


def to_zarr(src, out, attrs, hasher, recorded, overwrite) -> str:
    """Write ``src`` (a result being converted) as the Zarr store ``out``; its checksum."""
    grids = {n: v for n, v in src.variables().items() if tuple(v.dimensions) == src.dims}
    layout = {
        "axes": _axes(src, hasher),
        "variables": {n: (np.dtype(v.dtype), _var_attrs(v)) for n, v in grids.items()},
        "families": _families(src, hasher),
    }
    return zarr_io.write_store(
        out,
        layout,
        src.tiling,
        src.blocks(hasher),
        attrs,
        overwrite=overwrite,
        hasher=hasher,
        before_commit=lambda: _check_source(src, hasher, recorded),
    )


def _define_netcdf(nc: Any, src: _Source, hasher: ContentHasher) -> dict[str, Any]:
    """The dims, axes and variables on fewer dims (with their values) and the 4-D variables of
    the netCDF file ``nc``: the source's dtypes, attributes, fill values and storage chunks,
    zlib + shuffle."""
    for d, (values, a) in _axes(src, hasher).items():
        nc.createDimension(d, values.size)
        v = nc.createVariable(d, "f8", (d,), fill_value=False)
        v.setncatts(a)
        v[:] = values
    for name, (values, dims, _, chunks) in _families(src, hasher).items():
        var = src.ds.variables[name]
        attrs = {k: var.getncattr(k) for k in var.ncattrs()}
        fill = attrs.pop("_FillValue", False)
        v = nc.createVariable(name, np.dtype(var.dtype).newbyteorder("="), dims, fill_value=fill,
                              chunksizes=chunks, **compression_keywords("zlib"))  # fmt: skip
        v.setncatts(attrs)
        v[...] = values
    variables = {}
    for name, var in src.variables().items():
        if tuple(var.dimensions) == src.dims:
            attrs = {k: var.getncattr(k) for k in var.ncattrs()}
            fill = attrs.pop("_FillValue", False)
            dtype = np.dtype(var.dtype).newbyteorder("=")
            variables[name] = nc.createVariable(
                name, dtype, src.dims, **compression_keywords("zlib"),
                chunksizes=src.tiling.chunk, fill_value=fill,
            )  # fmt: skip
            variables[name].setncatts(attrs)
    return variables


def to_netcdf(src, out, attrs, hasher, recorded, overwrite) -> str:
    """Write ``src`` (a result being converted) as the netCDF file ``out``; its checksum."""
    with replacing(out, overwrite=overwrite) as tmp:
        try:
            with netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
                variables = _define_netcdf(nc, src, hasher)
                for i, block in src.blocks(hasher):
                    for name, arr in block.items():
                        variables[name][src.tiling.slices(i)] = arr
                _check_source(src, hasher, recorded)
                nc.setncatts(attrs)
                checksum = hasher.finish(nc)
                nc.setncattr(CHECKSUM_ATTR, checksum)
        except RuntimeError as exc:  # netCDF4 reports HDF5 failures (ENOSPC too) like this
            raise WriteError(f"writing {out} failed ({exc})") from None
        fsync_path(tmp)
    return checksum


def output_bytes(source: Path, out: Path) -> int:
    """An upper bound [bytes] of what converting ``source`` to ``out`` writes."""
    src = _Source(Path(source))
    try:
        grids = {n: v for n, v in src.variables().items() if tuple(v.dimensions) == src.dims}
        names = {n: np.dtype(v.dtype) for n, v in grids.items()}
    finally:
        src.close()
    return format_for(out).output_bytes(names, src.tiling.shape)

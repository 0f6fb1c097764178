"""The netCDF-4 backend: CF-1.11 files, written crash-safely (:mod:`engine.io.atomic`).

Backend interface (a second format, e.g. ``engine/io/zarr.py``, provides the same five):

- ``write_survey(ds, path, survey, *, command, overwrite) -> Path``: an in-memory survey
  Dataset with the survey's title, definition and scene;
- ``merge(store, survey, out, *, fingerprint, command, overwrite, complevel) -> Summary``: the
  blocks of a streamed run (:class:`engine.io.blocks.BlockStore`), each verified as it is
  read, one storage chunk per block part, into ``out`` with its content checksum
  (:mod:`engine.io.contents`); returns the class counts and value ranges gathered on the way;
- ``output_bytes(names, shape) -> int``: an upper bound of the size of what ``merge`` writes;
- ``read_fingerprint(path) -> str | None``: the survey fingerprint a finished result records;
- ``read_info(path, *, verify) -> dict``: provenance of a result, or of the unfinished run
  behind it; with ``verify``, every value checked against the content checksum.

No half-written file ever carries the output's name; an existing output is kept unless
``overwrite``. :func:`cf_dataset` adds the global attributes (Conventions, title, history,
source, ``survey_definition`` = the TOML text verbatim, the scene parameters); every variable
and axis attribute comes from :mod:`engine.schema`. The file layout is described in the README
("Large surveys: streaming, resume, dask").
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import netCDF4  # ~9 ms once engine is imported: not worth a lazy import
import numpy as np

from .._jit import threading_layer
from .._version import __version__
from ..kernels.geometry import CLASS_NAMES
from ..schema import FINGERPRINT_ATTR, axis_attrs, map_kind, variable_attrs
from . import OutputError, WriteError
from .atomic import fsync_path, not_regular, replacing
from .blocks import BlockStore, Summary, check_parts_dir, parts_info
from .contents import CHECKSUM_ATTR, CHECKSUM_BLOCK_ATTR, ContentHasher, verify_file
from .manifest import parts_dir

if TYPE_CHECKING:
    import xarray as xr

    from ..scene import Scene
    from ..surveyfile import Survey

__all__ = [
    "CONVENTIONS",
    "ZLIB_LEVEL",
    "cf_attrs",
    "cf_dataset",
    "compression",
    "encoding_for",
    "history_line",
    "merge",
    "output_bytes",
    "read_fingerprint",
    "read_info",
    "write_netcdf",
    "write_survey",
]

CONVENTIONS = "CF-1.11"
#: zlib level 1 + shuffle: level 4 compresses < 1 % better and costs 7-26 % more time.
ZLIB_LEVEL = 1


# --- attributes and encodings -----------------------------------------------------------------


def history_line(command: str, *, now: datetime | None = None) -> str:
    """One CF history entry: ISO-8601 UTC time, the command and numba's threading layer."""
    stamp = (now or datetime.now(UTC)).astimezone(UTC)
    return f"{stamp:%Y-%m-%dT%H:%M:%SZ} {command} (numba threading layer: {threading_layer()})"


def cf_attrs(
    attrs: Mapping[str, Any],
    *,
    title: str,
    survey_definition: str,
    command: str = "conesurvey",
    scene: Scene | None = None,
) -> dict[str, Any]:
    """The global attributes ``attrs`` with the CF ones a conesurvey output carries: the new
    history entry first (newest first, CF), the scene's parameters, the definition last."""
    rest = dict(attrs)
    if scene is not None:
        rest.update(scene.as_attrs())
    old_history = rest.pop("history", "")
    entry = history_line(command)
    for key in ("Conventions", "title", "source", "survey_definition"):
        rest.pop(key, None)
    return {
        "Conventions": CONVENTIONS,
        "title": title,
        "history": f"{entry}\n{old_history}" if old_history else entry,
        "source": f"conesurvey {__version__}",
        **rest,
        "survey_definition": survey_definition,
    }


def _typed_flags(attrs: Mapping[str, Any], dtype: np.dtype) -> dict[str, Any]:
    """``attrs`` with ``flag_values`` of the variable's own type (CF requires it)."""
    out = dict(attrs)
    if "flag_values" in out:
        out["flag_values"] = np.asarray(out["flag_values"], dtype=dtype)
    return out


def cf_dataset(
    ds: xr.Dataset,
    *,
    title: str,
    survey_definition: str,
    command: str = "conesurvey",
    scene: Scene | None = None,
) -> xr.Dataset:
    """A shallow copy of ``ds`` with the CF global attributes (:func:`cf_attrs`); the
    ``flag_values`` of flag variables (``orbit_class``, ``status``) get the variable's type."""
    out = ds.copy(deep=False)
    out.attrs = cf_attrs(
        ds.attrs, title=title, survey_definition=survey_definition, command=command, scene=scene
    )
    for var in out.data_vars.values():
        var.attrs = _typed_flags(var.attrs, var.dtype)
    return out


def compression(complevel: int = ZLIB_LEVEL) -> dict[str, Any]:
    """zlib + shuffle settings (netCDF4 and xarray take the same keys); 0 = uncompressed."""
    return {"zlib": complevel > 0, "complevel": max(complevel, 1), "shuffle": complevel > 0}


def encoding_for(ds: xr.Dataset, complevel: int = ZLIB_LEVEL) -> dict[str, dict[str, Any]]:
    """netCDF encodings: coordinates without _FillValue, data variables zlib + shuffle."""
    enc: dict[str, dict[str, Any]] = {}
    for name, var in ds.variables.items():
        if name in ds.coords:
            if var.dtype.kind == "f":
                enc[str(name)] = {"_FillValue": None}
        elif var.ndim > 0:
            enc[str(name)] = {**compression(complevel), "dtype": var.dtype}
    return enc


# --- writing ----------------------------------------------------------------------------------


def write_netcdf(ds: xr.Dataset, path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
    """Write ``ds`` to the netCDF-4 file ``path`` atomically; returns the path.

    Raises ``FileExistsError`` if ``path`` exists and not ``overwrite`` (checked before writing
    and again, atomically where the file system supports hard links, when renaming).
    """
    path = Path(path)
    with replacing(path, overwrite=overwrite) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4", encoding=encoding_for(ds))
        fsync_path(tmp)
    return path


def write_survey(
    ds: xr.Dataset,
    path: str | os.PathLike[str],
    survey: Survey,
    *,
    command: str = "conesurvey",
    overwrite: bool = False,
) -> Path:
    """Add the survey's title, definition and scene (:func:`cf_dataset`), then write it."""
    return write_netcdf(cf_dataset(ds, **_provenance(survey, command)), path, overwrite=overwrite)


def _provenance(survey: Survey, command: str) -> dict[str, Any]:
    """The keywords of :func:`cf_attrs` that a survey and the command that ran it give."""
    return {
        "title": survey.title,
        "survey_definition": survey.source_text,
        "command": command,
        "scene": survey.scene,
    }


def output_bytes(names: Mapping[str, np.dtype], shape: tuple[int, ...]) -> int:
    """Upper bound [bytes] of the netCDF file :func:`merge` writes: the values uncompressed
    (zlib can grow incompressible data by < 0.1 %), the axes, 1 % and 1 MB for HDF5's
    metadata (chunk indices, attributes, the survey definition)."""
    points = math.prod(shape)
    data = sum(np.dtype(dt).itemsize for dt in names.values()) * points + 8 * sum(shape)
    return int(data * 1.01) + (1 << 20)


def merge(
    store: BlockStore,
    survey: Survey,
    out: Path,
    *,
    fingerprint: str,
    command: str = "conesurvey",
    overwrite: bool = False,
    complevel: int = ZLIB_LEVEL,
) -> Summary:
    """Write every block of ``store`` into ``out`` (netCDF-4, chunk-aligned, zlib level
    ``complevel`` + shuffle) through a temporary file inside the store (private to the run);
    returns the statistics gathered on the way. The file carries the content checksum
    (:mod:`engine.io.contents`) of what was written.

    FileExistsError if ``out`` exists and not ``overwrite``; OutputError if a block is missing
    or fails its checksum; WriteError if the netCDF library fails to write (a full disk
    shows up as "NetCDF: HDF error"); nothing is left under ``out`` in any of these cases.
    """
    attrs = cf_attrs(survey.attrs(), **_provenance(survey, command))
    with replacing(out, overwrite=overwrite, tmp_dir=store.root) as tmp:
        try:
            summary = _write_merged(store, survey, tmp, attrs, fingerprint, complevel)
        except RuntimeError as exc:  # netCDF4 reports HDF5 failures (ENOSPC too) like this
            raise WriteError(f"writing {out} failed ({exc})") from None
        fsync_path(tmp)
    return summary


def _write_merged(
    store: BlockStore,
    survey: Survey,
    tmp: Path,
    attrs: dict[str, Any],
    fingerprint: str,
    complevel: int,
) -> Summary:
    summary = Summary()
    hasher = ContentHasher(store.tiling.block)
    kind = map_kind(survey.method, survey.scene)
    with netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
        nc.setncatts(
            {
                **attrs,
                FINGERPRINT_ATTR: fingerprint,
                CHECKSUM_BLOCK_ATTR: np.asarray(store.tiling.block, np.int64),
            }
        )
        for d in survey.dims:
            values = np.asarray(getattr(survey, d), np.float64)
            nc.createDimension(d, values.size)
            v = nc.createVariable(d, "f8", (d,), fill_value=False)
            v.setncatts(axis_attrs(d, survey.energy_relative))
            v[:] = values
            hasher.add(d, values)
        variables = {}
        for name, dt in store.names.items():
            v = nc.createVariable(
                name,
                dt,
                survey.dims,
                **compression(complevel),
                chunksizes=store.tiling.chunk,
                fill_value=False if dt.kind in "iu" else np.nan,
            )
            v.setncatts(_typed_flags(variable_attrs(name, kind), dt))
            variables[name] = v
        for slab, block in store.blocks():
            for name, arr in block.items():
                variables[name][slab] = arr
                hasher.add(name, arr)
            summary.add(block)
        nc.setncattr(CHECKSUM_ATTR, hasher.finish(nc))
    return summary


# --- reading ----------------------------------------------------------------------------------


def read_info(path: str | os.PathLike[str], *, verify: bool = False) -> dict[str, Any]:
    """Provenance of a result file, or of an unfinished run's block store.

    Keys: ``path``, ``complete``, ``attrs`` (global attributes), ``dims``; a file adds
    ``counts`` (class name -> count; values that are no class code under ``"other"``),
    ``checksum`` (whether one is recorded), ``leftover_parts`` (a block store beside it) and,
    with ``verify``, ``verified`` = (ok, what was found) (:func:`engine.io.contents.verify_file`).
    A block store adds ``blocks_done`` and ``blocks_total``, or ``problem`` if its manifest is
    missing or invalid. ``notes`` lists what could not be read. OutputError if there is neither
    or the file is not readable netCDF. Never raises anything else for a damaged or foreign file.
    """
    path = Path(path)
    parts = parts_dir(path)
    info: dict[str, Any] = {"path": str(path), "notes": []}
    kind = not_regular(path)
    if kind is not None:
        raise OutputError(f"{path} is {kind}, not a netCDF file")
    if os.path.lexists(path):
        info.update(_file_info(path, verify))
        info["leftover_parts"] = os.path.lexists(parts)
    elif os.path.lexists(parts):
        info.update(_parts_state(parts))
    else:
        raise OutputError(f"no such file: {path}")
    return info


def read_fingerprint(path: Path) -> str | None:
    """The survey fingerprint a finished result records (None if it has none, or is not a
    readable netCDF file; a FIFO or device is not opened)."""
    if not_regular(path) is not None:
        return None
    try:
        with netCDF4.Dataset(path) as nc:
            fp = nc.getncattr(FINGERPRINT_ATTR) if FINGERPRINT_ATTR in nc.ncattrs() else None
    except Exception:  # not netCDF, damaged, a directory ...
        return None
    return fp if isinstance(fp, str) else None


def _parts_state(parts: Path) -> dict[str, Any]:
    """What an unfinished run's store says, or why it cannot say it."""
    try:
        check_parts_dir(parts)
        return parts_info(parts)
    except (OutputError, OSError) as exc:
        return {"complete": False, "attrs": {}, "dims": {}, "problem": str(exc)}


def _file_info(path: Path, verify: bool) -> dict[str, Any]:
    info: dict[str, Any] = {"notes": []}
    try:
        with netCDF4.Dataset(path) as nc:
            info["attrs"] = _attributes(nc, info["notes"])
            info["dims"] = {d: len(nc.dimensions[d]) for d in nc.dimensions}
            counts = _class_counts(nc, info["notes"])
            if counts is not None:
                info["counts"] = counts
            info["complete"] = FINGERPRINT_ATTR in info["attrs"]
            info["checksum"] = CHECKSUM_ATTR in info["attrs"]
            if verify:
                info["verified"] = verify_file(nc)
    except Exception as exc:  # netCDF4 raises OSError, RuntimeError, ... for a damaged file
        raise OutputError(f"{path} is not a readable netCDF file ({exc})") from None
    return info


def _attributes(nc: Any, notes: list[str]) -> dict[str, Any]:
    out = {}
    for key in nc.ncattrs():
        try:
            out[key] = nc.getncattr(key)
        except Exception as exc:  # an attribute of a type netCDF4 cannot decode
            notes.append(f"global attribute {key} cannot be read ({exc})")
    return out


def _class_counts(nc: Any, notes: list[str]) -> dict[str, int] | None:
    """Count of each class code of ``orbit_class`` ("other" for values that are not one)."""
    v = nc.variables.get("orbit_class")
    if v is None:
        return None
    if np.dtype(v.dtype).kind not in "iu" or v.ndim == 0:
        notes.append(f"orbit_class is not an integer array ({v.dtype}); classes not counted")
        return None
    v.set_auto_maskandscale(False)
    n = len(CLASS_NAMES)
    counts = np.zeros(n + 1, np.int64)
    try:
        for sl in _slabs(v.shape, v.chunking()):
            codes = np.asarray(v[sl]).ravel().astype(np.int64)
            valid = (codes >= 0) & (codes < n)
            counts[:n] += np.bincount(codes[valid], minlength=n)
            counts[n] += int((~valid).sum())
    except Exception as exc:  # a damaged chunk
        notes.append(f"orbit_class cannot be read ({exc}); classes not counted")
        return None
    out = dict(zip(CLASS_NAMES, counts[:n].tolist(), strict=True))
    if counts[n]:
        out["other"] = int(counts[n])
    return out


def _slabs(shape: tuple[int, ...], chunking: Any) -> Iterator[tuple[slice, ...]]:
    """Hyperslabs one storage chunk along the first axis at a time (bounded memory)."""
    step = chunking[0] if isinstance(chunking, list | tuple) else max(1, shape[0])
    for s in range(0, shape[0], step):
        yield (slice(s, min(shape[0], s + step)),) + tuple(slice(0, n) for n in shape[1:])

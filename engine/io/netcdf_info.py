"""Reading the netCDF backend's results back: provenance, completeness, class counts.

:func:`read_info` (``conesurvey info``) and :func:`read_fingerprint` (does the output already
hold this survey?) of :mod:`engine.io.netcdf`'s backend interface, which re-exports them. A
damaged or foreign file is reported, never a traceback; a FIFO or a device is never opened.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import netCDF4
import numpy as np

from ..schema import FINGERPRINT_ATTR, MAP_KINDS, flag_table
from . import OutputError
from .atomic import not_regular
from .blocks import check_parts_dir, parts_info
from .contents import CHECKSUM_ATTR, verify_file
from .manifest import parts_dir

__all__ = ["read_fingerprint", "read_info"]


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
            counts = class_counts(nc, info["notes"])
            if counts is not None:
                info["counts"] = counts
            fates = fate_counts(nc, info["notes"])
            if fates is not None:
                info["fate_counts"] = fates
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


def class_counts(nc: Any, notes: list[str]) -> dict[str, int] | None:
    """Count of each class code of ``orbit_class`` ("other" for values that are not one), named
    as the kind of map (the ``map_kind`` attribute: the cone's classes, or a surface's) names
    them."""
    names = tuple(n for _, n in flag_table("orbit_class", _map_kind(nc)))
    return flag_counts(nc, "orbit_class", names, notes)


def _map_kind(nc: Any) -> str | None:
    """The file's ``map_kind`` attribute where it names a kind of map (else None)."""
    try:
        kind = str(nc.getncattr("map_kind"))
    except Exception:  # no such attribute, or one netCDF4 cannot decode
        return None
    return kind if kind in MAP_KINDS else None


def fate_counts(nc: Any, notes: list[str]) -> dict[str, int] | None:
    """Count of each fate of a fate map's ``fate`` (None for other maps), named as the kind of
    map (the ``map_kind`` attribute) names them."""
    table = dict(flag_table("fate", _map_kind(nc)))
    names = tuple(table.get(c, f"(code {c})") for c in range(max(table) + 1))
    out = flag_counts(nc, "fate", names, notes)
    if out is None:
        return None
    return {k: n for k, n in out.items() if n or not k.startswith("(code")}


def flag_counts(
    nc: Any, name: str, names: tuple[str, ...], notes: list[str]
) -> dict[str, int] | None:
    """Count of each code 0, 1, ... of the flag variable ``name`` (``names`` in code order;
    "other" for values that are not a code)."""
    v = nc.variables.get(name)
    if v is None:
        return None
    if np.dtype(v.dtype).kind not in "iu" or v.ndim == 0:
        notes.append(f"{name} is not an integer array ({v.dtype}); its flags are not counted")
        return None
    v.set_auto_maskandscale(False)
    n = len(names)
    counts = np.zeros(n + 1, np.int64)
    try:
        for sl in _slabs(v.shape, v.chunking()):
            codes = np.asarray(v[sl]).ravel().astype(np.int64)
            valid = (codes >= 0) & (codes < n)
            counts[:n] += np.bincount(codes[valid], minlength=n)
            counts[n] += int((~valid).sum())
    except Exception as exc:  # a damaged chunk
        notes.append(f"{name} cannot be read ({exc}); its flags are not counted")
        return None
    out = dict(zip(names, counts[:n].tolist(), strict=True))
    if counts[n]:
        out["other"] = int(counts[n])
    return out


def _slabs(shape: tuple[int, ...], chunking: Any) -> Iterator[tuple[slice, ...]]:
    """Hyperslabs one storage chunk along the first axis at a time (bounded memory)."""
    step = chunking[0] if isinstance(chunking, list | tuple) else max(1, shape[0])
    for s in range(0, shape[0], step):
        yield (slice(s, min(shape[0], s + step)),) + tuple(slice(0, n) for n in shape[1:])

"""The files of a run's Zarr store that no block writes: what they must hold, made from the plan.

A store is its *skeleton* (the root group's ``zarr.json``, every array's ``zarr.json``, the
axes and the variables on fewer dims with their values, r_circ and V_min) plus the chunk files
of the blocks. The skeleton is made in memory from the run's plan (:func:`skeleton`: zarr's own
metadata and chunk bytes, through a ``MemoryStore``), written once when the store is made
(:func:`make_store`), and is then what the store is compared with, byte for byte:

- a resume (:func:`repair`) writes again every skeleton file that differs or is missing (an
  edited axis, a deleted ``r_circ/`` or ``h/``, an edited ``units`` or ``scale_factor``) and
  removes what the run did not write (an extra array, a file at a chunk key that is a
  directory or a link, never followed), each named in a warning;
- the commit (:meth:`engine.io.zarrstore.RunStore.check_files`) holds and compares every
  skeleton file (:mod:`engine.io.hold`), refuses a store that holds anything else, and takes
  the consolidated metadata and the content checksum's headers from the skeleton, not from the
  disk: what a reader interprets (units, fill values, flag tables) is what the run wrote.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..grid import Tiling, storage_chunks
from ..schema import axis_attrs, variable_attrs, variable_dims
from .atomic import NEW_FILE, fsync_dir, read_regular, write_atomic
from .cf import typed_flags
from .zarrchunks import SEPARATOR, chunk_key_encoding, codecs, fill_value
from .zarrlayout import (
    RUN_ATTR,
    UNFINISHED_ATTR,
    UNFINISHED_TEXT,
    fill_attr,
    json_attr,
    zarr_module,
)

if TYPE_CHECKING:
    from .planshape import RunPlan

__all__ = ["META", "extra_entries", "layout", "make_store", "repair", "skeleton"]

META = "zarr.json"
#: The largest skeleton file read back [bytes] (a family variable's chunk is ~512 kB).
_MAX_BYTES = 64 << 20


def layout(
    plan: RunPlan, names: Mapping[str, np.dtype], families: Mapping[str, np.ndarray]
) -> dict[str, Any]:
    """The arguments of :func:`skeleton` for ``plan``: its axes, the variables its blocks
    hold (``names``) and the ones on fewer dims (``families``, their values)."""
    kind = plan.map_kind
    axes = {
        d: (np.asarray(plan.axis(d), np.float64), axis_attrs(d, plan.energy_relative))
        for d in plan.dims
    }
    variables = {n: (np.dtype(dt), variable_attrs(n, kind)) for n, dt in names.items()}
    fixed = {n: (v, variable_dims(n, plan.dims), variable_attrs(n, kind), None)
             for n, v in families.items()}  # fmt: skip
    return {"axes": axes, "variables": variables, "families": fixed}


def skeleton(
    run_id: str,
    *,
    axes: Mapping[str, tuple[np.ndarray, dict[str, Any]]],
    variables: Mapping[str, tuple[np.dtype, dict[str, Any]]],
    tiling: Tiling,
    complevel: int,
    families: Mapping[str, tuple[np.ndarray, tuple[str, ...], dict[str, Any], Any]] = {},
    separator: str = SEPARATOR,
) -> dict[str, bytes]:
    """The skeleton files (key -> bytes, as zarr writes them): the root group marked unfinished
    with the run's id, the axes with their values, the data variables (no chunk), ``families``
    (on fewer dims: name -> (values, dims, attributes, chunks or None), their chunks too)."""
    zarr = zarr_module()
    found: dict[str, Any] = {}
    store = zarr.storage.MemoryStore(found)
    attrs = {UNFINISHED_ATTR: UNFINISHED_TEXT, RUN_ATTR: run_id}
    zarr.create_group(store, zarr_format=3, attributes=attrs)
    dims = tuple(axes)
    for d, (values, a) in axes.items():
        arr = zarr.create_array(
            store, name=d, shape=values.shape, chunks=values.shape, dtype=np.float64,
            fill_value=np.nan, compressors=None, dimension_names=(d,),
            attributes={k: json_attr(v) for k, v in a.items()},
        )  # fmt: skip
        arr[:] = values
    specs = [(n, dt, a, tiling.shape, tiling.chunk, dims, None) for n, (dt, a) in variables.items()]
    specs += [(n, v.dtype, a, v.shape, c or storage_chunks(v.shape), d, v)
              for n, (v, d, a, c) in families.items()]  # fmt: skip
    for name, dt, a, shape, chunks, vdims, values in specs:
        dt = np.dtype(dt)
        attrs = {k: json_attr(v) for k, v in typed_flags(a, dt).items() if k != "_FillValue"}
        if dt.kind == "f":
            attrs["_FillValue"] = fill_attr(dt)
        arr = zarr.create_array(
            store, name=name, shape=shape, chunks=tuple(chunks), dtype=dt,
            fill_value=fill_value(dt), compressors=codecs(complevel), dimension_names=vdims,
            attributes=attrs, config={"write_empty_chunks": True},
            chunk_key_encoding=chunk_key_encoding(separator),
        )  # fmt: skip
        if values is not None:
            arr[...] = values
    return {key: buf.to_bytes() for key, buf in found.items()}


def make_store(path: Path, files: Mapping[str, bytes]) -> None:
    """Create the store ``path`` (a new directory) holding the skeleton ``files``
    (:func:`skeleton`), every file and directory fsynced."""
    os.mkdir(path)
    made = {path}
    for key, data in files.items():
        target = path / key
        for parent in reversed(target.relative_to(path).parents[:-1]):
            if path / parent not in made:
                os.mkdir(path / parent)
                made.add(path / parent)
        fd = os.open(target, NEW_FILE, 0o666)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]
            os.fsync(fd)
        finally:
            os.close(fd)
    for directory in sorted(made, key=lambda p: len(p.parts), reverse=True):
        fsync_dir(directory)


def _dirs(keys: Iterable[str]) -> set[str]:
    out = set()
    for key in keys:
        parts = key.split("/")[:-1]
        out.update("/".join(parts[: i + 1]) for i in range(len(parts)))
    return out


def extra_entries(
    store: Path,
    expected: Iterable[str],
    chunks: Iterable[str],
    temporaries: list[str] | None = None,
) -> list[str]:
    """The entries of ``store`` (relative paths, not followed) that are neither a skeleton key
    (``expected``), a chunk key of a block (``chunks``), a directory leading to one, nor a
    writer's temporary file (``.NAME.<hex>.tmp``, put in ``temporaries`` if given): what the
    run did not write. A link, a FIFO or a device at any name is one. One pass of ``scandir``
    (the kinds come with the names: no ``stat`` a file)."""
    files = set(expected) | set(chunks)
    dirs = _dirs(files)
    extra: list[str] = []
    todo = [("", str(store))]
    while todo:
        prefix, path = todo.pop()
        with os.scandir(path) as entries:
            for entry in entries:
                key = prefix + entry.name
                if entry.is_dir(follow_symlinks=False):
                    if key in dirs:
                        todo.append((key + "/", entry.path))
                    else:
                        extra.append(key)
                elif not entry.is_file(follow_symlinks=False):
                    extra.append(key)
                elif entry.name.startswith(".") and entry.name.endswith(".tmp"):
                    if temporaries is not None:
                        temporaries.append(key)
                elif key not in files:
                    extra.append(key)
    return sorted(extra)


def _remove(path: Path) -> None:
    """Remove ``path`` whatever it is (a link is removed, not followed)."""
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path)
    else:
        os.unlink(path)


def repair(
    store: Path,
    files: Mapping[str, bytes],
    chunks: Iterable[str],
    warn: Callable[[str], None],
) -> None:
    """Make the unfinished ``store`` hold its skeleton ``files`` exactly (a resume, before any
    block is written): what the run did not write removed, each skeleton file that differs or
    is missing written again (atomically, never through a link), each named in ``warn``."""
    for key in extra_entries(store, files, chunks):
        _remove(store / key)
        warn(f"removed {key} from {store}: the run did not write it")
    for key, data in files.items():
        path = store / key
        try:
            same = read_regular(path, _MAX_BYTES, follow_links=False) == data
        except (OSError, ValueError):
            same = False
        if same:
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, lambda f, data=data: f.write(data))
        if key != META:  # the root: a new run id, every resume
            warn(f"{key} of {store} was changed or removed since the run wrote it; written again")

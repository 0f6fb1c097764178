"""The Zarr backend: Zarr v3 stores with the netCDF file's variables, attributes and chunks.

The Zarr row of :mod:`engine.io.formats` (its docstring states the protocol):
:func:`write_survey`, :func:`merge` (here the final commit of a store whose chunks the workers
wrote, :mod:`engine.io.zarrstore`), :func:`output_bytes`, :func:`read_fingerprint`,
:func:`read_info`; and :func:`create` (a new run's store). ``xarray.open_zarr(OUT.zarr)`` reads
the same Dataset as ``xarray.open_dataset(OUT.nc)``: dims (``dimension_names``), CF attributes
from :mod:`engine.schema`, ``_FillValue`` NaN on float variables as xarray encodes it, none on
integers and axes, storage chunks of the netCDF file, bit-identical values. Attributes are JSON,
so ``flag_values`` read back as a list of ints; :class:`ZarrView` and
:func:`engine.io.results.open_result` give them the variable's type again.

A store under the output's name is complete: it is built inside the run's private directory
(``OUT.zarr.parts/store.zarr``), committed (final attributes with the survey fingerprint and
the content checksum, then zarr's consolidated metadata, fsynced) and renamed into place.
"""

from __future__ import annotations

import functools
import math
import os
import shutil
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..grid import Tiling
from ..schema import FINGERPRINT_ATTR, grid_dims
from . import OutputError
from .atomic import exists_error, fsync_dir, not_regular, refuse_special
from .blocks import check_parts_dir, survey_dims
from .cf import cf_attrs
from .contents import BLOCK_SCHEME, CHECKSUM_ATTR, CHECKSUM_BLOCK_ATTR, ContentHasher, verify_file
from .hold import HeldFiles
from .manifest import Manifest, parts_dir, survey_families
from .netcdf_info import class_counts, fate_counts
from .space import output_bytes
from .summary import Summary
from .zarrchunks import chunk_keys
from .zarrcommit import check_tree, commit_store, metadata_problem
from .zarrlayout import UNFINISHED_ATTR, ChunkWriter, ZarrView, read_meta, zarr_module
from .zarrskeleton import META, layout, make_store, skeleton
from .zarrstore import RunStore, parts_state
from .zarrverify import check_held, check_store, hold_file

if TYPE_CHECKING:
    import xarray as xr

    from .planshape import RunPlan

__all__ = [
    "SUFFIX",
    "ZarrView",
    "create",
    "merge",
    "open_view",
    "output_bytes",
    "put_in_place",
    "read_fingerprint",
    "read_info",
    "unavailable",
    "write_survey",
    "zarr_module",
]

SUFFIX = ".zarr"


def unavailable() -> str:
    """Why Zarr output cannot be written here ("" if it can: the zarr package imports)."""
    try:
        zarr_module()
    except OutputError as exc:
        return str(exc)
    return ""


# --- making a store -----------------------------------------------------------------------------


def create(
    root: Path, plan: RunPlan, tiling: Tiling, complevel: int, warn: Callable[[str], None]
) -> RunStore:
    """The directory of a new run of ``survey`` into a Zarr store (:mod:`engine.io.zarrstore`)."""
    manifest = Manifest.new(plan, tiling)
    lay = layout(plan, manifest.names, survey_families(plan))

    def files(run_id: str, level: int, separator: str) -> dict[str, bytes]:
        return skeleton(run_id, **lay, tiling=tiling, complevel=level, separator=separator)

    return RunStore.create(root, manifest, files, complevel, warn)


# --- committing a store -------------------------------------------------------------------------


def put_in_place(src: Path, out: Path, *, overwrite: bool, aside: Path) -> None:
    """Rename the committed store ``src`` to ``out``. An existing ``out`` is refused
    (FileExistsError) unless ``overwrite``; then it is first renamed to ``aside`` (in the
    run's private directory) and deleted after."""
    _remove(aside)  # the output a killed run had set aside
    if os.path.lexists(out):
        if not overwrite:
            raise exists_error(out)
        if not_regular(out, follow_links=False) not in (None, "a symbolic link", "a directory"):
            refuse_special(out)  # a FIFO, a device or a socket is never replaced
        os.rename(out, aside)
    try:
        os.rename(src, out)
    except (FileExistsError, IsADirectoryError, NotADirectoryError, OSError) as exc:
        if os.path.lexists(out):  # appeared meanwhile (a non-empty directory, a file)
            raise exists_error(out) from None
        raise exc
    fsync_dir(out.parent)
    fsync_dir(src.parent)
    _remove(aside)


def _remove(path: Path) -> None:
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path)
    elif os.path.lexists(path):
        os.unlink(path)


def _provenance_attrs(plan: RunPlan, command: str, fingerprint: str, block: tuple[int, ...]):
    attrs = cf_attrs(
        plan.attrs(),
        title=plan.title,
        survey_definition=plan.source_text,
        command=command,
        scene=plan.scene,
    )
    return {**attrs, FINGERPRINT_ATTR: fingerprint, CHECKSUM_BLOCK_ATTR: list(block)}


def _receipt_block(receipt: dict) -> dict[str, np.ndarray]:
    """A stand-in block whose statistics (:class:`Summary`) are the receipt's."""
    out: dict[str, np.ndarray] = {}
    for name, counts in receipt["summary"]["flags"].items():
        out[name] = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
    for name, lo_hi in receipt["summary"]["ranges"].items():
        out[name] = np.asarray(lo_hi, np.float64)
    return out


def merge(
    store: RunStore,
    plan: RunPlan,
    out: Path,
    *,
    fingerprint: str,
    command: str = "conesurvey",
    overwrite: bool = False,
    complevel: int = 1,
) -> Summary:
    """Commit the run's store and rename it to ``out``: every file of the store what the run
    wrote (:func:`engine.io.zarrverify.check_store`; no value is decoded), the content checksum
    (scheme ``sha256-blocks-v1``) combined from the receipts, the statistics gathered from
    them. FileExistsError if ``out`` exists and not ``overwrite``; OutputError if a block is
    missing or changed; OSError if the disk fails. ``complevel`` was fixed when the store was
    made."""
    if os.path.lexists(out) and not overwrite:
        raise exists_error(out)
    store.check_files()
    tiling = store.tiling
    hasher = ContentHasher(tiling.block, BLOCK_SCHEME)
    for d in plan.dims:
        hasher.add(d, np.asarray(plan.axis(d), np.float64))
    summary = Summary()
    families = survey_families(plan)  # written when the store was made: the same values
    for name, values in families.items():
        hasher.add(name, values)
    summary.add(families)
    for i in range(tiling.nblocks):
        receipt = store.journal[i]
        for name in store.names:
            hasher.add_digest(name, bytes.fromhex(receipt["values"][name]))
        summary.add(_receipt_block(receipt))
    attrs = _provenance_attrs(plan, command, fingerprint, tiling.block)
    try:
        _, root = commit_store(store.store, attrs, hasher, store.files or {},
                               record=(store.root, store.run_id))  # fmt: skip
        hold_file(store.held, store.store, META, root)
        store.check_held()  # the last look: a writer from here on waits until the rename
        put_in_place(store.store, out, overwrite=overwrite, aside=store.root / "replaced.zarr")
    finally:
        store.release()
    return summary


def write_survey(
    ds: xr.Dataset,
    path: str | os.PathLike[str],
    plan: RunPlan,
    *,
    command: str = "conesurvey",
    overwrite: bool = False,
) -> Path:
    """Write the in-memory survey ``ds`` (the results of ``survey``) as the Zarr store
    ``path``, through a temporary store beside it renamed into place."""
    path = Path(path)
    if os.path.lexists(path) and not overwrite:
        raise exists_error(path)
    dims = tuple(plan.dims)
    names = {n: ds[n].dtype for n in plan.variables if n in ds and ds[n].dims == dims}
    families = {n: ds[n].values for n in plan.variables if n in ds and n not in names}
    tiling = Tiling.for_grid(plan.shape)
    blocks = (
        (i, {n: ds[n].values[tiling.slices(i)] for n in names}) for i in range(tiling.nblocks)
    )
    attrs = cf_attrs(
        ds.attrs, title=plan.title, survey_definition=plan.source_text,
        command=command, scene=plan.scene,
    )  # fmt: skip
    attrs[CHECKSUM_BLOCK_ATTR] = list(tiling.block)
    lay = layout(plan, names, families)
    write_store(path, lay, tiling, blocks, attrs, overwrite=overwrite)
    return path


def write_store(
    out: Path,
    layout: Mapping[str, Any],
    tiling: Tiling,
    blocks: Any,
    attrs: Mapping[str, Any],
    *,
    overwrite: bool = False,
    complevel: int = 1,
    hasher: ContentHasher | None = None,
    before_commit: Callable[[], None] | None = None,
) -> str:
    """Write a whole store in this process: ``layout`` (axes, variables, families: see
    :func:`make_store`), the ``(index, arrays)`` of every block of ``tiling``, the global
    ``attrs``; built as ``OUT.<random>.tmp`` beside ``out``, committed and renamed into place.
    The content checksum is ``hasher``'s if given (the caller adds every value to it; a
    conversion keeps the source's scheme), else one of scheme ``sha256-blocks-v1`` computed
    as the blocks are written. ``before_commit()`` may still refuse (raise): nothing is then
    left. Returns the checksum."""
    tmp = out.with_name(f"{out.name}.{os.urandom(6).hex()}.tmp")
    run_id = os.urandom(16).hex()
    variables = layout["variables"]
    arrays = tuple((n, dt.str) for n, (dt, _) in variables.items())
    count = len(arrays) * math.prod(-(-n // c) for n, c in zip(tiling.shape, tiling.chunk,
                                                              strict=True))  # fmt: skip
    held = HeldFiles(count + 64)  # as a run's: held from the write (or check) to the rename
    receipts: dict[int, dict] = {}
    try:
        files = skeleton(run_id, **layout, tiling=tiling, complevel=complevel)
        make_store(tmp, files)
        writer = ChunkWriter(str(tmp), run_id, tiling.shape, tiling.chunk, arrays, complevel,
                             held=held)  # fmt: skip
        own = ContentHasher(tiling.block, BLOCK_SCHEME)
        for d, (values, _) in layout["axes"].items():
            own.add(d, values)
        for name, (values, *_) in layout.get("families", {}).items():
            own.add(name, values)
        for i, block in blocks:
            receipts[i] = receipt = writer.write(i, tiling.slices(i), block)
            for name in variables:
                own.add_digest(name, bytes.fromhex(receipt["values"][name]))
        if before_commit is not None:
            before_commit()
        limit = (
            max(np.dtype(dt).itemsize for dt, _ in variables.values()) * math.prod(tiling.chunk)
            + 1024
        )
        keys = functools.partial(_block_keys, tiling, writer)
        check_store(tmp, files, held, keys, receipts, limit)
        result, root = commit_store(tmp, attrs, hasher or own, files)
        hold_file(held, tmp, META, root)
        check_held(held, tmp)
        aside = out.with_name(f"{out.name}.{os.urandom(6).hex()}.tmp")
        put_in_place(tmp, out, overwrite=overwrite, aside=aside)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        held.release()
    return result


def _block_keys(tiling: Tiling, writer: ChunkWriter, index: int) -> list[str]:
    slab = tiling.slices(index)
    return [
        k for n, _ in writer.arrays for k in chunk_keys(n, slab, tiling.chunk, writer.separator)
    ]


def open_view(path: Path) -> ZarrView:
    """A finished store read through the netCDF4 interface (``convert``): OutputError for one
    holding a link, a FIFO or a device, an oversized chunk, or arrays that differ from its
    consolidated metadata (damaged: ``info --verify`` says so too)."""
    path = Path(path)
    check_tree(path)
    attrs = read_meta(path / META).get("attributes")
    if isinstance(attrs, dict) and UNFINISHED_ATTR in attrs:
        raise OutputError(f"{path} is an unfinished run's store; finish the run first")
    if problem := metadata_problem(path):
        raise OutputError(f"{path} is damaged: {problem}")
    return ZarrView(path)


def read_fingerprint(path: Path) -> str | None:
    """The survey fingerprint a finished store records (None if it has none or is not a
    readable, finished Zarr store)."""
    try:
        attrs = read_meta(Path(path) / "zarr.json").get("attributes", {})
    except OutputError:
        return None
    if not isinstance(attrs, dict) or UNFINISHED_ATTR in attrs:
        return None
    fp = attrs.get(FINGERPRINT_ATTR)
    return fp if isinstance(fp, str) else None


def read_info(path: str | os.PathLike[str], *, verify: bool = False) -> dict[str, Any]:
    """Provenance of a store or of the unfinished run behind it: the keys of
    :func:`engine.io.netcdf.read_info`. OutputError if there is neither or the store is not
    readable; never anything else for a damaged or foreign store."""
    path = Path(path)
    parts = parts_dir(path)
    info: dict[str, Any] = {"path": str(path), "notes": []}
    if os.path.lexists(path):
        if os.path.islink(path) or not os.path.isdir(path):
            raise OutputError(f"{path} is not a Zarr store (a directory)")
        info.update(_store_info(path, verify))
        info["leftover_parts"] = os.path.lexists(parts)
    elif os.path.lexists(parts):
        try:
            check_parts_dir(parts)
            state = parts_state(parts)
            state["dims"] = dict(zip(survey_dims(state["attrs"]["survey_definition"]),
                                     state.pop("shape"), strict=True))  # fmt: skip
            info.update(state)
        except (OutputError, OSError) as exc:
            info.update({"complete": False, "attrs": {}, "dims": {}, "problem": str(exc)})
    else:
        raise OutputError(f"no such Zarr store: {path}")
    return info


def _store_info(path: Path, verify: bool) -> dict[str, Any]:
    info: dict[str, Any] = {"notes": []}
    check_tree(path)  # nothing followed, no FIFO or device opened, no chunk read unbounded
    try:
        view = ZarrView(path)
    except OutputError:
        raise
    except Exception as exc:  # zarr raises many kinds for a damaged or foreign store
        raise OutputError(f"{path} is not a readable Zarr store ({exc})") from None
    attrs = {k: view.getncattr(k) for k in view.ncattrs()}
    info["attrs"] = attrs
    dims: dict[str, int] = {}
    for var in view.variables.values():
        dims.update(zip(var.dimensions, var.shape, strict=False))
    grid = [d for d in grid_dims(dims) if d in dims]  # in the grid's order, as a netCDF file's
    info["dims"] = {**{d: dims[d] for d in grid}, **dims}
    counts = class_counts(view, info["notes"])
    if counts is not None:
        info["counts"] = counts
    if (fates := fate_counts(view, info["notes"])) is not None:
        info["fate_counts"] = fates
    info["complete"] = FINGERPRINT_ATTR in attrs and UNFINISHED_ATTR not in attrs
    info["checksum"] = CHECKSUM_ATTR in attrs
    if verify:
        problem = metadata_problem(path)
        info["verified"] = (False, problem) if problem else verify_file(view)
    return info

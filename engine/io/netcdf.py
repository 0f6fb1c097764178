"""The netCDF-4 backend: CF-1.11 files, written crash-safely (:mod:`engine.io.atomic`).

The netCDF row of :mod:`engine.io.formats` (the protocol of every format) is built from:

- ``write_survey(ds, path, survey, *, command, overwrite) -> Path``: an in-memory survey
  Dataset with the survey's title, definition and scene;
- ``merge(store, plan, out, *, fingerprint, command, overwrite, compression, complevel,
  pending, incoming) -> Summary``: the blocks of a streamed run
  (:class:`engine.io.blocks.BlockStore`) into ``out`` with its content checksum
  (:mod:`engine.io.contents`), written while the blocks still ``pending`` are computed (the
  caller's ``incoming`` yields each once it is committed; :mod:`engine.io.feed`); blocks not
  handed over are verified as they are read; returns the class counts and value ranges
  gathered on the way;
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

import contextlib
import math
import os
import sys
from collections.abc import Callable, Collection, Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import netCDF4  # ~9 ms once engine is imported: not worth a lazy import
import numpy as np

from ..grid import storage_chunks
from ..schema import FINGERPRINT_ATTR, axis_attrs, variable_attrs, variable_dims
from . import WriteError, deflate
from .atomic import fsync_path, replacing
from .blocks import BlockStore
from .cf import CONVENTIONS, cf_attrs, cf_dataset, history_line, typed_flags
from .codecs import (
    DEFAULT_COMPRESSION,
    FALLBACK,
    compression_keywords,
    fallback_notice,
    is_blosc,
    merge_notices,
    variable_keywords,
)
from .contents import CHECKSUM_ATTR, CHECKSUM_BLOCK_ATTR, ContentHasher
from .feed import feed
from .manifest import survey_families
from .netcdf_info import read_fingerprint, read_info
from .pagecache import flushing
from .space import free_bytes, output_bytes
from .summary import Summary

if TYPE_CHECKING:
    import xarray as xr

    from .planshape import RunPlan

__all__ = [
    "CONVENTIONS",
    "cf_attrs",
    "cf_dataset",
    "encoding_for",
    "history_line",
    "merge",
    "output_bytes",
    "read_fingerprint",
    "read_info",
    "write_netcdf",
    "write_survey",
]

# --- encodings ------------------------------------------------------------------------------


def encoding_for(
    ds: xr.Dataset, compression: str = DEFAULT_COMPRESSION, complevel: int | None = None
) -> dict[str, dict[str, Any]]:
    """netCDF encodings: coordinates without _FillValue, data variables compressed
    (:func:`engine.io.codecs.variable_keywords`, by the variable's size: netCDF-C chunks a
    small variable whole)."""
    compression_keywords(compression, complevel)  # ValueError for a bad choice, always
    enc: dict[str, dict[str, Any]] = {}
    for name, var in ds.variables.items():
        if name in ds.coords:
            if var.dtype.kind == "f":
                enc[str(name)] = {"_FillValue": None}
        elif var.ndim > 0:
            codec = variable_keywords(compression, complevel, var.nbytes)
            enc[str(name)] = {**codec, "dtype": var.dtype}
    return enc


# --- writing ----------------------------------------------------------------------------------


def write_netcdf(
    ds: xr.Dataset,
    path: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    compression: str = DEFAULT_COMPRESSION,
    complevel: int | None = None,
) -> Path:
    """Write ``ds`` to the netCDF-4 file ``path`` atomically, its variables compressed
    (:func:`compression_keywords`); returns the path.

    Raises ``FileExistsError`` if ``path`` exists and not ``overwrite`` (checked before writing
    and again, atomically where the file system supports hard links, when renaming).
    """
    path = Path(path)
    enc = encoding_for(ds, compression, complevel)
    if notice := fallback_notice(compression):
        _warn(notice)
    with replacing(path, overwrite=overwrite) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4", encoding=enc)
        fsync_path(tmp)
    return path


def write_survey(
    ds: xr.Dataset,
    path: str | os.PathLike[str],
    plan: RunPlan,
    *,
    command: str = "conesurvey",
    overwrite: bool = False,
    compression: str = DEFAULT_COMPRESSION,
    complevel: int | None = None,
) -> Path:
    """Add the survey's title, definition and scene (:func:`cf_dataset`), then write it."""
    full = cf_dataset(ds, **_provenance(plan, command))
    return write_netcdf(
        full, path, overwrite=overwrite, compression=compression, complevel=complevel
    )


def _provenance(plan: RunPlan, command: str) -> dict[str, Any]:
    """The keywords of :func:`cf_attrs` that a survey and the command that ran it give."""
    return {
        "title": plan.title,
        "survey_definition": plan.source_text,
        "command": command,
        "scene": plan.scene,
    }


def merge(
    store: BlockStore,
    plan: RunPlan,
    out: Path,
    *,
    fingerprint: str,
    command: str = "conesurvey",
    overwrite: bool = False,
    compression: str = DEFAULT_COMPRESSION,
    complevel: int | None = None,
    pending: Collection[int] = (),
    incoming: Iterable[tuple[int, dict[str, np.ndarray]]] = (),
    warn: Callable[[str], None] | None = None,
) -> Summary:
    """Write every block of ``store`` into ``out`` (netCDF-4, one storage chunk per block part,
    compressed: :func:`engine.io.codecs.variable_keywords`) through a temporary file inside the
    store (private to the run); returns the statistics gathered on the way. The file carries
    the content checksum (:mod:`engine.io.contents`) of what was written. If blosc fails on a
    chunk, the file is written again from the store with that variable in zstd (``warn``
    says so).

    ``pending``: the blocks not in the store yet; iterating ``incoming`` (on this thread)
    computes them and yields each, ``(index, arrays as stored)``, once it is committed. The
    file is defined first (every variable and attribute) and written by a writer thread in
    block order while they are computed (:class:`engine.io.feed.BlockFeed`); it is renamed to
    ``out`` only when complete. What ``incoming`` raises is raised after the temporary file is
    removed.

    ValueError for a bad ``compression`` or ``complevel``; FileExistsError if ``out`` exists
    and not ``overwrite``; OutputError if a block is missing or fails its checksum;
    WriteError if the netCDF library fails to write (a full disk shows up as "NetCDF: HDF
    error"); nothing is left under ``out`` in any of these cases.
    """
    for notice in merge_notices(compression, complevel):
        (warn or _warn)(notice)
    chunk = math.prod(store.tiling.chunk)
    codecs = {
        n: variable_keywords(compression, complevel, chunk * dt.itemsize)
        for n, dt in store.names.items()
    }
    families = survey_families(plan)  # on fewer dims: written whole as the file is defined
    for n, values in families.items():
        kw = variable_keywords(compression, complevel, values.nbytes)
        codecs[n] = variable_keywords(FALLBACK, complevel, 0) if is_blosc(kw) else kw
    attrs = cf_attrs(plan.attrs(), **_provenance(plan, command))
    attrs[FINGERPRINT_ATTR] = fingerprint
    upstream: list[BaseException] = []  # what the compute raised: passed on as it is

    def computed() -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        try:
            yield from incoming
        except BaseException as exc:
            upstream.append(exc)
            raise

    blocks: Iterable[tuple[int, dict[str, np.ndarray]]] = computed()
    while True:
        try:
            with replacing(out, overwrite=overwrite, tmp_dir=store.root) as tmp:
                try:
                    with flushing(tmp, drop=True):  # the disk writes while blocks are computed
                        summary = _write_file(
                            tmp, store, plan, attrs, codecs, families, pending, blocks,
                            warn or _warn,
                        )  # fmt: skip
                except (RuntimeError, OSError) as exc:  # netCDF4 reports HDF5 failures (ENOSPC
                    # too) as RuntimeError, h5py as OSError
                    if upstream and exc is upstream[0]:
                        raise
                    raise WriteError(f"writing {out} failed ({exc})") from None
                fsync_path(tmp)
            return summary
        except _Refused as exc:  # the file is gone: rewritten, that variable with zstd
            if free_bytes(store.root) < _ROOM:  # a full disk: the same error as any other codec's
                raise WriteError(f"writing {out} failed ({exc.__cause__})") from None
            codecs[exc.name] = variable_keywords(FALLBACK, complevel, 0)
            (warn or _warn)(
                f"{exc.name}: a storage chunk that blosc cannot shrink (HDF5's blosc filter "
                f"then fails); {out.name} is written again with {exc.name} in {FALLBACK}"
            )
            pending, blocks = (), ()


class _Refused(Exception):  # noqa: N818 (not an error: the merge's signal to rewrite)
    """Blosc could not write a chunk of variable ``name``."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.name = name


#: Free bytes below which a failed blosc write is taken for a full disk, not a chunk blosc
#: cannot shrink (HDF5 reports both as "NetCDF: HDF error").
_ROOM = 1 << 26


def _warn(msg: str) -> None:
    print(f"conesurvey: warning: {msg}", file=sys.stderr)


def _write_file(
    tmp: Path,
    store: BlockStore,
    plan: RunPlan,
    attrs: dict[str, Any],
    codecs: dict[str, dict[str, Any]],
    families: dict[str, np.ndarray],
    pending: Collection[int],
    blocks: Iterable[tuple[int, dict[str, np.ndarray]]],
    warn: Callable[[str], None],
) -> Summary:
    """One attempt of :func:`merge` into ``tmp``: define, fill, checksum, close. Deflate
    variables are written as chunks compressed on every core (:mod:`engine.io.deflate`) into
    the file defined by netCDF4 and closed, then reopened for the checksum; where h5py
    cannot open it, through netCDF4 (``warn`` says so)."""
    deflated = all(kw.get("compression") == "zlib" for kw in codecs.values())
    direct = deflated and not deflate.unavailable()
    direct = deflated and not deflate.unavailable()
    nc = netCDF4.Dataset(tmp, "w", format="NETCDF4")
    try:
        hasher = ContentHasher(store.tiling.block)
        variables = _define(nc, store, plan, attrs, codecs, families, hasher)
        chunks = _direct(nc, tmp, store, warn) if direct else None
        if chunks is not None:
            with chunks:
                summary = _fill(store, chunks.submit, codecs, hasher, pending, blocks, chunks)
            nc = netCDF4.Dataset(tmp, "a")
        else:
            if direct:  # h5py could not open it: netCDF4 writes the values
                nc = netCDF4.Dataset(tmp, "a")
                variables = {n: nc[n] for n in store.names}
            summary = _fill(store, _netcdf4_writer(variables), codecs, hasher, pending, blocks)
        summary.add(families)  # their ranges
        nc.setncattr(CHECKSUM_ATTR, hasher.finish(nc))
    except BaseException:
        with contextlib.suppress(Exception):  # after a failed write the close fails too
            nc.close()
        raise
    nc.close()
    return summary


def _direct(nc: Any, tmp: Path, store: BlockStore, warn: Callable[[str], None]) -> Any:
    """Close ``nc`` (defined) and open it for direct chunk writes; None (and a notice) if h5py
    cannot open the file or finds the filters other than defined."""
    nc.close()
    try:
        return deflate.DirectChunks(tmp, store.names)
    except (OSError, ValueError) as exc:
        warn(f"zlib is compressed by netCDF4 on one thread, slower: h5py cannot write ({exc})")
        return None


def _define(
    nc: Any,
    store: BlockStore,
    plan: RunPlan,
    attrs: dict[str, Any],
    codecs: dict[str, dict[str, Any]],
    families: dict[str, np.ndarray],
    hasher: ContentHasher,
) -> dict[str, Any]:
    """Define the whole file up front: global attributes, axes and the variables on fewer dims
    (``families``: written and hashed whole) and the result variables the blocks hold (no
    values yet); returns the latter by name."""
    nc.setncatts({**attrs, CHECKSUM_BLOCK_ATTR: np.asarray(store.tiling.block, np.int64)})
    for d in plan.dims:
        values = np.asarray(plan.axis(d), np.float64)
        nc.createDimension(d, values.size)
        v = nc.createVariable(d, "f8", (d,), fill_value=False)
        v.setncatts(axis_attrs(d, plan.energy_relative))
        v[:] = values
        hasher.add(d, values)
    kind = plan.map_kind
    variables = {}
    for name, dt in plan.variables.items():
        fill = False if dt.kind in "iu" else np.nan
        if name in families:
            values, dims = families[name], variable_dims(name, plan.dims)
            kw = {"chunksizes": storage_chunks(values.shape), **codecs[name]}
            v = nc.createVariable(name, dt, dims, fill_value=fill, **kw)
            v.setncatts(typed_flags(variable_attrs(name, kind), dt))
            v[...] = values
            hasher.add(name, values)
            continue
        v = nc.createVariable(
            name, dt, plan.dims, chunksizes=store.tiling.chunk, fill_value=fill, **codecs[name]
        )
        v.setncatts(typed_flags(variable_attrs(name, kind), dt))
        variables[name] = v
    # Blocks fill whole chunks: none is read back, so none is cached (each is compressed and
    # written as its block is); set once the variables exist in HDF5 (the sync) to apply.
    nc.sync()
    for v in variables.values():
        v.set_var_chunk_cache(size=0)
    return variables


def _netcdf4_writer(variables: dict[str, Any]) -> Callable[..., Callable[[], None]]:
    def put(name: str, slab: tuple, values: np.ndarray) -> Callable[[], None]:
        variables[name][slab] = values
        return lambda: None  # written already

    return put


def _fill(
    store: BlockStore,
    put: Callable[[str, tuple, np.ndarray], Callable[[], None]],
    codecs: dict[str, dict[str, Any]],
    hasher: ContentHasher,
    pending: Collection[int],
    incoming: Iterable[tuple[int, dict[str, np.ndarray]]],
    direct: deflate.DirectChunks | None = None,
) -> Summary:
    """Write every block on a writer thread while ``incoming`` computes the ``pending`` ones
    (:func:`engine.io.feed.feed`): a block whose file holds the chunks this file stores
    (:mod:`engine.io.chunkfile`) has them copied by ``direct``; else ``put(name, slab,
    values)`` starts a variable (direct chunks: compressed on the pool) and returns the call
    that completes it. A block is hashed and counted meanwhile."""
    summary = Summary()
    chunk = store.tiling.chunk

    def write(index: int, block: dict[str, np.ndarray]) -> None:
        slab = store.tiling.slices(index)
        finishing = []
        stored, codec = getattr(block, "chunks", None), getattr(block, "codec", None)
        for name, arr in block.items():
            if direct is not None and stored and direct.copies(name, codec, chunk):
                finishing.append(direct.copy(name, slab, stored[name]))
                continue
            try:
                finishing.append(put(name, slab, arr))
            except RuntimeError as exc:
                if is_blosc(codecs[name]):
                    raise _Refused(name) from exc
                raise
        for name, arr in block.items():
            hasher.add(name, arr)
        summary.add(block)
        for done in finishing:
            done()

    feed(store, write, pending, incoming)
    return summary

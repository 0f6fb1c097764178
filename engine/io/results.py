"""Open a survey result for reading, whatever state or format it is in: :func:`open_result`.

One function opens every kind of result the commands ``plot`` and ``report`` look at:

- a finished netCDF file ``OUT.nc`` (read lazily with xarray: a map reads only its slice);
- a run that is still going or was killed: ``OUT.nc`` is not there yet but ``OUT.nc.parts/``
  holds some blocks (:mod:`engine.io.blocks`). The blocks are read lazily too, one block file
  at a time (a ``.npz`` member, or a ``.chunks`` file decoded), never modified (a reader must
  not touch a running run's files); points of blocks not computed yet are NaN and
  :meth:`Result.computed` tells them from undefined values. Integer variables
  (``orbit_class``, ``status``) become float64 so that they can hold NaN.

- a finished Zarr store ``OUT.zarr`` (:mod:`engine.io.zarr`), or the unfinished run behind it
  (``OUT.zarr.parts/``: the blocks its journal records are read from its store).

Another format is one more case in :func:`open_result` returning the same :class:`Result`.
Variable and axis attributes come from the file itself, or for an unfinished run from
:mod:`engine.schema`, as the finished file will carry them.
"""

from __future__ import annotations

import itertools
import os
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import xarray as xr
from xarray.backends import BackendArray
from xarray.core import indexing

from ..grid import Tiling, block_shape, storage_chunks
from ..schema import FINGERPRINT_ATTR, axis_attrs, grid_dims, variable_attrs, variable_dims
from . import OutputError
from .blocks import BlockStore
from .formats import format_for
from .manifest import parts_dir, read_manifest, survey_families
from .planshape import RunPlan
from .zarr import zarr_module
from .zarrlayout import STORE, UNFINISHED_ATTR
from .zarrstore import RunStore

__all__ = [
    "READ_POINTS",
    "PlanReader",
    "Result",
    "open_netcdf",
    "open_result",
    "open_zarr",
    "read_plans_with",
]

#: Points per tile when a finished file is read tile by tile (~16 MB of float64).
READ_POINTS = 1 << 21


@dataclass
class Result:
    """A survey result opened for reading.

    ``ds``: the variables with their CF attributes and the global attributes (lazy);
    ``complete``: a finished result; ``tiling``: the tiles it is best read in (the blocks of an
    unfinished run, storage-chunk-aligned tiles of a file); ``done``: indices of the blocks
    computed so far (None when complete); ``fingerprint``: the survey's fingerprint.
    """

    path: Path
    ds: xr.Dataset
    complete: bool
    tiling: Tiling
    done: frozenset[int] | None = None
    fingerprint: str | None = None
    kind: str = "netcdf"

    @property
    def dims(self) -> tuple[str, ...]:
        """The survey's axes, in order: (alpha, energy, h, Lz) or (alpha, r0, v0, w0)."""
        return grid_dims(self.ds.dims)

    @property
    def blocks_total(self) -> int:
        return self.tiling.nblocks

    @property
    def blocks_done(self) -> int:
        return self.blocks_total if self.done is None else len(self.done)

    @property
    def points_done(self) -> int:
        if self.done is None:
            return self.tiling.size
        return sum(self.tiling.points(i) for i in self.done)

    @property
    def note(self) -> str:
        """``unfinished run: 3 of 8 blocks computed (37.5 % of points)``; "" when complete."""
        if self.complete:
            return ""
        pct = 100.0 * self.points_done / max(self.tiling.size, 1)
        return (
            f"unfinished run: {self.blocks_done} of {self.blocks_total} blocks computed "
            f"({pct:.1f} % of points)"
        )

    def computed(self) -> xr.DataArray | None:
        """Lazy boolean map over the survey axes: True where a point has been computed (None
        for a finished result, where every point is)."""
        if self.done is None:
            return None
        arr = _BlockArray(self.tiling, self.done, None, np.dtype(bool))
        var = xr.Variable(self.dims, indexing.LazilyIndexedArray(arr))
        coords = {d: self.ds.coords[d] for d in self.dims}
        return xr.DataArray(var, coords=coords, name="computed")

    def tiles(self) -> Iterator[dict[str, slice]]:
        """Selections (dim -> slice) covering every computed point once, tile by tile."""
        indices = range(self.tiling.nblocks) if self.done is None else sorted(self.done)
        for i in indices:
            yield dict(zip(self.dims, self.tiling.slices(i), strict=True))

    def close(self) -> None:
        self.ds.close()

    def __enter__(self) -> Result:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_result(path: str | os.PathLike[str]) -> Result:
    """Open the survey result ``path`` for reading: a finished netCDF file, or the unfinished
    run behind it (``path`` + ``.parts``; the ``.parts`` directory itself is accepted too).

    Raises OutputError naming the path when there is neither or it cannot be read.
    """
    path = Path(path)
    if path.name.endswith(".parts") and path.is_dir():
        path = path.with_name(path.name[: -len(".parts")])
    fmt = format_for(path)
    if fmt.open_result is not None and (path.is_dir() if fmt.directory else path.is_file()):
        return fmt.open_result(path)
    if path.is_file():  # a file under another name: netCDF-4 is the default format
        return open_netcdf(path)
    if parts_dir(path).is_dir():
        return _open_parts(path)
    if path.is_dir():
        raise OutputError(f"{path} is a directory, not a conesurvey result file")
    raise OutputError(f"no such file: {path} (nor an unfinished run {parts_dir(path).name}/)")


def open_netcdf(path: Path) -> Result:
    """A finished netCDF file (the netCDF row's ``open_result``)."""
    try:
        ds = xr.open_dataset(path, engine="netcdf4")
    except (OSError, ValueError) as exc:
        raise OutputError(f"{path} is not a readable netCDF file ({exc})") from None
    return _finished(path, ds, "netcdf", "chunksizes")


def open_zarr(path: Path) -> Result:
    """A finished Zarr store (the Zarr row's ``open_result``)."""
    zarr_module()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # consolidated metadata is not in the v3 spec (yet)
            ds = xr.open_zarr(path, chunks=None)
    except Exception as exc:  # zarr raises many kinds for a damaged or foreign store
        raise OutputError(f"{path} is not a readable Zarr store ({exc})") from None
    if UNFINISHED_ATTR in ds.attrs:
        ds.close()
        raise OutputError(f"{path} is the store of an unfinished run; open its output name")
    for var in ds.data_vars.values():  # JSON attributes: flags get the variable's type again
        if "flag_values" in var.attrs:
            var.attrs["flag_values"] = np.asarray(var.attrs["flag_values"], var.dtype)
    return _finished(path, ds, "zarr", "chunks")


def _finished(path: Path, ds: xr.Dataset, kind: str, chunk_key: str) -> Result:
    """A finished result: checked to be a survey, read in storage-chunk-aligned tiles."""
    dims = grid_dims(ds.dims)
    missing = [d for d in dims if d not in ds.dims]
    if missing or "orbit_class" not in ds:
        ds.close()
        what = f"the axes {missing}" if missing else "the variable orbit_class"
        raise OutputError(f"{path} is not a conesurvey survey: it has no {what}")
    shape = tuple(ds.sizes[d] for d in dims)
    chunk = ds["orbit_class"].encoding.get(chunk_key) or storage_chunks(shape)
    tiling = Tiling(shape, tuple(chunk), block_shape(shape, tuple(chunk), READ_POINTS))
    fp = ds.attrs.get(FINGERPRINT_ATTR)
    # An in-memory survey written by write_survey carries no fingerprint but is complete.
    return Result(path, ds, True, tiling, None, fp, kind)


class PlanReader(Protocol):
    """How an unfinished run's survey definition (the TOML text its manifest keeps) becomes its
    plan: ``reader(text, origin)``, a ValueError naming the problem where the text is not a
    survey. The survey-file reader sits above this layer and hands itself down
    (:func:`read_plans_with`; ``engine/__init__.py`` does, so it is in place wherever the
    package is imported)."""

    def __call__(self, text: str, origin: str) -> RunPlan: ...


_readers: list[PlanReader] = []


def read_plans_with(reader: PlanReader) -> None:
    """Read unfinished runs' survey definitions with ``reader`` from now on."""
    _readers[:] = [reader]


def _open_parts(path: Path) -> Result:
    root = parts_dir(path)
    manifest = read_manifest(root)
    if not _readers:  # the package's import hands it down: only a broken install gets here
        raise OutputError(f"{root}: no survey reader to read the unfinished run's definition")
    try:
        plan = _readers[0](manifest.survey_definition, f"{root.name}/manifest.json")
    except ValueError as exc:
        raise OutputError(f"cannot read the unfinished run's survey definition: {exc}") from None
    tiling = manifest.tiling
    axes = dict(zip(plan.dims, plan.axes, strict=True))
    if tuple(a.size for a in axes.values()) != tiling.shape:
        raise OutputError(f"{root}: the manifest's grid does not match its survey definition")
    kind = plan.map_kind
    # Blocks journaled (committed) whose files are there; a reader hashes nothing and changes
    # nothing (the run that owns the store verifies its blocks).
    if (root / STORE).is_dir():
        zarr_module()
        store: BlockStore | RunStore = RunStore.open(root)
        done = frozenset(store.journal)
        load = _zarr_loader(root / STORE, tiling)
    else:
        store = BlockStore.open(root)
        done = frozenset(i for i in store.journal if store.path(i).is_file())
        load = _block_loader(store)
    coords = {d: xr.Variable(d, v, axis_attrs(d, plan.energy_relative)) for d, v in axes.items()}
    data = {}
    for name, dtype in store.names.items():
        arr = _BlockArray(
            tiling, done, load, np.dtype(np.float64) if dtype.kind in "iub" else dtype
        )
        arr.name = name
        data[name] = xr.Variable(plan.dims, indexing.LazilyIndexedArray(arr),
                                 variable_attrs(name, kind))  # fmt: skip
    attrs: dict[str, Any] = {
        "title": plan.title,
        **plan.attrs(),
        "source": f"conesurvey {manifest.engine}",
        "survey_definition": manifest.survey_definition,
    }
    for name, values in survey_families(plan).items():  # on fewer dims: computed here
        dims = variable_dims(name, plan.dims)
        data[name] = xr.Variable(dims, values, variable_attrs(name, kind))
    order = [n for n in plan.variables if n in data]
    ds = xr.Dataset({n: data[n] for n in order}, coords=coords, attrs=attrs)
    return Result(path, ds, False, tiling, done, manifest.fingerprint, "parts")


Loader = Callable[[int, str], "np.ndarray | None"]


def _block_loader(store: BlockStore) -> Loader:
    """Block files of either kind (values in ``.npz``, compressed chunks), read unverified."""

    def load(index: int, name: str) -> np.ndarray | None:
        try:
            if store.codec is not None:
                return store.decode(index, store.path(index).read_bytes())[name]
            with np.load(store.path(index), allow_pickle=False) as z:
                return z[name]
        except Exception:  # vanished (the run just finished), truncated, wrong members ...
            return None

    return load


def _zarr_loader(store: Path, tiling: Tiling) -> Loader:
    zarr = zarr_module()
    group = zarr.open_group(zarr.storage.LocalStore(store, read_only=True), mode="r")

    def load(index: int, name: str) -> np.ndarray | None:
        try:
            return np.asarray(group[name][tiling.slices(index)])
        except Exception:  # the run just finished and renamed its store, a damaged chunk ...
            return None

    return load


class _BlockArray(BackendArray):
    """One variable of an unfinished run (or, without a store, its computed mask), read lazily
    block by block; points of blocks not computed are NaN (False for the mask)."""

    def __init__(
        self, tiling: Tiling, done: frozenset[int], load: Loader | None, dtype: np.dtype
    ) -> None:
        self.tiling = tiling
        self.done = done
        self.load = load
        self.shape = tiling.shape
        self.dtype = dtype
        self.name = ""

    def __getitem__(self, key: indexing.ExplicitIndexer) -> np.ndarray:
        return indexing.explicit_indexing_adapter(
            key, self.shape, indexing.IndexingSupport.BASIC, self._raw_indexing_method
        )

    def _raw_indexing_method(self, key: tuple[Any, ...]) -> np.ndarray:
        picks = [np.arange(n)[k] for n, k in zip(self.shape, key, strict=True)]
        shape = tuple(p.size for p in picks if np.ndim(p))  # integer keys drop their dim
        flat = [np.atleast_1d(p) for p in picks]
        if any(p.size == 0 for p in flat):
            return np.empty(shape, self.dtype)
        lo = [int(p.min()) for p in flat]
        box = self._box(lo, [int(p.max()) + 1 for p in flat])
        return box[np.ix_(*(p - a for p, a in zip(flat, lo, strict=True)))].reshape(shape)

    def _box(self, lo: list[int], hi: list[int]) -> np.ndarray:
        """Values of the hyperslab [lo, hi) (NaN or False where no block is computed)."""
        fill = False if self.dtype.kind == "b" else np.nan
        box = np.full([b - a for a, b in zip(lo, hi, strict=True)], fill, self.dtype)
        ranges = [
            range(a // n, (b - 1) // n + 1)
            for a, b, n in zip(lo, hi, self.tiling.block, strict=True)
        ]
        for pos in itertools.product(*ranges):
            index = int(np.ravel_multi_index(pos, self.tiling.counts))
            if index not in self.done:
                continue
            slab = self.tiling.slices(index)
            inter = [
                slice(max(s.start, a), min(s.stop, b)) for s, a, b in zip(slab, lo, hi, strict=True)
            ]
            dst = tuple(slice(i.start - a, i.stop - a) for i, a in zip(inter, lo, strict=True))
            if self.load is None:
                box[dst] = True
                continue
            block = self._load(index)
            if block is not None:
                src = tuple(
                    slice(i.start - s.start, i.stop - s.start)
                    for i, s in zip(inter, slab, strict=True)
                )
                box[dst] = block[src]
        return box

    def _load(self, index: int) -> np.ndarray | None:
        """This variable of block ``index``, or None if it is unreadable (never deleted here:
        the run that owns the block decides)."""
        assert self.load is not None
        shape = tuple(s.stop - s.start for s in self.tiling.slices(index))
        arr = self.load(index, self.name)
        return arr if arr is not None and arr.shape == shape else None

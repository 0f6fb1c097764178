"""Streaming, resumable survey runs: blocks to disk as they finish, one netCDF file at the end.

Layout while a run is under way, next to the output ``OUT.nc``::

    OUT.nc.parts/manifest.json     fingerprint of the survey, engine version, tiling
    OUT.nc.parts/b00000042.npz     results of block 42 (written to .tmp, fsynced, renamed)

A block is done when its file exists; a run killed at any moment (SIGKILL included) loses at
most the blocks in flight. Running the same command again checks the fingerprint, deletes
stale ``.tmp`` files, verifies every stored block (a corrupt one is reported and recomputed)
and computes only the missing ones. At the end the blocks are merged into ``OUT.nc.tmp``,
which is fsynced and renamed to ``OUT.nc``; only then are the parts removed. Peak memory is a
few blocks, whatever the grid size. Blocks run locally (numba ``prange`` inside a block) or on
a dask.distributed cluster, the client staying the only writer.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import shutil
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .evaluation import evaluate_block
from .grid import BLOCK_POINTS, Tiling
from .schema import DIMS, axis_attrs, result_variables, survey_attrs, variable_attrs

if TYPE_CHECKING:
    from .surveyfile import Survey

__all__ = [
    "AlreadyComplete",
    "RunError",
    "RunStats",
    "fingerprint",
    "estimate_bytes",
    "run_survey",
    "read_info",
]

MANIFEST = "manifest.json"
#: Attribute of a finished output holding the survey fingerprint.
FINGERPRINT_ATTR = "survey_fingerprint"
#: zlib level 1 + shuffle: level 4 buys < 1 % smaller files for 7-26 % more time.
ZLIB_LEVEL = 1


class RunError(Exception):
    """A run that cannot start or resume (the message says why); CLI exit status 2."""


class AlreadyComplete(RunError):
    """The output already holds this very survey, finished: nothing to compute."""


# --- what a survey produces ------------------------------------------------------------


def output_variables(survey: Survey) -> dict[str, np.dtype]:
    """Names and dtypes of the result variables of ``survey``, in file order."""
    return result_variables(survey.method, survey.scene, survey.energy_relative)


def estimate_bytes(survey: Survey) -> int:
    """Uncompressed size [bytes] of the results (the block files hold this much)."""
    per_point = sum(dt.itemsize for dt in output_variables(survey).values())
    return per_point * survey.size


def fingerprint(survey: Survey) -> str:
    """SHA-256 of everything that determines the results: axes, scene, method, tolerances,
    title and the engine version."""
    from . import __version__

    doc = {
        "engine": __version__,
        "title": survey.title,
        "method": survey.method,
        "rtol": survey.rtol.hex(),
        "circular_tol": survey.circular_tol.hex(),
        "energy_relative": survey.energy_relative,
        "scene": {k: str(v) for k, v in survey.scene.as_attrs().items()},
        "axes": {d: [float(x).hex() for x in getattr(survey, d)] for d in DIMS},
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def block_spec(survey: Survey) -> dict[str, Any]:
    """What :func:`engine.grid.evaluate_block` needs (picklable, for dask workers too)."""
    spec: dict[str, Any] = {d: np.array(getattr(survey, d)) for d in DIMS}
    spec.update(
        scene=survey.scene,
        method=survey.method,
        energy_relative=survey.energy_relative,
        circular_tol=survey.circular_tol,
        rtol=survey.rtol,
    )
    return spec


def compute_block(spec: dict[str, Any], tiling: Tiling, index: int) -> tuple[int, dict]:
    """Results of block ``index`` (module-level, so dask can ship it to workers)."""
    return index, evaluate_block(spec, tiling.slices(index))


# --- durable small files ----------------------------------------------------------------


def _fsync_dir(directory: Path) -> None:
    fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _atomic_write(path: Path, write: Callable[[Any], None]) -> None:
    """Write ``path`` via ``path.tmp``: write, flush, fsync, rename, fsync the directory."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        write(f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    _fsync_dir(path.parent)


# --- the block store --------------------------------------------------------------------


@dataclass
class BlockStore:
    """Finished blocks of one run, one ``.npz`` file each, plus the manifest."""

    root: Path
    tiling: Tiling
    names: dict[str, np.dtype]
    warn: Callable[[str], None] = field(default=lambda msg: None)

    def path(self, index: int) -> Path:
        return self.root / f"b{index:08d}.npz"

    def save(self, index: int, arrays: dict[str, np.ndarray]) -> None:
        clean = {n: np.ascontiguousarray(arrays[n], dtype=dt) for n, dt in self.names.items()}
        _atomic_write(self.path(index), lambda f: np.savez(f, **clean))

    def load(self, index: int) -> dict[str, np.ndarray] | None:
        """The block's arrays, or None (after a warning) if its file is missing or corrupt."""
        p = self.path(index)
        shape = tuple(s.stop - s.start for s in self.tiling.slices(index))
        try:
            with np.load(p, allow_pickle=False) as z:
                out = {n: z[n] for n in self.names}
        except FileNotFoundError:
            return None
        except Exception as exc:  # truncated zip, bad CRC, missing member ...
            self.warn(f"block file {p.name} is corrupt ({exc.__class__.__name__}); recomputing")
            p.unlink(missing_ok=True)
            return None
        for n, dt in self.names.items():
            if out[n].shape != shape or out[n].dtype != dt:
                self.warn(f"block file {p.name} has the wrong {n} layout; recomputing")
                p.unlink(missing_ok=True)
                return None
        return out

    def done(self) -> set[int]:
        """Indices of blocks whose file exists (not yet verified)."""
        found = set()
        for p in self.root.glob("b*.npz"):
            with contextlib.suppress(ValueError):
                found.add(int(p.stem[1:]))
        return {i for i in found if i < self.tiling.nblocks}

    def verify(self) -> set[int]:
        """Indices of stored blocks that load and have the right layout."""
        return {i for i in sorted(self.done()) if self.load(i) is not None}


def _open_store(
    out: Path, survey: Survey, fp: str, chunk_points: int | None, warn: Callable[[str], None]
) -> tuple[BlockStore, int]:
    """Create or reopen ``OUT.parts``; returns the store and the number of blocks reused."""
    from . import __version__

    root = out.with_name(out.name + ".parts")
    names = output_variables(survey)
    manifest = root / MANIFEST
    if manifest.exists():
        try:
            m = json.loads(manifest.read_text())
            stored_fp = m["fingerprint"]
            tiling = Tiling(tuple(m["shape"]), tuple(m["chunk"]), tuple(m["block"]))
        except (ValueError, KeyError, TypeError) as exc:
            raise RunError(
                f"cannot resume: {manifest} is unreadable ({exc}); delete {root} to start over"
            ) from None
        if stored_fp != fp:
            why = (
                f"engine version {m.get('engine')} != {__version__}"
                if m.get("engine") != __version__
                else "the survey definition or scene differs"
            )
            raise RunError(
                f"cannot resume into {out}: the unfinished run in {root} is of another survey "
                f"({why}); use --overwrite to discard it and start again"
            )
        if chunk_points is not None and Tiling.for_grid(survey.shape, chunk_points) != tiling:
            warn(f"resuming with the unfinished run's block size {math.prod(tiling.block):,}")
        for tmp in root.glob("*.tmp"):
            tmp.unlink(missing_ok=True)
        store = BlockStore(root, tiling, names, warn)
        return store, len(store.verify())
    tiling = Tiling.for_grid(survey.shape, chunk_points or BLOCK_POINTS)
    root.mkdir(parents=True, exist_ok=True)
    doc = {
        "fingerprint": fp,
        "engine": __version__,
        "shape": list(tiling.shape),
        "chunk": list(tiling.chunk),
        "block": list(tiling.block),
        "survey_definition": survey.source_text,
    }
    _atomic_write(manifest, lambda f: f.write(json.dumps(doc, indent=1).encode()))
    return BlockStore(root, tiling, names, warn), 0


# --- computing blocks -------------------------------------------------------------------


def _local_blocks(
    spec: dict[str, Any], tiling: Tiling, pending: list[int]
) -> Iterator[tuple[int, dict]]:
    for i in pending:
        yield compute_block(spec, tiling, i)


def _dask_blocks(
    spec: dict[str, Any],
    tiling: Tiling,
    pending: list[int],
    scheduler: str | None,
    workers: int | None,
) -> Iterator[tuple[int, dict]]:
    """Blocks computed on a dask.distributed cluster, yielded as they complete.

    ``workers``: start a LocalCluster of that many single-threaded worker processes, each
    with NUMBA_NUM_THREADS = cores // workers (numba threads x workers <= cores). With
    ``scheduler`` the cluster exists already; start its workers with ``--nthreads 1`` and
    NUMBA_NUM_THREADS set to the cores per worker. At most 2 blocks per worker are in flight.
    """
    try:
        import dask
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise RunError(
            "the dask backend needs dask.distributed: pip install 'conesurvey[dask]'"
        ) from None
    # distributed's Nanny writes its pre-spawn environment (NUMBA_NUM_THREADS, OMP_NUM_THREADS,
    # ...) into this process's os.environ; numba re-reads it and refuses a thread count that
    # differs from its running pool. Restore the environment when the cluster is gone.
    saved_env = dict(os.environ)
    cluster = None
    if scheduler is None:
        n = int(workers or 1)
        threads = max(1, (os.cpu_count() or 1) // n)
        env = {"NUMBA_NUM_THREADS": str(threads), "OMP_NUM_THREADS": str(threads)}
        with dask.config.set({"distributed.nanny.pre-spawn-environ": env}):
            cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                host="127.0.0.1",
            )
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="20s")
        except OSError as exc:
            raise RunError(f"cannot reach the dask scheduler at {scheduler}: {exc}") from None
    try:
        n_workers = max(1, len(client.scheduler_info()["workers"]))
        spec_f = client.scatter(spec, broadcast=True)
        todo = iter(pending)
        futures = as_completed(loop=client.loop)  # not the default client's loop
        for i in todo:
            futures.add(client.submit(compute_block, spec_f, tiling, i, pure=False))
            if futures.count() >= 2 * n_workers:
                break
        for fut in futures:
            i, res = fut.result()
            fut.release()
            nxt = next(todo, None)
            if nxt is not None:
                futures.add(client.submit(compute_block, spec_f, tiling, nxt, pure=False))
            yield i, res
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
        os.environ.clear()
        os.environ.update(saved_env)


# --- merging into netCDF ----------------------------------------------------------------


@dataclass
class RunStats:
    """What a finished run reports: class counts, value ranges, timings, block counts."""

    shape: tuple[int, ...]
    counts: np.ndarray
    ranges: dict[str, tuple[float, float, str]]
    compute_seconds: float = 0.0
    write_seconds: float = 0.0
    compile_seconds: float = 0.0
    blocks_total: int = 0
    blocks_reused: int = 0
    path: Path | None = None

    @property
    def points(self) -> int:
        return math.prod(self.shape)


def _global_attrs(survey: Survey, fp: str, command: str) -> dict[str, Any]:
    import xarray as xr

    from .output import cf_dataset

    base = survey_attrs(
        survey.scene, survey.method, survey.circular_tol, survey.rtol, survey.energy_relative
    )
    ds = cf_dataset(
        xr.Dataset(attrs=base),
        title=survey.title,
        survey_definition=survey.source_text,
        command=command,
        scene=survey.scene,
    )
    attrs = dict(ds.attrs)
    attrs[FINGERPRINT_ATTR] = fp
    return attrs


def _merge(
    store: BlockStore,
    survey: Survey,
    out: Path,
    fp: str,
    command: str,
    overwrite: bool,
    complevel: int = ZLIB_LEVEL,
) -> RunStats:
    """Write every block into ``OUT.tmp`` (netCDF-4, zlib + shuffle, chunk-aligned), then
    rename it to ``out``; returns the statistics gathered on the way."""
    import netCDF4

    from .kernels.geometry import CLASS_NAMES

    tiling = store.tiling
    tmp = out.with_name(out.name + ".tmp")
    tmp.unlink(missing_ok=True)
    counts = np.zeros(len(CLASS_NAMES), np.int64)
    lo: dict[str, float] = {}
    hi: dict[str, float] = {}
    try:
        with netCDF4.Dataset(tmp, "w", format="NETCDF4") as nc:
            nc.setncatts(_global_attrs(survey, fp, command))
            for d in DIMS:
                values = np.asarray(getattr(survey, d), np.float64)
                nc.createDimension(d, values.size)
                v = nc.createVariable(d, "f8", (d,), fill_value=False)
                v.setncatts(axis_attrs(d, survey.energy_relative))
                v[:] = values
            variables = {}
            for name, dt in store.names.items():
                fill = False if dt.kind in "iu" else np.nan
                v = nc.createVariable(
                    name,
                    dt,
                    DIMS,
                    zlib=complevel > 0,
                    complevel=max(complevel, 1),
                    shuffle=complevel > 0,
                    chunksizes=tiling.chunk,
                    fill_value=fill,
                )
                attrs = variable_attrs(name)
                if name == "orbit_class":
                    attrs["flag_values"] = np.asarray(attrs["flag_values"], np.int8)
                v.setncatts(attrs)
                variables[name] = v
            for i in range(tiling.nblocks):
                block = store.load(i)
                if block is None:
                    raise RunError(f"block {i} vanished or is corrupt during the merge; rerun")
                sl = tiling.slices(i)
                for name, arr in block.items():
                    variables[name][sl] = arr
                    if name == "orbit_class":
                        counts += np.bincount(arr.ravel(), minlength=len(CLASS_NAMES))
                    elif arr.dtype.kind == "f":
                        fin = arr[np.isfinite(arr)]
                        if fin.size:
                            lo[name] = min(lo.get(name, np.inf), float(fin.min()))
                            hi[name] = max(hi.get(name, -np.inf), float(fin.max()))
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        if overwrite:
            os.replace(tmp, out)
        else:
            try:
                os.link(tmp, out)  # atomic, refuses to clobber a file that appeared meanwhile
            except FileExistsError:
                raise RunError(f"output file exists: {out} (use --overwrite)") from None
            except OSError:
                os.replace(tmp, out)
            else:
                tmp.unlink()
        _fsync_dir(out.parent)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    units = {n: variable_attrs(n).get("units", "") for n in lo}
    ranges = {n: (lo[n], hi[n], units[n]) for n in lo}
    return RunStats(tiling.shape, counts, ranges, path=out)


# --- the run ----------------------------------------------------------------------------


def read_info(path: Path) -> dict[str, Any]:
    """Provenance of a result file, or of an unfinished run's parts directory."""
    import netCDF4

    parts = path.with_name(path.name + ".parts")
    info: dict[str, Any] = {"path": str(path)}
    if path.exists():
        try:
            with netCDF4.Dataset(path) as nc:
                info["attrs"] = {k: nc.getncattr(k) for k in nc.ncattrs()}
                info["dims"] = {d: len(nc.dimensions[d]) for d in nc.dimensions}
                if "orbit_class" in nc.variables:
                    from .kernels.geometry import CLASS_NAMES

                    v = nc.variables["orbit_class"]
                    counts = np.zeros(len(CLASS_NAMES), np.int64)
                    for sl in _slabs(v.shape, v.chunking()):
                        counts += np.bincount(np.asarray(v[sl]).ravel(), minlength=len(CLASS_NAMES))
                    info["counts"] = dict(zip(CLASS_NAMES, counts.tolist(), strict=True))
                info["complete"] = FINGERPRINT_ATTR in info["attrs"]
        except OSError as exc:
            raise RunError(f"{path} is not a readable netCDF file ({exc})") from None
    elif parts.is_dir():
        m = json.loads((parts / MANIFEST).read_text())
        tiling = Tiling(tuple(m["shape"]), tuple(m["chunk"]), tuple(m["block"]))
        store = BlockStore(parts, tiling, {})
        info.update(
            complete=False,
            attrs={"survey_definition": m.get("survey_definition", ""), "engine": m["engine"]},
            dims=dict(zip(DIMS, tiling.shape, strict=True)),
            blocks_done=len(store.done()),
            blocks_total=tiling.nblocks,
        )
    else:
        raise RunError(f"no such file: {path}")
    return info


def _slabs(shape: tuple[int, ...], chunking: Any) -> Iterable[tuple[slice, ...]]:
    """Hyperslabs one storage chunk along the first axis at a time (bounded memory)."""
    step = chunking[0] if isinstance(chunking, list | tuple) else max(1, shape[0])
    for s in range(0, shape[0], step):
        yield (slice(s, min(shape[0], s + step)),) + tuple(slice(0, n) for n in shape[1:])


def run_survey(
    survey: Survey,
    out: str | os.PathLike[str],
    *,
    chunk_points: int | None = None,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    command: str = "conesurvey",
    warn: Callable[[str], None] | None = None,
    on_block: Callable[[int], None] | None = None,
    complevel: int = ZLIB_LEVEL,
) -> RunStats:
    """Run ``survey`` into the netCDF file ``out``, streaming blocks and resuming a killed run.

    ``chunk_points``: points per block (default :data:`engine.grid.BLOCK_POINTS`).
    ``scheduler`` / ``workers``: run blocks on a dask cluster (an address, or a LocalCluster
    of that many workers). Raises :class:`RunError` when the run cannot start or resume.
    ``on_block(index)`` is called after each block is safely stored (for tests and hooks).
    ``complevel``: zlib level of the netCDF variables, 0 = uncompressed (HDF5 compresses on one
    thread: level 1 writes ~36 MB/s of results here, uncompressed is disk-bound).
    """
    if not (isinstance(complevel, int) and 0 <= complevel <= 9):
        raise RunError(f"complevel must be an integer 0..9; got {complevel!r}")
    out = Path(out)
    warn = warn or (lambda msg: print(f"conesurvey: warning: {msg}", file=sys.stderr))
    fp = fingerprint(survey)
    parts = out.with_name(out.name + ".parts")
    if out.exists() and not overwrite:
        try:
            info = read_info(out)
        except RunError:
            info = {}
        if info.get("attrs", {}).get(FINGERPRINT_ATTR) == fp:
            raise AlreadyComplete(f"{out} already holds this survey, complete; nothing to do")
        raise RunError(f"output file exists: {out} (use --overwrite to replace it)")
    if overwrite and parts.is_dir():
        shutil.rmtree(parts)
    store, reused = _open_store(out, survey, fp, chunk_points, warn)
    tiling = store.tiling
    done = store.verify() if reused else set()
    pending = [i for i in range(tiling.nblocks) if i not in done]
    points_done = sum(tiling.points(i) for i in done)
    if progress is not None:
        progress(points_done, tiling.size)
    spec = block_spec(survey)
    # Compile (or load from numba's cache) before timing, on one point of the grid; this also
    # warms the cache before dask workers start (concurrent first compiles race, numba#4807).
    tc = time.perf_counter()
    if pending:
        evaluate_block(spec, tuple(slice(0, 1) for _ in DIMS))
    t0 = time.perf_counter()
    if scheduler is not None or workers is not None:
        blocks = _dask_blocks(spec, tiling, pending, scheduler, workers)
    else:
        blocks = _local_blocks(spec, tiling, pending)
    for i, res in blocks:
        store.save(i, res)
        points_done += tiling.points(i)
        if progress is not None:
            progress(points_done, tiling.size)
        if on_block is not None:
            on_block(i)
    t1 = time.perf_counter()
    stats = _merge(store, survey, out, fp, command, overwrite, complevel)
    shutil.rmtree(store.root, ignore_errors=True)
    stats.compute_seconds = t1 - t0
    stats.compile_seconds = t0 - tc
    stats.write_seconds = time.perf_counter() - t1
    stats.blocks_total = tiling.nblocks
    stats.blocks_reused = len(done)
    return stats

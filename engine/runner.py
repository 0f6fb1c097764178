"""Streaming, resumable survey runs: blocks to disk as they finish, one netCDF file at the end.

The order of a run (the README, "Large surveys: streaming, resume, dask", tells the user's
side):

1. refuse an existing output, unless it already holds this very survey (nothing to do) or
   ``overwrite`` is given (then an unfinished run behind it is discarded too);
2. open the block store ``OUT.parts`` (:mod:`engine.io.blocks`): a new one, or the unfinished
   run's if its fingerprint matches (stale ``.tmp`` files deleted, every stored block
   verified, a corrupt one reported and recomputed);
3. compile the kernels (or load them from numba's cache) on one point;
4. compute the missing blocks (:mod:`engine.backends`: here or on dask) and store each one as
   it arrives; a run killed at any moment (SIGKILL included) loses at most the blocks in
   flight;
5. merge the blocks into ``OUT.tmp``, fsync, rename to ``OUT`` (:func:`engine.io.netcdf.merge`);
   only then remove the parts. Peak memory is a few blocks, whatever the grid size.
"""

from __future__ import annotations

import math
import os
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .backends import BackendError, block_source, block_spec
from .evaluation import evaluate_block
from .grid import BLOCK_POINTS, Tiling
from .io import OutputError, netcdf
from .io.blocks import (
    FINGERPRINT_ATTR,
    MANIFEST,
    BlockStore,
    Manifest,
    Summary,
    fingerprint,
    parts_dir,
    read_manifest,
    survey_variables,
    write_manifest,
)
from .schema import DIMS

if TYPE_CHECKING:
    from .surveyfile import Survey

__all__ = ["AlreadyComplete", "RunError", "RunStats", "run_survey"]


class RunError(Exception):
    """A run that cannot start or resume (the message says why); CLI exit status 2."""


class AlreadyComplete(RunError):
    """The output already holds this very survey, finished: nothing to compute."""


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


def _refuse_existing(out: Path, fp: str) -> None:
    """RunError for an existing output (AlreadyComplete if it holds this survey, finished)."""
    try:
        info = netcdf.read_info(out)
    except OutputError:
        info = {}
    if info.get("attrs", {}).get(FINGERPRINT_ATTR) == fp:
        raise AlreadyComplete(f"{out} already holds this survey, complete; nothing to do")
    raise RunError(f"output file exists: {out} (use --overwrite to replace it)")


def _open_store(
    out: Path, survey: Survey, block_points: int | None, warn: Callable[[str], None]
) -> tuple[BlockStore, set[int]]:
    """Create ``OUT.parts``, or reopen the unfinished run's; returns the store and the indices
    of the verified blocks it holds."""
    root = parts_dir(out)
    names = survey_variables(survey)
    current = Manifest.new(survey, Tiling.for_grid(survey.shape, block_points or BLOCK_POINTS))
    if not (root / MANIFEST).exists():
        root.mkdir(parents=True, exist_ok=True)
        write_manifest(root, current)
        return BlockStore(root, current.tiling, names, warn), set()
    try:
        stored = read_manifest(root)
    except OutputError as exc:
        raise RunError(f"cannot resume: {exc}; delete {root} to start over") from None
    if stored.fingerprint != current.fingerprint:
        why = (
            f"engine version {stored.engine} != {current.engine}"
            if stored.engine != current.engine
            else "the survey definition or scene differs"
        )
        raise RunError(
            f"cannot resume into {out}: the unfinished run in {root} is of another survey "
            f"({why}); use --overwrite to discard it and start again"
        )
    if block_points is not None and stored.tiling != current.tiling:
        warn(f"resuming with the unfinished run's block size {math.prod(stored.tiling.block):,}")
    store = BlockStore(root, stored.tiling, names, warn)
    store.remove_stale_tmp()
    return store, store.verify()


def _merge(
    store: BlockStore,
    survey: Survey,
    out: Path,
    fp: str,
    command: str,
    overwrite: bool,
    complevel: int,
) -> Summary:
    """The blocks merged into the output file (RunError if it appeared meanwhile or a block
    is gone)."""
    try:
        return netcdf.merge(
            store,
            survey,
            out,
            fingerprint=fp,
            command=command,
            overwrite=overwrite,
            complevel=complevel,
        )
    except FileExistsError:
        raise RunError(f"output file exists: {out} (use --overwrite)") from None
    except OutputError as exc:
        raise RunError(str(exc)) from None


def run_survey(
    survey: Survey,
    out: str | os.PathLike[str],
    *,
    block_points: int | None = None,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    command: str = "conesurvey",
    warn: Callable[[str], None] | None = None,
    on_block: Callable[[int], None] | None = None,
    complevel: int = netcdf.ZLIB_LEVEL,
) -> RunStats:
    """Run ``survey`` into the netCDF file ``out``, streaming blocks and resuming a killed run.

    ``block_points``: points per block (default :data:`engine.grid.BLOCK_POINTS`; a resumed
    run keeps its own). ``scheduler`` / ``workers``: run blocks on a dask cluster (an address,
    or a LocalCluster of that many workers). Raises :class:`RunError` when the run cannot start
    or resume. ``on_block(index)`` is called after each block is safely stored (for tests and
    hooks). ``complevel``: zlib level of the netCDF variables, 0 = uncompressed (HDF5
    compresses on one thread: level 1 writes ~36 MB/s of results here, uncompressed is
    disk-bound).
    """
    if not (isinstance(complevel, int) and 0 <= complevel <= 9):
        raise RunError(f"complevel must be an integer 0..9; got {complevel!r}")
    out = Path(out)
    warn = warn or (lambda msg: print(f"conesurvey: warning: {msg}", file=sys.stderr))
    fp = fingerprint(survey)
    if out.exists() and not overwrite:
        _refuse_existing(out, fp)
    if overwrite and parts_dir(out).is_dir():
        shutil.rmtree(parts_dir(out))
    store, done = _open_store(out, survey, block_points, warn)
    tiling = store.tiling
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
    try:
        for i, res in block_source(spec, tiling, pending, scheduler=scheduler, workers=workers):
            store.save(i, res)
            points_done += tiling.points(i)
            if progress is not None:
                progress(points_done, tiling.size)
            if on_block is not None:
                on_block(i)
    except BackendError as exc:
        raise RunError(str(exc)) from None
    t1 = time.perf_counter()
    summary = _merge(store, survey, out, fp, command, overwrite, complevel)
    shutil.rmtree(store.root, ignore_errors=True)
    return RunStats(
        tiling.shape,
        summary.counts,
        summary.ranges,
        compute_seconds=t1 - t0,
        write_seconds=time.perf_counter() - t1,
        compile_seconds=t0 - tc,
        blocks_total=tiling.nblocks,
        blocks_reused=len(done),
        path=out,
    )

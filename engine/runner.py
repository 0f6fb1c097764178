"""Streaming, resumable survey runs: blocks to disk as they finish, one netCDF file at the end.

The order of a run (the README, "Large surveys: streaming, resume, dask" and "Guarantees",
tells the user's side). Every refusal comes before anything is written:

1. take the output's lock (:mod:`engine.io.lock`), held until the end: a second run of the
   same output is refused, naming the holder;
2. look, without writing: an existing output is refused unless it already holds this very
   survey (nothing to do) or ``overwrite`` is given; an unfinished run ``OUT.parts`` is
   resumed if its manifest is valid and of this survey (every stored block is hashed against
   the journal), refused otherwise; leftovers of a finished run (or of a run killed as it
   started) are recognised as debris;
3. check the disk: the blocks still to compute plus the output being merged beside them must
   fit; compile the kernels (or load them from numba's cache) on one point, which also lets
   the engine refuse the survey; reach the dask cluster if one is asked for;
4. write: remove debris, the discarded run or the bad blocks; create the store; compute the
   missing blocks (:mod:`engine.backends`) and commit each one as it arrives; a run killed at
   any moment (SIGKILL included) loses at most the blocks in flight;
5. meanwhile, merge the blocks in order into a temporary file inside the store, each block as
   soon as it and every block before it are stored (:func:`engine.io.netcdf.merge`, on a writer
   thread: :mod:`engine.io.feed`); once the last is written, fsync and rename to ``OUT``; only
   then remove the store (manifest first).

A failure after step 3 (a full disk, a lost dask cluster, a block that changed on disk) raises
:class:`RunFailed`: the blocks stored so far are kept and the same call resumes.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ._compiling import quiet as quiet_compiles
from .backends import BackendError, check_address, open_backend
from .evaluation import evaluate_block
from .grid import Tiling
from .io import OutputError
from .io.atomic import not_regular, output_name_problem
from .io.blocks import BlockStore, Scan, check_parts_dir, remove_store
from .io.codecs import level
from .io.leftovers import is_debris
from .io.lock import Locked, LockError, OutputLock, describe_holder
from .io.manifest import fingerprint, parts_dir, read_manifest, survey_families
from .io.space import free_bytes
from .io.summary import Summary
from .io.zarrstore import RunStore
from .plan import RunPlan, plan_from_survey
from .precision import PrecisionError
from .progress import format_bytes
from .runstats import AlreadyComplete, RunError, RunFailed, RunStats

if TYPE_CHECKING:
    from .surveyfile import Survey

__all__ = [
    "AlreadyComplete",
    "RunError",
    "RunFailed",
    "RunStats",
    "run_survey",
]


_Block = tuple[int, dict[str, np.ndarray]]


@dataclass
class _Store:
    """What step 2 found: the store to resume (with its scan), or a store to remove first."""

    fp: str
    remove_first: str = ""  # why the existing store is removed ("" = keep it)
    store: BlockStore | None = None
    scan: Scan = field(default_factory=Scan)
    tiling: Tiling | None = None


def _inspect(
    out: Path, run: RunPlan, overwrite: bool, block_points: int | None, warn: Callable
) -> _Store:
    """Step 2 (reads only): RunError or AlreadyComplete, else what to do with the store."""
    fmt = run.output.format
    plan = _Store(fingerprint(run))
    root = parts_dir(out)
    try:
        has_store = check_parts_dir(root)
    except OutputError as exc:
        raise RunError(str(exc)) from None
    kind = not_regular(out, follow_links=False)
    expected = ("a directory",) if fmt.directory else ()  # a Zarr store is one
    if kind not in (None, "a symbolic link", *expected):
        raise RunError(f"output path {out} is {kind}; give a file name")
    if os.path.lexists(out) and not overwrite:
        finished = fmt.read_fingerprint(out)
        if finished != plan.fp:
            raise RunError(f"output file exists: {out} (use --overwrite to replace it)")
        if has_store and is_debris(root, finished):
            remove_store(root)  # not a refusal: the run has nothing to do but tidy up
            warn(f"removed {root}, left behind by the run that finished {out}")
        raise AlreadyComplete(f"{out} already holds this survey, complete; nothing to do")
    if not has_store:
        return plan
    if is_debris(root, None):
        plan.remove_first = "removed: it has no manifest (left by a killed run)"
        return plan
    try:  # with --overwrite too: a killed run --overwrite resumes when it is run again
        plan.store = fmt.open_run(root, warn)
        why, problem = read_manifest(root).mismatch(run), None
    except OutputError as exc:
        why, problem = None, exc
    if overwrite and (problem or why):
        plan.store, plan.remove_first = None, "discarded (--overwrite)"
        return plan
    if problem:
        raise RunError(
            f"cannot resume: {problem}; use --overwrite to discard {root} and start again"
        )
    if why is not None:
        raise RunError(
            f"cannot resume into {out}: the unfinished run in {root} is of another survey "
            f"({why}); use --overwrite to discard it and start again"
        )
    stored = plan.store.tiling
    if block_points is not None and stored != Tiling.for_grid(run.shape, block_points):
        warn(f"resuming with the unfinished run's block size {math.prod(stored.block):,}")
    if (expect := getattr(plan.store, "expect", None)) is not None:
        expect(run)  # what the store must hold besides its blocks (Zarr: its metadata)
    plan.scan = plan.store.scan()
    return plan


def _check_space(out: Path, run: RunPlan, tiling: Tiling, pending: list[int]) -> None:
    """RunError unless the blocks still to compute and the output merged beside all of them
    fit on the output's file system."""
    blocks, merged = run.output.format.run_bytes(run, tiling, pending, out.parent)
    free = shutil.disk_usage(out.parent).free
    if blocks + merged > free:
        raise RunError(
            f"the survey needs up to {format_bytes(blocks + merged)} of disk "
            f"({format_bytes(blocks)} for the blocks still to compute + "
            f"{format_bytes(merged)} for the output merged beside them) but {out.parent} "
            f"has {format_bytes(free)} free ({run.size:,} points); use --force to run anyway"
        )


def _take_lock(out: Path, command: str) -> OutputLock:
    try:
        return OutputLock.acquire(out, command)
    except Locked as exc:
        raise RunError(
            f"another run is writing {out} ({describe_holder(exc.holder)}); "
            "wait for it to finish (its lock is released when it exits)"
        ) from None
    except LockError as exc:
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
    compression: str | None = None,
    complevel: int | None = None,
    check_space: bool = True,
    output_format: str | None = None,
) -> RunStats:
    """Run ``survey`` into the netCDF file ``out``, streaming blocks and resuming a killed run.

    ``block_points``: points per block (default :data:`engine.grid.BLOCK_POINTS`; a resumed
    run keeps its own). ``scheduler`` / ``workers``: run blocks on a dask cluster (an address,
    or a LocalCluster of that many workers). ``check_space``: refuse a run whose blocks and
    output do not fit on the disk. Raises :class:`RunError` when the run cannot start or
    resume (nothing written), :class:`RunFailed` when it stopped after writing (resumable).
    ``on_block(index)`` is called after each block is safely stored (for tests and hooks).
    ``compression`` / ``complevel``: how the output's variables are compressed
    (:mod:`engine.io.codecs`; docs/output.md); None: the format's default (netCDF: zlib;
    Zarr: blosc_lz4). ``output_format``: a format's name (:mod:`engine.io.formats`; None:
    the format of ``out``'s name).
    """
    try:  # every input checked once (engine.checks), before anything else
        run = plan_from_survey(
            survey, out, block_points=block_points, compression=compression,
            complevel=complevel, output_format=output_format,
        )  # fmt: skip
    except ValueError as exc:
        raise RunError(str(exc)) from None
    fmt, compression, complevel = run.output.format, run.output.compression, run.output.complevel
    if scheduler is not None:
        try:
            check_address(scheduler)
        except ValueError as exc:
            raise RunError(str(exc)) from None
    out = Path(out)
    if why := output_name_problem(out):
        raise RunError(why)
    warn = warn or (lambda msg: print(f"conesurvey: warning: {msg}", file=sys.stderr))
    if not out.parent.is_dir():
        raise RunError(f"output directory does not exist: {out.parent}")
    if why := fmt.unavailable():
        raise RunError(why)  # an optional dependency: refused before anything is written
    stores: list[Any] = []  # whose held files are let go when the run ends, however
    with _take_lock(out, command), _ending(stores):
        asked = None if block_points is None else run.output.block_points
        plan = _inspect(out, run, overwrite, asked, warn)
        stores.append(plan.store)
        tiling = (
            plan.store.tiling
            if plan.store is not None
            else Tiling.for_grid(run.shape, run.output.block_points)
        )
        done = plan.scan.good
        pending = [i for i in range(tiling.nblocks) if i not in done]
        if check_space:
            _check_space(out, run, tiling, pending)
        if done and (resumed := getattr(progress, "resumed", None)) is not None:  # said first
            resumed(len(done), tiling.nblocks, sum(map(tiling.points, done)), tiling.size)
        # Compile (or load) on one point before anything is written: the engine may still
        # refuse the survey; dask workers then find the cache warm (numba#4807). OpenMP's
        # threads sleep at a region's end, off the writer's cores (7 % less CPU on 2 cores).
        tc = time.perf_counter()
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
        compiling = getattr(progress, "compiling", quiet_compiles)  # `run -q`: no notice
        with compiling():  # a first run's compile is announced, not a silent wait
            evaluate_block(run, tuple(slice(0, 1) for _ in run.dims))
        if run.output.precision == "single":  # r_circ, V_min: checked before anything is written
            survey_families(run)
        t0 = time.perf_counter()
        try:
            backend = open_backend(scheduler, workers)
        except BackendError as exc:
            raise RunFailed(f"{exc}; nothing was written") from None
        try:
            store = _prepare(out, run, plan, tiling, warn)
            stores.append(store)
            once = dict(fingerprint=plan.fp, command=command, overwrite=overwrite)
            blocks = _compute(store, backend, run, pending, len(done), progress, on_block)
            ended: list[float] = []  # when the last block was stored
            incoming = _timed(blocks, ended)
            summary = _merge(
                store, run, out, **once, compression=compression, complevel=complevel,
                pending=pending, incoming=incoming, warn=warn,
            )  # fmt: skip
            t1 = ended[0] if ended else t0
        except ValueError as exc:  # from what was written (a damaged store), not the survey's
            why = f"the run stopped after it began to write ({exc})"
            raise exc if isinstance(exc, PrecisionError) else RunFailed(why) from None
        finally:
            backend.close()
        try:
            if kept := store.remove():
                warn(f"left {store.root} with the files you put there: {', '.join(kept[:5])}")
        except OSError as exc:
            warn(f"could not remove {store.root} ({exc.strerror}); the next run removes it")
    return RunStats(
        tiling.shape,
        summary.counts,
        summary.ranges,
        run.dims,
        summary.flags,
        compute_seconds=t1 - t0,
        write_seconds=time.perf_counter() - t1,
        compile_seconds=t0 - tc,
        blocks_total=tiling.nblocks,
        blocks_reused=len(done),
        path=out,
    )


@contextlib.contextmanager
def _ending(stores: list[Any]) -> Iterator[None]:
    """However the run ends, the files the ``stores`` hold are let go (:mod:`engine.io.hold`).
    A value the survey's precision cannot hold is the survey's refusal: the run's store is
    removed (the same command would meet it again; another precision resumes nothing)."""
    try:
        yield
    except PrecisionError as exc:
        if (store := next((s for s in reversed(stores) if s is not None), None)) is None:
            raise RunError(str(exc)) from None
        store.remove()
        raise RunError(f"{exc}; the blocks computed so far were removed") from None
    finally:
        for store in stores:
            if (release := getattr(store, "release", None)) is not None:
                release()


def _prepare(
    out: Path, run: RunPlan, plan: _Store, tiling: Tiling, warn: Callable
) -> BlockStore | RunStore:
    """Step 4's first writes: remove what goes, create or tidy the store."""
    root = parts_dir(out)
    try:
        if plan.remove_first:
            remove_store(root)
            warn(f"{root} {plan.remove_first}")
        if plan.store is not None:
            plan.store.discard(plan.scan)
            return plan.store
        complevel = level(run.output.compression, run.output.complevel)
        return run.output.format.create(root, run, tiling, complevel, warn)
    except OSError as exc:
        raise RunFailed(_cannot_write(exc, root)) from None


def _compute(
    store: BlockStore | RunStore,
    backend: object,
    run: RunPlan,
    pending: list[int],
    reused: int,
    progress: Callable[[int, int], None] | None,
    on_block: Callable[[int], None] | None,
) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
    """Compute and commit the pending blocks, yielding each (as stored) once it is committed
    (RunFailed if a block cannot be stored or the backend fails)."""
    tiling = store.tiling
    points = tiling.size - sum(tiling.points(i) for i in pending)
    if progress is not None:
        progress(points, tiling.size)
    stored = reused  # blocks durable (journaled) so far

    def landed(index: int) -> None:  # a block file's store: on the thread that made it durable
        nonlocal stored
        stored += 1
        if on_block is not None:
            on_block(index)

    behind = getattr(store, "behind", None)  # the block files: made durable on a thread
    durably = behind(landed) if behind is not None else contextlib.nullcontext()
    try:
        writer = getattr(store, "writer", None)  # Zarr: blocks write their own chunks
        with durably:
            for i, res in backend.blocks(run, tiling, pending, writer):  # type: ignore[attr-defined]
                try:
                    clean = store.commit(i, res)
                except OSError as exc:
                    raise RunFailed(
                        f"{_cannot_write(exc, store.path(i))}; {stored} of {tiling.nblocks} "
                        "blocks are stored"
                    ) from None
                points += tiling.points(i)
                if progress is not None:
                    progress(points, tiling.size)
                if behind is None:
                    landed(i)
                yield i, clean
    except OSError as exc:  # the last blocks' files, made durable as the run ends
        raise RunFailed(
            f"{_cannot_write(exc, store.root)}; {stored} of {tiling.nblocks} blocks are stored"
        ) from None
    except (BackendError, OutputError) as exc:  # OutputError: a writer's (Zarr)
        raise RunFailed(f"{exc}; {stored} of {tiling.nblocks} blocks are stored") from None


def _timed(blocks: Iterator[_Block], ended: list[float]) -> Iterator[_Block]:
    """``blocks``, noting in ``ended`` when the last one has come."""
    yield from blocks
    ended.append(time.perf_counter())


def _cannot_write(exc: OSError, where: Path) -> str:
    return f"cannot write {exc.filename or where}: {exc.strerror or exc}"


def _merge(store: BlockStore | RunStore, run: RunPlan, out: Path, **options: Any) -> Summary:
    """The blocks merged into the output by its format's ``commit`` (netCDF: while they are
    computed, :func:`engine.io.netcdf.merge`; Zarr: the final commit,
    :func:`engine.io.zarr.merge`):
    RunError if the output appeared meanwhile, RunFailed if it cannot be written or a block
    changed, and what the compute raised."""
    try:
        return run.output.format.commit(store, run, out, **options)
    except FileExistsError:
        raise RunError(
            f"output file exists: {out} (created while this run computed; use --overwrite)"
        ) from None
    except OSError as exc:
        free = format_bytes(free_bytes(out.parent))
        raise RunFailed(f"{_cannot_write(exc, out)} ({free} free)") from None
    except OutputError as exc:
        free = format_bytes(free_bytes(out.parent))
        raise RunFailed(f"{exc} ({free} free on {out.parent})") from None

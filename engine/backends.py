"""Where the blocks of a streamed run are computed: here, or on a dask.distributed cluster.

A block source is an iterator of ``(index, results)`` over the pending block indices, in any
order; the caller (:func:`engine.runner.run_survey`) stays the only writer. Locally a block runs
the numba kernels with ``prange`` inside it; on dask each worker computes whole blocks. Both
call :func:`compute_block`, so the results are bit-identical (README, "Large surveys:
streaming, resume, dask").
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from .evaluation import evaluate_block
from .grid import Tiling
from .schema import DIMS

if TYPE_CHECKING:
    from .surveyfile import Survey

__all__ = [
    "BackendError",
    "block_source",
    "block_spec",
    "compute_block",
    "dask_blocks",
    "local_blocks",
]

Blocks = Iterator[tuple[int, dict[str, np.ndarray]]]


class BackendError(Exception):
    """A block source that cannot start (dask missing, scheduler unreachable)."""


def block_spec(survey: Survey) -> dict[str, Any]:
    """What :func:`engine.evaluation.evaluate_block` needs (picklable, for dask workers too)."""
    spec: dict[str, Any] = {d: np.array(getattr(survey, d)) for d in DIMS}
    spec.update(
        scene=survey.scene,
        method=survey.method,
        energy_relative=survey.energy_relative,
        circular_tol=survey.circular_tol,
        rtol=survey.rtol,
    )
    return spec


def compute_block(
    spec: dict[str, Any], tiling: Tiling, index: int
) -> tuple[int, dict[str, np.ndarray]]:
    """Results of block ``index`` (module-level, so dask can ship it to workers)."""
    return index, evaluate_block(spec, tiling.slices(index))


def block_source(
    spec: dict[str, Any],
    tiling: Tiling,
    pending: list[int],
    *,
    scheduler: str | None = None,
    workers: int | None = None,
) -> Blocks:
    """The pending blocks computed on dask (with ``scheduler`` or ``workers``), else here."""
    if scheduler is not None or workers is not None:
        return dask_blocks(spec, tiling, pending, scheduler, workers)
    return local_blocks(spec, tiling, pending)


def local_blocks(spec: dict[str, Any], tiling: Tiling, pending: list[int]) -> Blocks:
    """The pending blocks computed one after the other in this process."""
    for i in pending:
        yield compute_block(spec, tiling, i)


def dask_blocks(
    spec: dict[str, Any],
    tiling: Tiling,
    pending: list[int],
    scheduler: str | None,
    workers: int | None,
) -> Blocks:
    """Blocks computed on a dask.distributed cluster, yielded as they complete.

    ``workers``: start a LocalCluster of that many single-threaded worker processes, each
    with NUMBA_NUM_THREADS = cores // workers (numba threads x workers <= cores). With
    ``scheduler`` the cluster exists already; start its workers with ``--nthreads 1`` and
    NUMBA_NUM_THREADS set to the cores per worker. At most 2 blocks per worker are in flight.
    BackendError if dask.distributed is missing or the scheduler cannot be reached.
    """
    try:  # optional dependency; lazy also because dask.distributed takes ~0.28 s to import
        import dask
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise BackendError(
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
            raise BackendError(f"cannot reach the dask scheduler at {scheduler}: {exc}") from None
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

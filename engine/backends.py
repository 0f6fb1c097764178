"""Where the blocks of a streamed run are computed: here, or on a dask.distributed cluster.

A backend is opened before the run writes anything (:func:`open_backend`: a dask scheduler is
reached within a few seconds, or the run stops with nothing written) and then yields
``(index, results)`` over the pending block indices, in any order; the caller
(:func:`engine.runner.run_survey`) stays the only writer. Locally a block runs the numba kernels
with ``prange`` inside it; on dask each worker computes whole blocks. Both call
:func:`compute_block`, so the results are bit-identical (README, "Large surveys: streaming,
resume, dask").

A lost cluster never shows a traceback: a scheduler that goes away, a task that killed its
workers (dask's ``KilledWorker``) or a cluster left without workers for
``conesurvey.no-workers-timeout`` seconds (dask config; default 60, environment variable
``DASK_CONESURVEY__NO_WORKERS_TIMEOUT``) raise :class:`BackendError`; the blocks stored so far
are kept. A worker killed while others remain only costs its blocks in flight: the survey
description travels as a task (not as scattered data, which dies with its worker), so the
scheduler can recompute it anywhere. A block is computed from the run plan
(:class:`engine.plan.RunPlan`), which travels whole.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from .blockbuffers import Buffers
from .errortext import install_hint
from .evaluation import evaluate_block
from .grid import Tiling
from .pipeline import computed_ahead, written_behind
from .precision import at, stored

if TYPE_CHECKING:
    from .plan import RunPlan

__all__ = [
    "BackendError",
    "DaskBackend",
    "LocalBackend",
    "check_address",
    "compute_block",
    "open_backend",
    "write_block",
]

Blocks = Iterator[tuple[int, dict[str, np.ndarray]]]
#: Seconds to reach a scheduler (dask config ``conesurvey.connect-timeout``).
CONNECT_TIMEOUT = 5.0
#: Seconds a cluster may have no workers before the run gives up
#: (dask config ``conesurvey.no-workers-timeout``).
NO_WORKERS_TIMEOUT = 60.0
#: Seconds between checks of the cluster while no block completes.
POLL = 1.0
_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx", "inproc")


class BackendError(Exception):
    """A block source that cannot start or that failed (dask missing, scheduler unreachable or
    lost, no workers left); the message is one line."""


def compute_block(
    plan: RunPlan, tiling: Tiling, index: int, out: dict[str, np.ndarray] | None = None
) -> tuple[int, dict[str, np.ndarray]]:
    """Results of block ``index`` (module-level, so dask can ship it to workers), of the
    plan's dtypes (float32 where its precision is single). ``out``: buffers to compute into
    (reused from block to block, no new memory to fault in): for each variable of
    :func:`engine.evaluation.block_variables`, a C-contiguous 1-D array of its dtype with room
    for the block's points; the results are views of their first ones, in the block's shape."""
    slices = tiling.slices(index)
    if out is not None:
        shape = tuple(s.stop - s.start for s in slices)
        size = tiling.points(index)
        views = {n: a[:size].reshape(shape) if a.ndim == 1 and a.size >= size else a
                 for n, a in out.items()}  # fmt: skip
        return index, evaluate_block(plan, slices, out=views)
    results = evaluate_block(plan, slices)
    where = at(tuple(plan.dims), [a[s] for a, s in zip(plan.axes, slices, strict=True)])
    dtypes = plan.variables
    return index, {n: stored(n, a, dtypes.get(n, a.dtype), where=where) for n, a in results.items()}


def write_block(
    plan: RunPlan, tiling: Tiling, index: int, writer: Any
) -> tuple[int, dict[str, Any]]:
    """Compute block ``index`` and write it with ``writer`` where it was computed (a dask
    worker writes its own chunks, :class:`engine.io.zarrstore.ChunkWriter`); only the
    writer's receipt is returned."""
    i, results = compute_block(plan, tiling, index)
    return i, writer.write(i, tiling.slices(i), results)


def _same(x: Any) -> Any:
    """The identity (a task whose result is the survey description)."""
    return x


def check_address(address: str) -> str:
    """A dask scheduler address (``tcp://host:8786``; a bare ``host:port`` means tcp) as
    distributed takes it; ValueError saying what is wrong."""
    text = address.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if scheme not in _SCHEMES:
        raise ValueError(
            f"--scheduler {address!r}: unknown protocol {scheme!r} (one of {', '.join(_SCHEMES)})"
        )
    if scheme == "inproc":
        if not _inproc_listening(rest):
            raise ValueError(
                f"--scheduler {address!r}: no dask scheduler listens at this in-process "
                "address (inproc:// reaches only a scheduler started in this very process; "
                "give tcp://host:port)"
            )
        return f"{scheme}://{rest}"
    host, colon, port = rest.rpartition(":")
    if not colon or not host.strip("[]") or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"--scheduler {address!r} is not an address like tcp://host:8786")
    return f"{scheme}://{rest}"


def _inproc_listening(rest: str) -> bool:
    """Whether a scheduler of this process listens at ``inproc://rest``."""
    try:
        from distributed.comm.inproc import global_manager

        return global_manager.get_listener_for(rest) is not None
    except (ImportError, ValueError):
        return False


class LocalBackend:
    """The pending blocks computed one after the other in this process, :data:`AHEAD` blocks
    ahead of the caller on a thread of their own (the numba kernels on every core; they
    release the GIL), into reused buffers (:class:`engine.blockbuffers.Buffers`), while the
    caller stores and writes the last; with a ``writer`` (the Zarr store's), each block's
    chunks are encoded and written on another thread meanwhile (:mod:`engine.pipeline`)."""

    def blocks(
        self, plan: RunPlan, tiling: Tiling, pending: list[int], writer: Any = None
    ) -> Blocks:
        computed = computed_ahead(
            lambda i, out: compute_block(plan, tiling, i, out), pending,
            lambda: Buffers(plan, tiling),
        )  # fmt: skip
        if writer is None:
            yield from computed
        else:
            yield from written_behind(computed, lambda i, r: writer.write(i, tiling.slices(i), r))

    def close(self) -> None:
        """Nothing to release."""


def open_backend(scheduler: str | None = None, workers: int | None = None) -> Any:
    """The backend of a run: dask with ``scheduler`` (an address) or ``workers`` (a local
    cluster of that many processes), else :class:`LocalBackend`. BackendError if dask is
    missing or the scheduler cannot be reached within ``CONNECT_TIMEOUT`` seconds."""
    if scheduler is not None or workers is not None:
        return DaskBackend(scheduler, workers)
    return LocalBackend()


def _config(key: str, default: float) -> float:
    import dask

    try:
        value = float(dask.config.get(f"conesurvey.{key}", default))
    except (TypeError, ValueError):
        raise BackendError(f"dask config conesurvey.{key} must be a number of seconds") from None
    return value if value > 0 else default


class DaskBackend:
    """Blocks computed on a dask.distributed cluster, yielded as they complete.

    ``workers``: start a LocalCluster of that many single-threaded worker processes, each
    with NUMBA_NUM_THREADS = cores // workers (numba threads x workers <= cores). With
    ``scheduler`` the cluster exists already; start its workers with ``--nthreads 1`` and
    NUMBA_NUM_THREADS set to the cores per worker. At most 2 blocks per worker are in flight.
    """

    def __init__(self, scheduler: str | None, workers: int | None) -> None:
        try:  # optional dependency; lazy also because dask.distributed takes ~0.28 s to import
            import dask
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise BackendError(
                f"the dask backend needs dask.distributed: {install_hint('dask')}"
            ) from None
        # distributed's Nanny writes its pre-spawn environment (NUMBA_NUM_THREADS, ...) into
        # this process's os.environ; numba re-reads it and refuses a thread count that differs
        # from its running pool. The environment is restored when the cluster is gone.
        self._saved_env = dict(os.environ)
        self.cluster = None
        # A wait for a block that :meth:`_result` abandons (its worker died) leaves the client's
        # internal gather task to fail later with AllExit, which asyncio logs as "Task exception
        # was never retrieved" at exit; what failed has been reported as one line already.
        logging.getLogger("asyncio").setLevel(logging.CRITICAL)
        if scheduler is None:
            n = int(workers or 1)
            threads = max(1, (os.cpu_count() or 1) // n)
            env = {"NUMBA_NUM_THREADS": str(threads), "OMP_NUM_THREADS": str(threads)}
            try:
                with dask.config.set({"distributed.nanny.pre-spawn-environ": env}):
                    self.cluster = LocalCluster(
                        n_workers=n,
                        threads_per_worker=1,
                        processes=True,
                        dashboard_address=None,
                        host="127.0.0.1",
                        silence_logs=logging.CRITICAL,
                    )
                self.client = Client(self.cluster, set_as_default=False)
            except Exception as exc:
                self.close()
                why = _one_line(exc)
                raise BackendError(f"cannot start a local dask cluster ({why})") from None
            return
        timeout = _config("connect-timeout", CONNECT_TIMEOUT)
        try:
            self.client = Client(check_address(scheduler), timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            self._restore()
            raise BackendError(
                f"cannot reach the dask scheduler at {scheduler} within {timeout:g} s "
                f"({_one_line(exc)})"
            ) from None

    def blocks(
        self, plan: RunPlan, tiling: Tiling, pending: list[int], writer: Any = None
    ) -> Blocks:
        """The pending blocks, as they complete (BackendError if the cluster fails); with a
        ``writer``, each worker writes the blocks it computes and returns the receipts."""
        try:
            n_workers = max(1, len(self.client.nthreads()))
            plan_f = self.client.submit(_same, plan, pure=False)
        except Exception as exc:
            raise _lost(exc) from None
        todo = iter(pending)
        in_flight: dict[Any, int] = {}

        def submit_next() -> None:
            i = next(todo, None)
            if i is not None:
                fut = (
                    self.client.submit(compute_block, plan_f, tiling, i, pure=False)
                    if writer is None
                    else self.client.submit(write_block, plan_f, tiling, i, writer, pure=False)
                )
                in_flight[fut] = i

        for _ in range(2 * n_workers):
            submit_next()
        watchdog = _Watchdog(self.client, _config("no-workers-timeout", NO_WORKERS_TIMEOUT))
        while in_flight:
            for fut in self._completed(in_flight, watchdog):
                del in_flight[fut]
                result = self._result(fut, watchdog)
                submit_next()
                yield result

    def _completed(self, in_flight: dict[Any, int], watchdog: _Watchdog) -> list[Any]:
        """The futures that are done, waiting for one (and checking the cluster every
        ``POLL`` seconds while none is). Polls ``Future.done()``: the futures belong to this
        backend's client, whatever client is the process's default."""
        start = time.monotonic()
        nap = 0.002
        while True:
            try:
                done = [f for f in in_flight if f.done()]
            except Exception as exc:
                raise _lost(exc) from None
            if done:
                return done
            if time.monotonic() - start >= POLL:
                watchdog.check()
                start = time.monotonic()
            time.sleep(nap)
            nap = min(2 * nap, 0.05)

    def _result(self, fut: Any, watchdog: _Watchdog) -> tuple[int, dict[str, np.ndarray]]:
        """The block of a finished future. Its data lives on the worker that computed it: if
        that worker dies before the data arrives, dask computes the block again, so the wait is
        in ``POLL`` slices with the cluster checked between them (a cluster left without
        workers is a BackendError, not a run that waits forever)."""
        from distributed.scheduler import KilledWorker

        while True:
            if fut.status == "error":
                exc = fut.exception()
                if isinstance(exc, KilledWorker):
                    raise BackendError(f"dask gave up on a block: {_one_line(exc)}")
                raise exc  # the block's own error (as a local run would raise it)
            try:
                result = fut.result(timeout=POLL)
                fut.release()
                return result
            except TimeoutError:
                watchdog.check()
            except Exception as exc:
                raise _lost(exc) from None

    def close(self) -> None:
        """Close the client (and the local cluster); restore the environment."""
        try:
            if hasattr(self, "client"):
                self.client.close(timeout=2)
            if self.cluster is not None:
                self.cluster.close(timeout=5)
        except Exception:  # closing a lost cluster may fail: nothing is left to release
            pass
        finally:
            self._restore()

    def _restore(self) -> None:
        os.environ.clear()
        os.environ.update(self._saved_env)


class _Watchdog:
    """Raises BackendError when the cluster has had no workers for ``timeout`` seconds."""

    def __init__(self, client: Any, timeout: float) -> None:
        self.client = client
        self.timeout = timeout
        self.since: float | None = None

    def check(self) -> None:
        try:
            n = len(self.client.nthreads())
        except Exception as exc:
            raise _lost(exc) from None
        now = time.monotonic()
        if n:
            self.since = None
        elif self.since is None:
            self.since = now
        elif now - self.since > self.timeout:
            raise BackendError(f"the dask cluster has had no workers for {self.timeout:g} s")


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or exc.__class__.__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _lost(exc: BaseException) -> BackendError:
    return BackendError(f"lost the dask cluster ({exc.__class__.__name__}: {_one_line(exc)})")

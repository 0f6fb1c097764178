"""What the benchmarks share: the machine in words, the load, their timing loops (the best of
interleaved rounds, first calls, a fresh interpreter's import and first calls), the verdict on a
target, and the serial share of a call.

The serial share is the part of a call that threads cannot shorten: at 1 thread, the wall time
spent outside its parallel region (validating, allocating, assembling the outputs), as a share
of the whole. With a serial share s, n threads give at most 1 / (s + (1 - s) / n): 3 % caps 16
threads at 11.4x.
"""

from __future__ import annotations

import json
import math
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numba
import numpy as np


def best(fn: Callable[[], object], repeats: int) -> float:
    """The shortest wall time [s] of ``repeats`` calls of ``fn``."""
    t = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        t = min(t, time.perf_counter() - t0)
    return t


def load() -> str:
    """The load average (1, 5, 15 min)."""
    return ", ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"


def interleaved(
    fns: dict[str, Callable[[], object]],
    rounds: int,
    clocks: Sequence[Callable[[], float]] = (time.perf_counter,),
) -> dict[str, tuple[float, ...]]:
    """The best time [s] of each call by each clock (wall: ``time.perf_counter``; CPU:
    ``time.process_time`` or ``time.thread_time``) over ``rounds`` rounds, each calling every
    function once in turn: a load that comes and goes falls on all of them alike."""
    best = {name: [math.inf] * len(clocks) for name in fns}
    for _ in range(rounds):
        for name, fn in fns.items():
            start = [clock() for clock in clocks]
            fn()
            ends = [clock() for clock in clocks]
            best[name] = [min(b, e - s) for b, s, e in zip(best[name], start, ends, strict=True)]
    return {name: tuple(b) for name, b in best.items()}


def first_calls(fns: dict[str, Callable[[], object]]) -> tuple[dict[str, float], dict]:
    """Each function called once, in order: the wall time [s] of each first call (its compile,
    or its load from the cache, included) and what each returned."""
    seconds, results = {}, {}
    for name, fn in fns.items():
        t0 = time.perf_counter()
        results[name] = fn()
        seconds[name] = time.perf_counter() - t0
    return seconds, results


def fresh_interpreter(probe: str, cache_dir: str | None = None, timeout: float = 1800) -> dict:
    """Run ``probe`` (Python that prints one JSON object as its last line: its own timings) in a
    fresh interpreter, with the compile cache ``cache_dir`` (None: the user's), and return
    that object with ``process``, the wall time [s] of the whole process, added."""
    env = {k: v for k, v in os.environ.items() if k != "CONESURVEY_NO_CACHE"}
    if cache_dir is not None:
        env["CONESURVEY_CACHE_DIR"] = cache_dir
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True,
                         check=True, timeout=timeout)  # fmt: skip
    out = json.loads(res.stdout.strip().splitlines()[-1])
    out["process"] = time.perf_counter() - t0
    return out


def verdict(value: float, target: float) -> str:
    """ "met" if ``value`` reaches ``target`` (larger is better), else "MISSED"."""
    return "met" if value >= target else "MISSED"


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


#: The machine, in words (every figure names it).
MACHINE = f"{_cpu_model()}, {os.cpu_count()} logical CPUs"


class InRegion:
    """Wall time spent inside ``module.name`` (a call's parallel region) while active: the
    attribute is wrapped on entry and restored on exit."""

    def __init__(self, module, name: str):
        self.module, self.name = module, name
        self.inside = 0.0

    def __enter__(self) -> InRegion:
        inner = self.original = getattr(self.module, self.name)

        def timed(*args, **kw):
            t0 = time.perf_counter()
            try:
                return inner(*args, **kw)
            finally:
                self.inside += time.perf_counter() - t0

        setattr(self.module, self.name, timed)
        return self

    def __exit__(self, *exc) -> None:
        setattr(self.module, self.name, self.original)


def serial_share(fn: Callable[[], object], module, name: str, rounds: int = 5,
                 also: Sequence[tuple[object, str]] = ()) -> float:  # fmt: skip
    """Lowest share, over ``rounds`` calls at 1 thread, of ``fn``'s wall time spent outside its
    parallel region ``module.name`` (and the regions ``also``: (module, name) pairs, none
    called inside another). Restores the number of threads."""
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        fn()
        best = math.inf
        for _ in range(rounds):
            regions = [InRegion(m, n) for m, n in ((module, name), *also)]
            for region in regions:
                region.__enter__()
            try:
                t0 = time.perf_counter()
                fn()
                total = time.perf_counter() - t0
            finally:
                for region in reversed(regions):
                    region.__exit__()
            best = min(best, 1.0 - sum(r.inside for r in regions) / total)
    finally:
        numba.set_num_threads(before)
    return best


@numba.njit(parallel=True, nogil=True, cache=True)
def spin(n_items: int, n_inner: int) -> float:
    """A compute-only prange loop (no memory traffic): timed at 1 and 2 threads beside a
    benchmark, its speedup is the machine's available parallelism in the same rounds."""
    acc = np.zeros(n_items)
    for i in numba.prange(n_items):
        x = 0.0
        for j in range(n_inner):
            x += math.sin(x + j)
        acc[i] = x
    return acc.sum()


@numba.njit(parallel=True, nogil=True, cache=True)
def spin_vector(n_items: int, n_inner: int) -> float:
    """:func:`spin` on the vector units: 32 independent multiply-adds a round (8 AVX2
    instructions, in the first-level cache), bound by the units' throughput like the lanes'
    step, where :func:`spin` is bound by the latency of one chain. On a virtual machine whose
    two cores share their vector units with other work on the host, this one loses and
    :func:`spin` does not."""
    acc = np.zeros(n_items)
    for i in numba.prange(n_items):
        x = np.arange(32.0)
        for _ in range(n_inner):
            for k in range(32):
                x[k] = x[k] * 1.0000001 + 1e-9
        acc[i] = x.sum()
    return acc.sum()


def matched_inner(control: Callable[[int, int], float], fn: Callable[[], object]) -> int:
    """The inner length of ``control(64, inner)`` (:func:`spin`, :func:`spin_vector`) that
    takes as long at 1 thread as ``fn`` (one call of each, after a warm-up call): a control
    as short as the engine's call pays the same cost of starting the threads."""
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        control(64, 100)
        t0 = time.perf_counter()
        control(64, 4_000)
        t_control = time.perf_counter() - t0
        t0 = time.perf_counter()
        fn()
        t_fn = time.perf_counter() - t0
    finally:
        numba.set_num_threads(before)
    return max(100, int(4_000 * t_fn / t_control))

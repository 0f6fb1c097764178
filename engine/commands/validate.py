"""``conesurvey validate SURVEY.toml``: check a survey definition without running it.

It refuses exactly what ``conesurvey run`` refuses about the definition (the one parser,
:func:`engine.surveyfile.load_survey`, checks the method against the scene and the tolerance
against the method); exit status 2 when it is invalid.

The run time it prints is measured: the survey's own plan evaluated on a sample of its grid
(:func:`measured_rate`: each axis sampled evenly, grown until its evaluation takes
:data:`TIMED_SECONDS`), scaled to the whole grid, plus the compression of its output (the
sample's values deflated as the run deflates them, timed) and a run's fixed cost, measured too
(:func:`measured_overhead`: a one-point run of the survey in a temporary directory, removed:
its store, files, fsyncs and threads; from 0.03 s on a quiet machine to 0.4 s under a load of
10, so no constant serves). Where the kernels are not compiled yet
the sample would compile them (30-120 s), so a stored rate per kind of map is used instead
(:data:`STORED_RATES`; none for fate maps, whose time depends on how long their orbits roll).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from .._jit import CACHE_DIR
from ..accuracy import sample_counts
from ..api import minimum_energy
from ..evaluation import evaluate_block
from ..io.blocks import estimate_bytes
from ..io.codecs import DEFAULT_COMPRESSION, level
from ..io.deflate import compress_chunk
from ..kernels import batch
from ..plan import RunPlan
from ..progress import format_bytes
from ..runner import run_survey
from ..schema import map_summary
from . import PROG, Command, load_plan

__all__ = [
    "COMMAND",
    "SAMPLE_POINTS",
    "STORED_RATES",
    "TIMED_SECONDS",
    "RUN_OVERHEAD",
    "deflate_seconds_per_byte",
    "compile_seconds",
    "energy_warning",
    "measured_rate",
    "run_seconds",
    "sample_plan",
]

#: CPU seconds of a first run's numba compile, by kind of map, and the kernel module whose
#: cached entries show that it was done. Closed form and fate map measured on the shipped
#: surveys (docs/surveys.md, "The first run compiles"); one period: the rk45/dop853 batch's
#: compile as the integrator benchmark measured it (84-91 s).
COMPILE_SECONDS = {"closed form": (30.0, "batch"), "one period": (90.0, "lanes"),
                   "fate": (50.0, "fate"), "sliding fate": (120.0, "hybrid"),
                   "surface exact": (20.0, "routh_orbit"),
                   "surface one period": (110.0, "lanes"),
                   "surface fate": (70.0, "fate")}  # fmt: skip


def compile_seconds(plan: RunPlan) -> float:
    """Seconds the first run will spend compiling the survey's kernels: 0 when numba's cache
    holds them already (compiled by an earlier run with these kernel sources)."""
    seconds, module = COMPILE_SECONDS[plan.map_kind]
    if CACHE_DIR is None:
        return seconds  # no cache: every run compiles
    where = _kernel_cache_dir()
    if where is not None and any(where.glob(f"{module}.*.nbi")):
        return 0.0
    return seconds


def _kernel_cache_dir() -> Path | None:
    """Where numba caches the kernels of this installation (numba's cache locator decides;
    None if it cannot be told)."""
    for value in vars(batch).values():
        path = getattr(getattr(value, "_cache", None), "_cache_path", None)
        if isinstance(path, str):
            return Path(path)
    return None


#: Points of the first sample ``validate`` evaluates (each axis sampled evenly), and how long
#: the evaluation of the sample it times takes at least (it grows until then).
SAMPLE_POINTS = 64
TIMED_SECONDS = 0.5
#: The largest sample (a block of a run: its memory), timed as often as it takes.
MAX_SAMPLE_POINTS = 1 << 20
#: Seconds a run spends whatever its size (its block store, output file, journal, fsyncs and
#: threads), assumed where it cannot be measured without compiling (a one-point run took
#: 0.26-0.48 s on the project's 2-core machine under a load of 10, 0.03-0.05 s quiet).
RUN_OVERHEAD = 0.4
#: One-point runs :func:`measured_overhead` takes the median of.
OVERHEAD_RUNS = 3
#: Throughput [points/s] assumed, by kind of map, while its kernels are not compiled yet (a
#: sample cannot be timed without compiling them: 30-120 s): the closed form and one period
#: on 2 cores (docs/performance.md). A fate map's time depends on how long its orbits roll
#: (its horizon, its scene): none is assumed; the sample is timed once a run compiled them.
STORED_RATES = {"closed form": 2.0e6, "one period": 2.0e4}


def sample_plan(plan: RunPlan, points: int = SAMPLE_POINTS) -> RunPlan:
    """``plan`` on a sample of its grid: each axis sampled evenly (its first and last values
    always), the longest axes most, about ``points`` points in all (at most twice as many;
    the whole grid if smaller)."""
    axes = []
    for a, n in zip(plan.axes, sample_counts(plan, points), strict=True):
        sub = a[np.unique(np.linspace(0, a.size - 1, n).round().astype(np.int64))]
        sub.setflags(write=False)
        axes.append(sub)
    return dataclasses.replace(plan, axes=tuple(axes))


def measured_rate(plan: RunPlan) -> tuple[float, int, dict[str, np.ndarray]]:
    """(points per second, points timed, the values of the last sample): the plan's
    evaluation timed on a sample of its grid (:func:`sample_plan`) that grows until one
    evaluation of it takes :data:`TIMED_SECONDS` (or is the whole grid; a sample of
    :data:`MAX_SAMPLE_POINTS` is evaluated as often as it takes), after an untimed evaluation
    of the first sample that loads its kernels from the cache. A sample timed for
    milliseconds was at the mercy of one scheduling delay (64 points: estimates of 1.6 s and
    45 s for the same 0.9 s run)."""
    sample = sample_plan(plan, SAMPLE_POINTS)
    whole = tuple(slice(None) for _ in sample.dims)
    evaluate_block(sample, whole)  # loads the kernels
    while True:
        t0 = time.perf_counter()
        values = evaluate_block(sample, whole)
        took = max(time.perf_counter() - t0, 1e-9)
        if took >= TIMED_SECONDS or sample.size >= plan.size:
            return sample.size / took, sample.size, values
        if sample.size >= MAX_SAMPLE_POINTS:  # as large as a block: time it again and again
            runs = math.ceil(TIMED_SECONDS / took)
            t0 = time.perf_counter()
            for _ in range(runs):
                evaluate_block(sample, whole)
            rate = runs * sample.size / max(time.perf_counter() - t0, 1e-9)
            return rate, runs * sample.size, values
        grow = min(max(1.3 * TIMED_SECONDS / took, 2.0), 64.0)  # to about TIMED_SECONDS
        sample = sample_plan(plan, min(int(sample.size * grow), MAX_SAMPLE_POINTS))
        whole = tuple(slice(None) for _ in sample.dims)


def deflate_seconds_per_byte(values: dict[str, np.ndarray]) -> float:
    """Seconds per uncompressed byte to deflate ``values`` as a run's output is deflated by
    default (shuffle and deflate at the default level, chunks of 2^16 values), on one core."""
    lvl = level(DEFAULT_COMPRESSION, None)
    total, t0 = 0, time.perf_counter()
    for arr in values.values():
        flat = np.ascontiguousarray(arr).reshape(-1)
        for i in range(0, flat.size, 1 << 16):
            compress_chunk(flat[i : i + (1 << 16)], lvl)
        total += flat.nbytes
    return (time.perf_counter() - t0) / max(total, 1)


def measured_overhead(plan: RunPlan) -> float:
    """Seconds a run of ``plan`` spends whatever its size, on this machine now: the median of
    :data:`OVERHEAD_RUNS` runs of its first grid point (kernels compiled already) into a
    temporary directory, removed after; their compute and finish, as a run counts them (one
    run alone took 0.11-0.18 s beside a busy neighbour; the fastest of three, below the runs
    that followed). Nothing is written where the survey's output goes."""
    one = SimpleNamespace(plan=dataclasses.replace(plan, axes=tuple(a[:1] for a in plan.axes)))
    took = []
    with tempfile.TemporaryDirectory(prefix="conesurvey-validate-") as tmp:
        for i in range(OVERHEAD_RUNS):
            stats = run_survey(one, Path(tmp) / f"overhead{i}.nc", warn=lambda message: None,
                               check_space=False)  # fmt: skip
            took.append(stats.compute_seconds + stats.write_seconds)
    return float(np.median(took))


def run_seconds(plan: RunPlan) -> tuple[float | None, str]:
    """The estimated run time [s] of ``plan`` on this machine, without its compile (None: no
    estimate), and how it was made: a timed sample once the kernels are compiled (the
    evaluation, the output's compression shared by the cores, and :func:`measured_overhead`), else
    the kind's stored rate."""
    if compile_seconds(plan) == 0.0:
        rate, n, values = measured_rate(plan)
        cores = max(os.cpu_count() or 1, 1)
        deflate = estimate_bytes(plan) * deflate_seconds_per_byte(values) / cores
        seconds = measured_overhead(plan) + plan.size / rate + deflate
        return seconds, f"on {cores} cores, from a timed sample of {n:,} points"
    rate = STORED_RATES.get(plan.map_kind)
    if rate is None:
        return None, "once the kernels are compiled (a fate map's time depends on its orbits)"
    seconds = RUN_OVERHEAD + plan.size / rate
    return seconds, "on 2 cores, at a stored rate (measured once the kernels are compiled)"


def energy_warning(plan: RunPlan) -> str | None:
    """A warning when every energy of the survey lies below the potential minimum V_min of
    every (alpha, h, Lz): every point would be forbidden (None otherwise, and for relative
    energies, launch states and grids where V has no minimum somewhere)."""
    if plan.launch or plan.energy_relative:
        return None
    a, h, lz = np.meshgrid(*(plan.axis(d) for d in ("alpha", "h", "Lz")), indexing="ij",
                           sparse=True)  # fmt: skip
    vmin = minimum_energy(a, h, lz, plan.scene)
    top = float(np.max(plan.axis("energy")))
    if not (np.all(np.isfinite(vmin)) and top < float(np.min(vmin))):
        return None
    return (
        f"every energy lies below V_min: the largest, {top:g} J, is under the smallest potential "
        f"minimum of the grid, {float(np.min(vmin)):g} J, so every point is forbidden; for "
        'offsets from V_min put relative_to = "V_min" in [axes.energy]'
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("survey", metavar="SURVEY.toml", help="survey definition (TOML)")


def _validate(args: argparse.Namespace, command: str) -> int:
    plan = load_plan(args.survey)
    need = estimate_bytes(plan)
    shape = " x ".join(f"{d} {n}" for d, n in zip(plan.dims, plan.shape, strict=True))
    print(f"{args.survey}: valid")
    if (warning := energy_warning(plan)) is not None:
        print(f"{PROG}: warning: {warning}", file=sys.stderr)
    print(f"  title   {plan.title}")
    method = plan.method.name
    print(f"  method  {method}" + (f" (rtol {plan.rtol:g})" if method != "exact" else ""))
    print(f"  grid    {shape} = {plan.size:,} points")
    print(
        f"  output  about {format_bytes(need)} uncompressed (less on disk: --compression "
        f"{DEFAULT_COMPRESSION} by default, docs/output.md)"
    )
    compiling = compile_seconds(plan)
    extra = (
        f" + about {compiling:.0f} s compiling the kernels (first run only)" if compiling else ""
    )
    seconds, how = run_seconds(plan)
    if seconds is None:
        print(f"  time    measured {how}{extra}")
    else:
        print(f"  time    about {seconds:.3g} s {how}{extra}")
    if plan.output.precision == "single":
        print("  precision single: float results stored as float32 (~7 significant digits); "
              "classes, status and fate exact")  # fmt: skip
    for line in map_summary(method, plan.scene, plan.energy_relative, plan.launch, plan.surface):
        print(f"  {line}")
    return 0


COMMAND = Command(
    name="validate",
    help="check a survey definition; print grid size, output size and run-time estimate",
    description="Check SURVEY.toml without running it (exit 2 if it is invalid).",
    add_arguments=add_arguments,
    run=_validate,
)

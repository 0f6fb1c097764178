"""``conesurvey validate SURVEY.toml``: check a survey definition without running it.

It refuses exactly what ``conesurvey run`` refuses about the definition (the one parser,
:func:`engine.surveyfile.load_survey`, checks the method against the scene and the tolerance
against the method); exit status 2 when it is invalid.

The run time it prints is measured: the survey's own plan evaluated on a sample of its grid
(:func:`measured_rate`, about :data:`SAMPLE_POINTS` points, each axis sampled evenly), scaled
to the whole grid. Where the kernels are not compiled yet the sample would compile them
(30-120 s), so a stored rate per kind of map is used instead (:data:`STORED_RATES`; none for
fate maps, whose time depends on how long their orbits roll).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from .._jit import CACHE_DIR
from ..api import minimum_energy
from ..evaluation import evaluate_block
from ..io.blocks import estimate_bytes
from ..io.codecs import DEFAULT_COMPRESSION
from ..kernels import batch
from ..plan import RunPlan
from ..progress import format_bytes
from ..schema import map_summary
from . import PROG, Command, load_plan

__all__ = [
    "COMMAND",
    "SAMPLE_POINTS",
    "STORED_RATES",
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


#: Points of the sample ``validate`` times to estimate a run (each axis sampled evenly).
SAMPLE_POINTS = 64
#: Throughput [points/s] assumed, by kind of map, while its kernels are not compiled yet (a
#: sample cannot be timed without compiling them: 30-120 s): the closed form and one period
#: on 2 cores (docs/performance.md). A fate map's time depends on how long its orbits roll
#: (its horizon, its scene): none is assumed; the sample is timed once a run compiled them.
STORED_RATES = {"closed form": 2.0e6, "one period": 2.0e4}


def sample_plan(plan: RunPlan, points: int = SAMPLE_POINTS) -> RunPlan:
    """``plan`` on a sample of its grid: each axis sampled evenly (its first and last values
    always), the longest axes most, about ``points`` points in all (at most twice as many;
    the whole grid if smaller)."""
    counts = [min(2, a.size) for a in plan.axes]
    while math.prod(counts) < points:
        grow = [i for i, a in enumerate(plan.axes) if counts[i] < a.size]
        if not grow:
            break
        i = max(grow, key=lambda j: plan.axes[j].size / counts[j])
        counts[i] = min(2 * counts[i], plan.axes[i].size)
    axes = []
    for a, n in zip(plan.axes, counts, strict=True):
        sub = a[np.unique(np.linspace(0, a.size - 1, n).round().astype(np.int64))]
        sub.setflags(write=False)
        axes.append(sub)
    return dataclasses.replace(plan, axes=tuple(axes))


def measured_rate(plan: RunPlan) -> tuple[float, int]:
    """(points per second, points timed): the plan's evaluation timed on a sample of its grid
    (:func:`sample_plan`), after a one-point call that loads its kernels from the cache."""
    sample = sample_plan(plan)
    evaluate_block(sample, tuple(slice(0, 1) for _ in sample.dims))
    t0 = time.perf_counter()
    evaluate_block(sample, tuple(slice(None) for _ in sample.dims))
    return sample.size / max(time.perf_counter() - t0, 1e-9), sample.size


def run_seconds(plan: RunPlan) -> tuple[float | None, str]:
    """The estimated run time [s] of ``plan`` on this machine, without its compile (None: no
    estimate), and how it was made: a timed sample once the kernels are compiled, else the
    kind's stored rate."""
    if compile_seconds(plan) == 0.0:
        rate, n = measured_rate(plan)
        return plan.size / rate, f"on {os.cpu_count()} cores, from a timed sample of {n} points"
    rate = STORED_RATES.get(plan.map_kind)
    if rate is None:
        return None, "once the kernels are compiled (a fate map's time depends on its orbits)"
    return plan.size / rate, "on 2 cores, at a stored rate (measured once the kernels are compiled)"


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

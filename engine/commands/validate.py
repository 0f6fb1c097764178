"""``conesurvey validate SURVEY.toml``: check a survey definition without running it.

It refuses exactly what ``conesurvey run`` refuses about the definition (the one parser,
:func:`engine.surveyfile.load_survey`, checks the method against the scene and the tolerance
against the method); exit status 2 when it is invalid.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from .._jit import CACHE_DIR
from ..api import minimum_energy
from ..io.blocks import estimate_bytes
from ..io.codecs import DEFAULT_COMPRESSION
from ..kernels import batch
from ..plan import RunPlan
from ..progress import format_bytes
from ..schema import map_summary
from . import PROG, Command, load_plan

__all__ = ["COMMAND", "EXACT_RATE", "INTEGRATOR_RATE", "compile_seconds", "energy_warning"]

#: Exact-path throughput assumed by ``validate`` [points/s] (2 cores, docs/performance.md).
EXACT_RATE = 2.0e6
#: Integrator throughput assumed by ``validate`` [orbits/s] at rtol 1e-10 on 2 cores.
INTEGRATOR_RATE = 2.0e4
#: CPU seconds of a first run's numba compile, by kind of map, and the kernel module whose
#: cached entries show that it was done. Closed form and fate map measured on the shipped
#: surveys (docs/surveys.md, "The first run compiles"); one period: the rk45/dop853 batch's
#: compile as the integrator benchmark measured it (84-91 s).
COMPILE_SECONDS = {"closed form": (30.0, "batch"), "one period": (90.0, "lanes"),
                   "fate": (50.0, "fate"), "sliding fate": (120.0, "hybrid")}  # fmt: skip


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


def _estimates(plan: RunPlan) -> tuple[int, float]:
    """(uncompressed output bytes, estimated run time [s])."""
    rate = EXACT_RATE if plan.method.name == "exact" else INTEGRATOR_RATE
    return estimate_bytes(plan), plan.size / rate


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
    need, seconds = _estimates(plan)
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
    print(f"  time    about {seconds:.3g} s on 2 cores{extra}")
    if plan.output.precision == "single":
        print("  precision single: float results stored as float32 (~7 significant digits); "
              "classes, status and fate exact")  # fmt: skip
    for line in map_summary(method, plan.scene, plan.energy_relative, plan.launch):
        print(f"  {line}")
    return 0


COMMAND = Command(
    name="validate",
    help="check a survey definition; print grid size, output size and run-time estimate",
    description="Check SURVEY.toml without running it (exit 2 if it is invalid).",
    add_arguments=add_arguments,
    run=_validate,
)

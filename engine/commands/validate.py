"""``conesurvey validate SURVEY.toml``: check a survey definition without running it.

It refuses exactly what ``conesurvey run`` refuses about the definition (the one parser,
:func:`engine.surveyfile.load_survey`, checks the method against the scene and the tolerance
against the method); exit status 2 when it is invalid.
"""

from __future__ import annotations

import argparse

from ..io.blocks import estimate_bytes
from ..progress import format_bytes
from ..schema import map_summary
from ..surveyfile import Survey
from . import Command, load

__all__ = ["COMMAND", "EXACT_RATE", "INTEGRATOR_RATE"]

#: Exact-path throughput assumed by ``validate`` [points/s] (2 cores, see the README).
EXACT_RATE = 2.0e6
#: Integrator throughput assumed by ``validate`` [orbits/s] at rtol 1e-10 on 2 cores.
INTEGRATOR_RATE = 2.0e4


def _estimates(survey: Survey) -> tuple[int, float]:
    """(uncompressed output bytes, estimated run time [s])."""
    rate = EXACT_RATE if survey.method == "exact" else INTEGRATOR_RATE
    return estimate_bytes(survey), survey.size / rate


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("survey", metavar="SURVEY.toml", help="survey definition (TOML)")


def _validate(args: argparse.Namespace, command: str) -> int:
    survey = load(args.survey)
    need, seconds = _estimates(survey)
    shape = " x ".join(f"{d} {n}" for d, n in zip(survey.dims, survey.shape, strict=True))
    print(f"{args.survey}: valid")
    print(f"  title   {survey.title}")
    print(
        f"  method  {survey.method}"
        + (f" (rtol {survey.rtol:g})" if survey.method != "exact" else "")
    )
    print(f"  grid    {shape} = {survey.size:,} points")
    print(f"  output  about {format_bytes(need)} uncompressed (zlib shrinks it, class maps ~150x)")
    print(f"  time    about {seconds:.3g} s on 2 cores")
    if survey.precision == "single":
        print("  precision single: float results stored as float32 (~7 significant digits); "
              "classes, status and fate exact")  # fmt: skip
    for line in map_summary(survey.method, survey.scene, survey.energy_relative, survey.launch):
        print(f"  {line}")
    return 0


COMMAND = Command(
    name="validate",
    help="check a survey definition; print grid size, output size and run-time estimate",
    description="Check SURVEY.toml without running it (exit 2 if it is invalid).",
    add_arguments=add_arguments,
    run=_validate,
)

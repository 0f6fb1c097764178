"""conesurvey: orbit surveys of a sphere rolling without slipping inside a right circular cone.

Public API: :class:`Scene`, :func:`evaluate` (points), :func:`survey` (4-D grids),
:func:`simulate` (one trajectory), :func:`radial_energy` and :func:`minimum_energy`;
launch states :func:`invariants` and :func:`launch_state`; the method registry :data:`METHODS`;
what accuracy costs on a survey, :func:`work_precision`; :func:`set_compile_notices` (whether
a compile is announced on stderr).
"""

from __future__ import annotations

from . import (
    _startup,  # noqa: F401  (first: a Ctrl-C while `python -m engine.cli` starts)
    accessor,  # noqa: F401  (registers the ds.cone accessor)
)
from ._compiling import set_compile_notices
from ._version import __version__
from .accuracy import work_precision
from .api import evaluate, launch_survey, minimum_energy, radial_energy, survey
from .fates import Horizon
from .io.results import read_plans_with
from .kernels.fate import FATE_NAMES
from .kernels.geometry import CLASS_NAMES
from .launch import invariants, launch_state
from .methods import METHODS
from .plan import RunPlan
from .scene import Scene
from .simulate import simulate  # binds the function over the submodule's name
from .surveyfile import parse_survey as _parse_survey


def _plan_of_text(text: str, origin: str) -> RunPlan:
    """The plan of a survey definition's TOML text (an unfinished run's, which io/ opens)."""
    return _parse_survey(text, origin=origin).plan


read_plans_with(_plan_of_text)  # io/ reads unfinished runs without importing the layers above

__all__ = [
    "Scene",
    "evaluate",
    "survey",
    "launch_survey",
    "simulate",
    "minimum_energy",
    "radial_energy",
    "invariants",
    "launch_state",
    "Horizon",
    "METHODS",
    "work_precision",
    "set_compile_notices",
    "CLASS_NAMES",
    "FATE_NAMES",
    "__version__",
]

"""conesurvey: orbit surveys of a sphere rolling without slipping inside a right circular cone.

Public API: :class:`Scene`, :func:`evaluate` (points), :func:`survey` (4-D grids),
:func:`simulate` (one trajectory), :func:`radial_energy` and :func:`minimum_energy`.
"""

from __future__ import annotations

__version__ = "0.1.0"

from . import accessor  # noqa: E402, F401  (registers the ds.cone accessor)
from .api import evaluate, minimum_energy, survey  # noqa: E402
from .kernels.physics import CLASS_NAMES  # noqa: E402
from .scene import Scene  # noqa: E402
from .simulate import simulate  # noqa: E402  (binds the function over the submodule)


def radial_energy(E: float, h: float, scene: Scene | None = None) -> float:
    """Radial energy calE [J] = E/(1+k) - k M h^2 / (2(1+k)) from the total energy E [J]."""
    s = Scene() if scene is None else scene
    return E / (1.0 + s.k) - s.k / (2.0 * (1.0 + s.k)) * s.M * h * h


__all__ = [
    "Scene",
    "evaluate",
    "survey",
    "simulate",
    "minimum_energy",
    "radial_energy",
    "CLASS_NAMES",
    "__version__",
]

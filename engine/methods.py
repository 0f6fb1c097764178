"""The method registry: every way conesurvey can compute an orbit, and which effects each honours.

The API, the survey file, the command line and ``conesurvey validate`` all take their list of
methods and their "method X cannot honour effect Y" answers from :data:`METHODS`. The
Runge-Kutta rows are made from :data:`engine.kernels.tableaux.RK_TABLEAUX`, so a new pair of
tableaux is a new method with no other change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .kernels.model import EFFECT_BITS
from .kernels.symplectic import SYMPLECTIC
from .kernels.symplectic import UNSUPPORTED_EFFECTS as _SYMPLECTIC_UNSUPPORTED
from .kernels.tableaux import RK_TABLEAUX

if TYPE_CHECKING:
    from .scene import Scene

__all__ = [
    "Method",
    "METHODS",
    "RTOL_RANGE",
    "DEFAULT_RTOL",
    "get_method",
    "check_method",
    "check_rtol",
]

#: Relative tolerances the integrators accept (tighter is below rounding; looser is not a map).
RTOL_RANGE = (1e-14, 1e-3)
_RTOL_TEXT = "[1e-14, 1e-3]"
DEFAULT_RTOL = 1e-10


@dataclass(frozen=True)
class Method:
    """A way to compute orbits.

    ``kernel_id`` is the literal id of its run kernel (None for the closed form); ``family`` is
    "closed form", "runge-kutta" or "splitting"; ``refuses`` maps each effect the method cannot
    honour to the reason.
    """

    name: str
    kernel_id: int | None
    family: str
    title: str
    refuses: tuple[tuple[str, str], ...] = ()

    @property
    def integrates(self) -> bool:
        """True for the integrators (they add step counts, energy drift and a status)."""
        return self.kernel_id is not None

    @property
    def refused_mask(self) -> int:
        """The refused effects as a kernel bit mask."""
        mask = 0
        for name, _ in self.refuses:
            mask |= EFFECT_BITS[name]
        return mask

    def refused_effects(self, scene: Scene) -> list[str]:
        """The effects of ``scene`` this method cannot honour."""
        refused = dict(self.refuses)
        return [e for e in scene.effects if e in refused]


def _rk_row(kernel_id: int) -> Method:
    tb = RK_TABLEAUX[kernel_id]
    return Method(tb.name, kernel_id, "runge-kutta", tb.title)


_SYMPLECTIC_REASONS = {
    "rolling_resistance": "it integrates the conservative radial Hamiltonian",
    "attitude": "it does not carry the sphere's orientation",
}

#: Every method by name, in the order users see them.
METHODS: dict[str, Method] = {
    "exact": Method(
        "exact",
        None,
        "closed form",
        "closed form (elliptic integrals)",
        (
            (
                "rolling_resistance",
                "the closed form describes lossless orbits; a fate map integrates the resistance",
            ),
            ("attitude", "the closed form does not follow the sphere's orientation"),
            ("sliding", "the closed form describes rolling without slipping"),
            ("spin_friction", "the closed form describes lossless orbits"),
        ),
    ),
    **{tb.name: _rk_row(i) for i, tb in enumerate(RK_TABLEAUX)},
    "symplectic": Method(
        "symplectic",
        SYMPLECTIC,
        "splitting",
        "time-transformed leapfrog with Yoshida's 6th-order composition",
        tuple(
            (name, _SYMPLECTIC_REASONS[name])
            for name, bit in EFFECT_BITS.items()
            if bit & _SYMPLECTIC_UNSUPPORTED
        )
        + (
            ("sliding", "a sliding sphere is not a conservative rolling orbit"),
            ("spin_friction", "it integrates the conservative radial Hamiltonian"),
        ),
    ),
}


def get_method(name: Any, *, integrator: bool = False) -> Method:
    """The registered method ``name`` (an integrator if ``integrator``); ValueError listing the
    methods otherwise."""
    choices = [m for m in METHODS.values() if m.integrates or not integrator]
    if not isinstance(name, str) or name not in [m.name for m in choices]:
        names = ", ".join(m.name for m in choices)
        raise ValueError(f"method must be one of {names}; got {name!r}")
    return METHODS[name]


def check_method(name: Any, scene: Scene, *, integrator: bool = False) -> Method:
    """The method ``name`` if it honours every effect of ``scene``; otherwise ValueError naming
    the effects it cannot honour and the methods that can."""
    method = get_method(name, integrator=integrator)
    refused = method.refused_effects(scene)
    if refused:
        able = [m.name for m in METHODS.values() if not m.refused_effects(scene) and m.integrates]
        reasons = "; ".join(f"{e}: {dict(method.refuses)[e]}" for e in refused)
        raise ValueError(
            f"method {method.name!r} cannot honour the scene's {', '.join(refused)} ({reasons}); "
            f"methods that can: {', '.join(able)}"
        )
    return method


def check_rtol(rtol: Any) -> float:
    """rtol as a float in :data:`RTOL_RANGE`; ValueError otherwise."""
    if isinstance(rtol, bool | str):
        raise ValueError(f"rtol must be a number; got {rtol!r}")
    try:
        r = float(rtol)
    except (TypeError, ValueError):
        raise ValueError(f"rtol must be a number; got {rtol!r}") from None
    lo, hi = RTOL_RANGE
    if not (lo <= r <= hi) or math.isnan(r):
        raise ValueError(f"rtol must lie in {_RTOL_TEXT}; got {rtol!r}")
    return r

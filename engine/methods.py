"""The method registry: every way conesurvey can compute an orbit, and which effects each honours.

The API, the survey file, the command line and ``conesurvey validate`` all take their list of
methods and their "method X cannot honour effect Y" answers from :data:`METHODS`. A method
declares which of the :data:`engine.kernels.effects.CAPABILITIES` it has and, for each it lacks,
why (opt-in, as an ODE solver declares the term structure it accepts); an effect of the effects
table that needs a capability a method lacks is refused with that reason. A method that does not
declare every capability is an error at import, so a new capability cannot be silently ignored.
The Runge-Kutta rows are made from :data:`engine.kernels.tableaux.RK_TABLEAUX`, so a new pair of
tableaux is a new method with no other change.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .kernels.effects import BY_NAME, CAPABILITIES, EFFECTS, mask_of
from .kernels.model import MODEL_CAPABILITIES, MODELS, Model
from .kernels.orbit import RUN_KERNELS
from .kernels.symplectic import SUPPORTS as SYMPLECTIC_SUPPORTS
from .kernels.symplectic import SYMPLECTIC
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
]

#: Relative tolerances the integrators accept (tighter is below rounding; looser is not a map).
RTOL_RANGE = (1e-14, 1e-3)
DEFAULT_RTOL = 1e-10


@dataclass(frozen=True)
class Method:
    """A way to compute orbits.

    ``kernel_id`` is the literal id of its run kernel (None for the closed form); ``family`` is
    "closed form", "runge-kutta" or "splitting"; ``supports`` names the capabilities
    (:data:`engine.kernels.effects.CAPABILITIES`) it has and ``lacks`` maps each other one to
    the reason; together they must name every capability exactly once.
    """

    name: str
    kernel_id: int | None
    family: str
    title: str
    supports: tuple[str, ...]
    lacks: tuple[tuple[str, str], ...] = ()
    #: What it needs of a model (``engine.kernels.model.MODEL_CAPABILITIES``).
    model_needs: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        lacked = [c for c, _ in self.lacks]
        declared = [*self.supports, *lacked]
        missing = [c for c in CAPABILITIES if c not in declared]
        unknown = [c for c in declared if c not in CAPABILITIES]
        twice = sorted({c for c in declared if declared.count(c) > 1})
        unexplained = [c for c, why in self.lacks if not why.strip()]
        if missing or unknown or twice or unexplained:
            raise ValueError(
                f"method {self.name!r} must declare each capability once, supported or lacked "
                f"with a reason: missing {missing}, unknown {unknown}, twice {twice}, "
                f"no reason {unexplained}"
            )

    @property
    def integrates(self) -> bool:
        """True for the integrators (they add step counts, energy drift and a status)."""
        return self.kernel_id is not None

    @property
    def refuses(self) -> tuple[tuple[str, str], ...]:
        """(effect, reason) for each effect of the effects table this method cannot honour: the
        effects needing a capability it lacks, with its reasons."""
        why = dict(self.lacks)
        out = []
        for effect in EFFECTS:
            reasons = [why[c] for c in effect.needs if c not in self.supports]
            if reasons:
                out.append((effect.name, "; ".join(reasons)))
        return tuple(out)

    def honours(self, effect: str) -> bool:
        """Whether this method honours the effect named ``effect``."""
        return effect not in dict(self.refuses)

    @property
    def refused_mask(self) -> int:
        """The refused effects as a kernel bit mask."""
        return mask_of(name for name, _ in self.refuses)

    def refused_effects(self, scene: Scene) -> list[str]:
        """The effects of ``scene`` this method cannot honour."""
        refused = dict(self.refuses)
        return [e for e in scene.effects if e in refused]

    def model_refusals(
        self, model: Model, scene: Scene | None = None, story: bool = False
    ) -> list[str]:
        """Why this method cannot serve ``model`` (with ``scene``'s effects): the model's
        reasons for lacking what the method (or the scene's sliding contact) needs; a sliding
        scene needs "sliding maps" too unless it is one launch's ``story``."""
        needs = list(self.model_needs)
        if scene is not None and any("sliding contact" in BY_NAME[e].needs for e in scene.effects):
            needs.append("sliding contact")
            if not story:
                needs.append("sliding maps")
        lacks = dict(model.lacks)
        return [f"{need}: {lacks[need]}" for need in needs if need in lacks]


#: What the Runge-Kutta pairs can do: they integrate the scene's full state and right-hand side.
RK_SUPPORTS = ("dissipative forces", "rigid-body state", "sliding contact", "terminal events")


def _rk_row(kernel_id: int) -> Method:
    tb = RK_TABLEAUX[kernel_id]
    return Method(tb.name, kernel_id, "runge-kutta", tb.title, RK_SUPPORTS)


#: Every method by name, in the order users see them.
METHODS: dict[str, Method] = {
    "exact": Method(
        "exact",
        None,
        "closed form",
        "closed form (elliptic integrals; off the cone, Routh's reduction and quadrature)",
        ("terminal events",),
        (
            (
                "dissipative forces",
                "the closed form describes lossless orbits; an integrator follows the losses",
            ),
            ("rigid-body state", "the closed form does not follow the sphere's orientation"),
            ("sliding contact", "the closed form describes rolling without slipping"),
        ),
        model_needs=("exact maps",),
    ),
    **{tb.name: _rk_row(i) for i, tb in enumerate(RK_TABLEAUX)},
    "symplectic": Method(
        "symplectic",
        SYMPLECTIC,
        "splitting",
        "time-transformed leapfrog with Yoshida's 6th-order composition",
        SYMPLECTIC_SUPPORTS,
        (
            ("dissipative forces", "it integrates the conservative radial Hamiltonian"),
            ("rigid-body state", "it does not carry the sphere's orientation"),
            ("sliding contact", "a sliding sphere is not a conservative rolling orbit"),
        ),
        model_needs=("separable split",),
    ),
}


def check_model_needs() -> None:
    """Every method's model needs are capabilities models declare (at import)."""
    for m in METHODS.values():
        unknown = [n for n in m.model_needs if n not in MODEL_CAPABILITIES]
        if unknown:
            raise ValueError(f"method {m.name!r} needs unknown model capabilities {unknown}")


check_model_needs()


def check_kernel_ids(methods: dict[str, Method]) -> None:
    """Every integrator's kernel id is its own, and names a run kernel (a Runge-Kutta pair's
    position or ``engine.kernels.orbit.RUN_KERNELS``); the closed form has none (at import)."""
    seen: dict[int, str] = {}
    for m in methods.values():
        if m.kernel_id is None:
            continue
        if m.kernel_id in seen:
            raise ValueError(f"methods {seen[m.kernel_id]!r} and {m.name!r} share kernel id "
                             f"{m.kernel_id}")  # fmt: skip
        seen[m.kernel_id] = m.name
        rk = m.family == "runge-kutta" and 0 <= m.kernel_id < len(RK_TABLEAUX)
        if not (rk or (m.family != "runge-kutta" and m.kernel_id in RUN_KERNELS)):
            raise ValueError(f"method {m.name!r}: kernel id {m.kernel_id} names no run kernel")


check_kernel_ids(METHODS)


def check_model(
    method: Method, model: Model, scene: Scene | None = None, story: bool = False
) -> None:
    """Refuse (ValueError) a method that cannot serve ``model`` (in one launch's ``story``, or
    a map), with the model's reasons and the methods that can."""
    why = method.model_refusals(model, scene, story)
    if why:
        able = [m.name for m in METHODS.values() if not m.model_refusals(model, scene, story)]
        raise ValueError(
            f"method {method.name!r} cannot serve the {model.name} model ({'; '.join(why)}); "
            f"methods that can: {', '.join(able) or 'none'}"
        )


#: The models, by name (the cone, and any surface of revolution).
MODEL_BY_NAME = {m.name: m for m in MODELS}


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

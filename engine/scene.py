"""The physical scene: the sphere, the cone's surroundings and which effects are simulated.

The fields after ``k`` each call for an effect of the effects table
(:data:`engine.kernels.effects.EFFECTS`): the row names the field, how it switches the effect on
(its ``switch``: a coefficient, a limit or a flag, which also says how the field is checked) and
the parameter slots it fills; :attr:`Scene.effects`, :attr:`Scene.effects_mask` and
:meth:`Scene.params` derive from the rows."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from .bounds import BOUNDS_DOC, LIMIT, LIMIT_TEXT, scene_problem
from .kernels.cone import set_alpha
from .kernels.effects import EFFECTS, mask_of
from .kernels.layouts import SLOTS
from .kernels.model import make_params

__all__ = ["Scene"]


def _check_positive(
    name: str, value: float, *, allow_zero: bool = False, divides: bool = False
) -> float:
    """``value`` as a float; ValueError naming the field unless it is a finite real number in
    range: >= 0 (> 0 unless ``allow_zero``) and within the bounds a run's arithmetic takes
    (:func:`engine.bounds.scene_problem`; ``divides``: the run divides by it). Booleans,
    strings and arrays are not numbers (``Scene(M=True)`` is refused)."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise ValueError(f"Scene.{name} must be a real number, got {value!r}")
    try:
        v = float(value)
    except OverflowError:  # an int beyond the doubles
        raise ValueError(f"Scene.{name} must be finite, got {value!r}") from None
    if math.isnan(v) or math.isinf(v):
        raise ValueError(f"Scene.{name} must be finite, got {value!r}")
    if v < 0 or (v == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"Scene.{name} must be {bound}, got {value!r}")
    if problem := scene_problem(v, divides=divides):
        raise ValueError(f"Scene.{name} {problem}, got {value!r}")
    return v


def _switched_on(switch: str, value: Any) -> bool:
    """Whether a scene field's value calls for its effect (``switch``: see
    :data:`engine.kernels.effects.SWITCHES`)."""
    if switch == "coefficient":
        return value > 0
    if switch == "limit":
        return value is not None
    return bool(value)


@dataclass(frozen=True)
class Scene:
    """A sphere of mass ``M`` [kg] and radius ``a`` [m] rolling inside a cone.

    Parameters
    ----------
    M : mass [kg], > 0.
    g : gravity [m s-2], >= 0 (0: a freely falling cone).
    a : sphere radius [m], > 0 (enters only the attitude and the real cone's vertex).
    k : inertia factor I/(M a^2), >= 0 (0.4 solid sphere, 2/3 thin shell, 0 point particle).
    rim : slant length [m] of the real cone from its vertex to its edge, as a user measures it
        (the centre is then at rim - a cot(alpha) on its own cone); None = an infinite cone.
    mu : friction coefficient for the slip check, > 0; None = no slip check.
    c_rr : rolling-resistance coefficient, >= 0 (0 = none).
    attitude : integrate the sphere's orientation (a unit quaternion) in simulations.
    mu_k : kinetic friction coefficient, 0 < mu_k <= mu (needs ``mu`` and k > 0); None = a slip
        ends the run (``slipped``). Naming it turns the slip into a transition: the sphere
        slides, and may roll again (docs/physics.md "Sliding, rolling again, and spin friction").
    c_spin : spin-friction coefficient, >= 0 (0 = none): a couple c_spin a N against the spin
        about the contact normal, while rolling and while sliding (needs ``mu_k``).
    """

    M: float = 1.0
    g: float = 9.81
    a: float = 0.01
    k: float = 0.4
    rim: float | None = None
    mu: float | None = None
    c_rr: float = 0.0
    attitude: bool = False
    mu_k: float | None = None
    c_spin: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "M", _check_positive("M", self.M, divides=True))
        set_(self, "g", _check_positive("g", self.g, allow_zero=True))
        set_(self, "a", _check_positive("a", self.a, divides=True))
        set_(self, "k", _check_positive("k", self.k, allow_zero=True))
        if self.M * self.g > LIMIT:  # the weight: every normal force and potential energy
            raise ValueError(
                f"Scene.g makes the weight M g = {self.M * self.g:.3g} N: beyond the "
                f"{LIMIT_TEXT} a run holds ({BOUNDS_DOC}), got {self.g!r}"
            )
        for effect in EFFECTS:
            name = effect.scene_field
            value = getattr(self, name)
            if effect.switch == "flag":
                if not isinstance(value, bool):
                    raise ValueError(f"Scene.{name} must be true or false, got {value!r}")
            elif effect.switch == "coefficient":
                set_(self, name, _check_positive(name, value, allow_zero=True))
            elif value is not None:  # a limit
                set_(self, name, _check_positive(name, value))
        if self.mu_k is not None:
            if self.mu is None:
                raise ValueError(
                    f"Scene.mu_k = {self.mu_k!r} needs the static coefficient Scene.mu (mu_k <= mu)"
                )
            if self.mu_k > self.mu:
                raise ValueError(
                    f"Scene.mu_k must be <= Scene.mu (kinetic friction does not exceed static "
                    f"friction), got mu_k = {self.mu_k!r} > mu = {self.mu!r}"
                )
            if self.k == 0:
                raise ValueError(
                    "Scene.mu_k needs k > 0: a sliding sphere's rotation is followed, and a "
                    "body with k = 0 has none"
                )
            if self.attitude:
                raise ValueError("Scene.mu_k cannot be combined with attitude = true (yet)")
        if self.c_spin > 0 and self.mu_k is None:
            raise ValueError(
                f"Scene.c_spin = {self.c_spin!r} needs Scene.mu_k (spin friction is part of "
                "the sliding model)"
            )

    @property
    def effects(self) -> tuple[str, ...]:
        """Names of the effects beyond the ideal cone that this scene calls for (in the order of
        the effects table)."""
        on = (e for e in EFFECTS if _switched_on(e.switch, getattr(self, e.scene_field)))
        return tuple(e.name for e in on)

    @property
    def effects_mask(self) -> int:
        """The effects as the bit mask the kernels compile in (``engine.kernels.effects``)."""
        return mask_of(self.effects)

    def effect_slots(self) -> dict[str, float]:
        """The effects' parameter slots (names of ``engine.kernels.layouts.SLOTS``) and their
        values: each effect's Scene field (a limit not given: +inf)."""
        out = {}
        for effect in EFFECTS:
            value = getattr(self, effect.scene_field)
            for slot in effect.params:
                out[slot] = math.inf if value is None else float(value)
        return out

    def params(self, alpha: float = math.pi / 4) -> np.ndarray:
        """The float64 parameter array of the kernels (layout ``engine.kernels.layouts``) on a
        cone of half-aperture ``alpha`` [rad] (batch kernels replace alpha per point)."""
        named = self.effect_slots()
        slots = np.array([SLOTS[name] for name in named], np.int64)
        values = np.array(list(named.values()), np.float64)
        p = make_params(self.M, self.g, self.k, self.a, slots, values)
        set_alpha(p, alpha)
        return p

    @property
    def mu_or_inf(self) -> float:
        """The friction coefficient as a float, +inf without a slip check."""
        return math.inf if self.mu is None else float(self.mu)

    @property
    def rim_or_inf(self) -> float:
        """The rim as a float, +inf for an infinite cone."""
        return math.inf if self.rim is None else float(self.rim)

    def as_attrs(self) -> dict[str, float | int | str]:
        """Scene parameters as netCDF-safe attributes (no None, no bool)."""
        out: dict[str, float | int | str] = {}
        for f in fields(self):
            if f.name.startswith("_"):
                continue
            v = getattr(self, f.name)
            if v is None:
                out[f"scene_{f.name}"] = "none"
            elif isinstance(v, bool):
                out[f"scene_{f.name}"] = int(v)
            else:
                out[f"scene_{f.name}"] = v
        return out


def _check_fields() -> None:
    """Every effect of the effects table has its Scene field (a row without one fails here, at
    import, not when a scene is first made)."""
    names = {f.name for f in fields(Scene)}
    missing = [f"{e.name} ({e.scene_field})" for e in EFFECTS if e.scene_field not in names]
    if missing:
        raise ValueError(f"effects without a Scene field: {', '.join(missing)}")


_check_fields()

"""The numbers a run can hold: bounds on the inputs whose physics would leave float64.

A run's arithmetic squares speeds, lengths and angular momenta (A = L_z^2 (...) / (2 M sin^2
alpha), v^2 / r, the error norms) and multiplies energies by squared lengths (the cubic of the
turning points, C r^3 = (C r) r^2). So that every such product stays finite with room to spare,
each of these numbers is held to at most :data:`LIMIT` = 1e150 in SI units (a product of two is
then at most 1e300, under float64's 1.8e308), and a number the run divides by (M, a) to at
least :data:`SMALLEST` = 1e-150:

- a scene's numbers (:func:`scene_problem`, asked by :class:`engine.Scene`);
- a launch's (:func:`check_launch`: ``engine.story``, ``engine.story.launch_fates``,
  :func:`engine.launch_survey`, a survey file's launch axes, ``engine.simulate``'s release):
  each squared speed [m2 s-2], kinetic, spin and potential energy [J], its distance from the
  vertex [m], its angular momentum [kg m2 s-1] and the normal force at its start [N].

A bound crossed is refused naming the field, never run into ``failed``, ``no_orbit`` or a
step budget spent on infinities (docs/api.md, "Input bounds"). The maps over invariants
(:func:`engine.evaluate`, :func:`engine.survey`) keep their class ``out_of_range`` per point.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np

from .errortext import PlanError

__all__ = [
    "LIMIT",
    "LIMIT_TEXT",
    "SMALLEST",
    "SMALLEST_TEXT",
    "BOUNDS_DOC",
    "check_launch",
    "launch_extremes",
    "scene_problem",
]

#: The largest magnitude of an energy [J], force [N], length [m], squared speed [m2 s-2],
#: angular momentum [kg m2 s-1] or scene number a run holds.
LIMIT = 1e150
#: The smallest magnitude of a number a run divides by (Scene.M, Scene.a).
SMALLEST = 1e-150
#: The bounds as the messages write them.
LIMIT_TEXT, SMALLEST_TEXT = "1e150", "1e-150"
#: Where the bounds are explained (every refusal names it).
BOUNDS_DOC = 'docs/api.md, "Input bounds"'
#: The launch fields, in the order of a launch map's axes.
LAUNCH_FIELDS = ("alpha", "r0", "v0", "w0", "u0", "slip_u", "backspin", "slip_v")


def scene_problem(value: float, *, divides: bool = False) -> str:
    """What is wrong with a scene number ``value`` (finite, in range otherwise) for the run's
    arithmetic: "" if nothing."""
    if abs(value) > LIMIT:
        return f"must be at most {LIMIT_TEXT} ({BOUNDS_DOC})"
    if divides and abs(value) < SMALLEST:
        return f"must be at least {SMALLEST_TEXT}: the run divides by it ({BOUNDS_DOC})"
    return ""


class Body(Protocol):
    """What the bounds read of a scene (:class:`engine.Scene`, which imports this module):
    its mass M [kg], gravity g [m s-2] and inertia factor k."""

    @property
    def M(self) -> float: ...
    @property
    def g(self) -> float: ...
    @property
    def k(self) -> float: ...


def _terms(v: Mapping[str, np.ndarray], scene: Body) -> list[tuple[str, str, str, Any]]:
    """(field named, what, unit, values) of each number a launch puts into a run, in the order
    they are checked: a field's own terms before those it shares (a huge v0 is named for its
    energy before the angular momentum it makes with r0)."""
    M, g, k = scene.M, scene.g, scene.k
    zero = np.zeros(())
    alpha = v.get("alpha", zero)
    s, c = np.sin(alpha), np.cos(alpha)
    r0, v0 = v.get("r0", zero), v.get("v0", zero)
    out = []
    speeds = [n for n in ("u0", "v0", "w0", "slip_u", "backspin", "slip_v") if n in v]
    for n in speeds:
        out.append((n, f"squared speed {n}^2", "m2 s-2", v[n] * v[n]))
    for n in speeds:
        if n == "w0":
            out.append((n, "spin energy 1/2 k M w0^2", "J", 0.5 * k * M * v[n] * v[n]))
        else:
            out.append((n, f"kinetic energy 1/2 (1+k) M {n}^2", "J",
                        0.5 * (1.0 + k) * M * v[n] * v[n]))  # fmt: skip
    if "r0" in v:
        out.append(("r0", "distance from the vertex r0", "m", r0))
        out.append(("r0", "potential energy M g r0 cos(alpha)", "J", M * g * r0 * c))
    if "r0" in v and "v0" in v:
        cot = c / s
        spin = 0.5 * k / (1.0 + k) * M * v0 * v0 * cot * cot
        out.append(("alpha", "spin energy of rolling round the cone, 1/2 k/(1+k) M v0^2 "
                    "cot(alpha)^2", "J", spin))  # fmt: skip
        which = np.where(np.abs(r0) >= np.abs(v0), "r0", "v0")
        out.append((which, "angular momentum L_z = M r0 v0 sin(alpha)", "kg m2 s-1",
                    M * r0 * v0 * s))  # fmt: skip
        out.append(("r0", "normal force of its motion M v0^2 cot(alpha) / r0", "N",
                    M * v0 * v0 * cot / r0))  # fmt: skip
    return out


def check_launch(values: Mapping[str, Any], scene: Body) -> None:
    """A :class:`PlanError` naming the field of the first launch number beyond :data:`LIMIT`
    (or not finite): ``values`` maps launch fields (:data:`LAUNCH_FIELDS`, any subset) to
    numbers or arrays that broadcast together, each finite already (a survey grid passes its
    axes' extremes: :func:`launch_extremes`)."""
    v = {n: np.asarray(x, np.float64) for n, x in values.items()}
    shape = np.broadcast_shapes(*(a.shape for a in v.values()))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        terms = _terms(v, scene)
    for field, what, unit, x in terms:
        size = np.broadcast_to(np.abs(x), shape)
        bad = ~(size <= LIMIT)
        if not bad.any():
            continue
        at = np.unravel_index(int(np.argmax(bad)), shape) if shape else ()
        name = str(np.broadcast_to(np.asarray(field), shape)[at])
        value = np.broadcast_to(v[name], shape)[at].item()
        got = float(size[at])
        raise PlanError(
            name,
            f"makes the launch's {what} = {got:.3g} {unit}: beyond the {LIMIT_TEXT} a run "
            f"holds ({BOUNDS_DOC})" if math.isfinite(got) else
            f"makes the launch's {what} overflow: beyond the {LIMIT_TEXT} a run holds "
            f"({BOUNDS_DOC})",
            value,
        )  # fmt: skip


def launch_extremes(dims: tuple[str, ...], axes: tuple[np.ndarray, ...]) -> dict[str, Any]:
    """The launch axes of a grid reduced to their two extreme values each, on orthogonal dims
    (a grid of 2^n points): each number :func:`check_launch` bounds is monotone in each
    axis's value, or in its magnitude, so the grid's largest is at these corners."""
    names = [n for n in dims if n in LAUNCH_FIELDS]
    ends = [np.array([a.min(), a.max()]) for n, a in zip(dims, axes, strict=True) if n in names]
    return dict(zip(names, np.ix_(*ends), strict=True))

"""The output vocabulary: every axis, variable, dtype, unit, CF flag table and global attribute
that conesurvey writes, and which variables a (method, scene) produces.

The API (:func:`engine.evaluate`, :func:`engine.survey`), the streamed survey runs and
:func:`engine.simulate` all read their names and attributes from here; nothing else defines an
output name. Units follow CF/UDUNITS (``radian``, ``m s-1``, ``"1"`` for dimensionless); no CF
standard_name fits these quantities, so none is invented. Flag variables are int8 with int8
``flag_values`` and space-separated ``flag_meanings`` (CF 1.11, section 3.5).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ._version import __version__
from .kernels.effects import BY_NAME, EFFECTS
from .methods import METHODS, MODEL_BY_NAME, get_method
from .variables import (
    AXES,
    CLOSED_FORM,
    ENERGY_RELATIVE,
    FATE,
    FATE_COMMENTS,
    FATE_KINDS,
    INTEGRATED,
    INVARIANTS,
    MAP_KINDS,
    REPLACED_BY_INTEGRATION,
    RESULTS,
    SLIDING_FATE,
    SURFACE_AXES,
    SURFACE_CLASS,
    SURFACE_EXACT,
    SURFACE_FATE,
    SURFACE_KIND,
    TRAJECTORY,
    Variable,
)

if TYPE_CHECKING:
    from .horizon import Horizon
    from .scene import Scene
    from .surfaces import Surface

# the output variables are defined in engine.variables and re-exported here, where every
# layer has always asked for them
__all__ = [
    "DIMS",
    "LAUNCH_DIMS",
    "GRID_DIMS",
    "RELEASE",
    "RELEASE_AXES",
    "FINGERPRINT_ATTR",
    "Variable",
    "AXES",
    "RESULTS",
    "TRAJECTORY",
    "axis_attrs",
    "variable_attrs",
    "variable_dims",
    "result_variables",
    "result_attrs",
    "survey_attrs",
    "map_kind",
    "map_summary",
    "grid_dims",
    "launch_dims",
    "CLOSED_FORM",
    "ENERGY_RELATIVE",
    "FATE",
    "FATE_COMMENTS",
    "FATE_KINDS",
    "INTEGRATED",
    "INVARIANTS",
    "MAP_KINDS",
    "REPLACED_BY_INTEGRATION",
    "SLIDING_FATE",
    "SURFACE_FATE",
    "SURFACE_AXES",
    "SURFACE_CLASS",
    "SURFACE_EXACT",
    "SURFACE_KIND",
]

#: The four survey axes, in the order of a survey's dims.
DIMS = ("alpha", "energy", "h", "Lz")
#: The axes of a survey over launch states (the sphere released with u = 0).
LAUNCH_DIMS = ("alpha", "r0", "v0", "w0")
#: How a launch on a scene with kinetic friction (``Scene.mu_k``) may differ from rolling: the
#: radial speed and the contact point's slip velocity at release (axes of its launch grid).
RELEASE = ("u0", "slip_u", "slip_v")
#: The axes of a survey over launch states on a scene with kinetic friction, each release
#: value an axis (one not given as an axis is none: a grid has any of them, in this order).
SLIDING_LAUNCH_DIMS = (*LAUNCH_DIMS, *RELEASE)
#: The launch axes a grid may add after (alpha, r0, v0, w0), in this order: the release values
#: and ``backspin`` = slip_u - u0, which spans the slip beyond the radial speed (slip_u or
#: backspin, not both).
RELEASE_AXES = ("u0", "slip_u", "backspin", "slip_v")


def _release_grids() -> tuple[tuple[str, ...], ...]:
    subsets = (tuple(n for i, n in enumerate(RELEASE_AXES) if b >> i & 1) for b in range(1, 16))
    return tuple((*LAUNCH_DIMS, *s) for s in subsets if not {"slip_u", "backspin"} <= set(s))


#: Every kind of survey grid over the cone, by its dims: the one place that lists them.
GRID_DIMS = (DIMS, LAUNCH_DIMS, *_release_grids())
#: Global attribute of a finished survey file holding the survey's fingerprint.
FINGERPRINT_ATTR = "survey_fingerprint"


def _check_effect_variables() -> None:
    for e in EFFECTS:
        for out, names in e.variables:
            table = TRAJECTORY if out == "trajectory" else RESULTS  # fate: RESULTS too
            unknown = [n for n in names if n not in table]
            assert not unknown, f"effect {e.name}: no {out} variable {unknown} in engine.schema"


_check_effect_variables()


def axis_attrs(name: str, energy_relative: bool = False) -> dict[str, Any]:
    """``units`` and ``long_name`` of a survey axis (the energy axis may be relative)."""
    if name == "energy" and energy_relative:
        return ENERGY_RELATIVE.attrs()
    return AXES[name].attrs()


def variable_attrs(name: str, kind: str | None = None) -> dict[str, Any]:
    """CF attributes of a result or trajectory variable (in a map of ``kind``, with a comment
    saying where its values come from)."""
    var = RESULTS.get(name) or TRAJECTORY[name]
    if name == "fate" and kind == "sliding fate":
        var = SLIDING_FATE
    if name == "fate" and kind == "surface fate":
        var = SURFACE_FATE
    if name == "orbit_class" and kind in SURFACE_KIND.values():
        var = SURFACE_CLASS
    attrs = var.attrs()
    if kind in FATE_KINDS and name in FATE_COMMENTS:
        attrs["comment"] = FATE_COMMENTS[name]
    return attrs


def variable_dims(name: str, dims: tuple[str, ...]) -> tuple[str, ...]:
    """The dims ``name`` is stored on in a survey of grid ``dims``: the axes it depends on
    (``Variable.depends``; r_circ, V_min: alpha, h, Lz) on the invariants' grid, else all."""
    var = RESULTS.get(name)
    if var is None or var.depends is None or tuple(dims) != DIMS:
        return tuple(dims)
    return tuple(d for d in dims if d in var.depends)


def flag_table(name: str, kind: str | None = None) -> tuple[tuple[int, str], ...]:
    """(code, meaning) of each flag of the flag variable ``name`` in a map of ``kind``."""
    attrs = variable_attrs(name, kind)
    return tuple(zip(attrs["flag_values"].tolist(), attrs["flag_meanings"].split(), strict=True))


def flag_count(name: str) -> int:
    """How many codes (0 .. n-1) the flag variable ``name`` may take in any kind of map."""
    top = max(max(c for c, _ in flag_table(name, kind)) for kind in MAP_KINDS)
    return top + 1


def grid_dims(names: Any) -> tuple[str, ...]:
    """The dims of :data:`GRID_DIMS` whose axes are in ``names`` (a Dataset's, a file's)."""
    present = set(names)
    if present & {"rho0", "z0"}:
        return tuple(d for d in SURFACE_AXES if d in present)
    if present & set(RELEASE_AXES):
        return (*LAUNCH_DIMS, *(n for n in RELEASE_AXES if n in present))
    return LAUNCH_DIMS if "r0" in present else DIMS


def surface_dims(surface: Surface, swept: Any = ()) -> tuple[str, ...]:
    """The dims of a survey over launches on ``surface``: the parameters it sweeps (``swept``,
    in the surface's order), then its launch position (rho0, or the cylinder's z0), v0, w0."""
    params = tuple(p for p in surface.parameters if p in set(swept))
    return (*params, surface.position, "v0", "w0")


def is_surface_grid(dims: tuple[str, ...]) -> bool:
    """Whether ``dims`` are a surface survey's (:func:`surface_dims`)."""
    dims = tuple(dims)
    return (
        len(dims) >= 3
        and dims[-3:] in (("rho0", "v0", "w0"), ("z0", "v0", "w0"))
        and all(d in SURFACE_AXES for d in dims)
        and list(dims) == [d for d in SURFACE_AXES if d in dims]
    )


def launch_dims(scene: Scene, release: Any = ()) -> tuple[str, ...]:
    """The dims of a survey over launch states of ``scene`` with the release values named in
    ``release`` as axes (in the order of :data:`RELEASE_AXES`; only with kinetic friction)."""
    sliding = "sliding" in scene.effects
    return (*LAUNCH_DIMS, *(n for n in RELEASE_AXES if n in release and sliding))


def effect_variables(scene: Scene, output: str) -> tuple[str, ...]:
    """The variables the effects of ``scene`` add to ``output`` ("closed form", "period",
    "fate" or "trajectory": :data:`engine.kernels.effects.OUTPUTS`), from the effects table,
    each once."""
    names: list[str] = []
    for name in scene.effects:
        for out, added in BY_NAME[name].variables:
            names += [v for v in added if out == output and v not in names]
    return tuple(names)


def period_variables(scene: Scene) -> tuple[str, ...]:
    """What one integrated radial period reports (``engine.integrated.evaluate_integrated``)."""
    return (*REPLACED_BY_INTEGRATION, "energy_drift", *effect_variables(scene, "period"))


def map_kind(method: str, scene: Scene, surface: Surface | None = None) -> str:
    """What a map of ``scene`` by ``method`` is (:data:`MAP_KINDS`): integrators follow a scene
    with a dissipative effect or one that brings terminal events (the effects table) to each
    orbit's fate; otherwise over one period. On a ``surface`` of revolution, the surface's
    kind of the same map (:data:`SURFACE_KIND`)."""
    if surface is not None:
        return SURFACE_KIND[map_kind(method, scene)]
    if not get_method(method).integrates:
        return "closed form"
    if any("sliding contact" in BY_NAME[e].needs for e in scene.effects):
        return "sliding fate"
    if any(BY_NAME[e].dissipative or BY_NAME[e].events for e in scene.effects):
        return "fate"
    return "one period"


def result_variables(
    method: str,
    scene: Scene,
    energy_relative: bool = False,
    launch: bool = False,
    surface: Surface | None = None,
) -> dict[str, np.dtype]:
    """Names and dtypes of the variables a map of ``scene`` by ``method`` holds, in file order
    (``launch``: a survey over launch states, which stores the invariants too; on a
    ``surface``: Routh's exact variables, then the integrator's)."""
    if surface is not None:
        kind = map_kind(method, scene)
        names = list(SURFACE_EXACT)
        if kind == "one period":
            names += INTEGRATED
        elif kind == "fate":
            names += FATE
        return {n: np.dtype(RESULTS[n].dtype) for n in names}
    kind = map_kind(method, scene)
    names = list(CLOSED_FORM)
    if kind == "closed form":
        names += effect_variables(scene, "closed form")
    elif kind == "one period":
        names += INTEGRATED
    elif kind in FATE_KINDS:
        names += FATE
        names += effect_variables(scene, "fate")
    if energy_relative:  # calE = V_min + energy |V_min| (the accessor's energy_absolute)
        names.append("V_min")
    if launch:
        names += INVARIANTS
    return {n: np.dtype(RESULTS[n].dtype) for n in names}


def map_summary(
    method: str,
    scene: Scene,
    energy_relative: bool = False,
    launch: bool = False,
    surface: Surface | None = None,
) -> list[str]:
    """What a map of ``scene`` by ``method`` will hold, in lines for people (``conesurvey
    validate``): which methods honour each effect the scene names, the kind of map, its
    variables."""
    lines = []
    for effect in scene.effects:
        model = MODEL_BY_NAME["surface" if surface is not None else "cone"]
        able = [m.name for m in METHODS.values()
                if m.honours(effect) and not m.model_refusals(model)]  # fmt: skip
        lines.append(f"effect {effect}: honoured by {', '.join(able)}")
    if surface is not None:
        lines.append(f"surface {surface.kind}: rim is {surface.rim_means}")
    kind = map_kind(method, scene, surface)
    lines.append(f"map    {kind}: {MAP_KINDS[kind]}")
    names = result_variables(method, scene, energy_relative, launch, surface)
    lines.append("holds  " + ", ".join(names))
    return lines


def result_attrs(
    scene: Scene, method: str, circular_tol: float, rtol: float, horizon: Horizon | None = None
) -> dict[str, Any]:
    """Global attributes of a map: source, method, what kind of map it is, tolerances, the
    horizon of a fate map, the scene's parameters."""
    kind = map_kind(method, scene)
    attrs: dict[str, Any] = {
        "source": f"conesurvey {__version__}",
        "method": method,
        "map_kind": kind,
        "map_description": MAP_KINDS[kind],
        "circular_tol": circular_tol,
    }
    if get_method(method).integrates:
        attrs["rtol"] = rtol
    if horizon is not None:
        attrs.update(horizon.as_attrs())
    attrs.update(scene.as_attrs())
    return attrs


def survey_attrs(
    scene: Scene,
    method: str,
    circular_tol: float,
    rtol: float,
    energy_relative: bool,
    horizon: Horizon | None = None,
    launch: bool = False,
) -> dict[str, Any]:
    """Global attributes of a survey (:func:`result_attrs` plus what its axes are)."""
    attrs = result_attrs(scene, method, circular_tol, rtol, horizon)
    if launch and "sliding" in scene.effects:
        attrs["grid"] = ("launch states: released at r0 with radial speed u0, speed v0, spin w0 "
                         "and the contact point's slip velocity (slip_u, slip_v)")  # fmt: skip
        return attrs
    if launch:
        attrs["grid"] = "launch states: released at r0 with radial speed 0, speed v0, spin w0"
        return attrs
    attrs["energy_axis"] = "relative to V_min" if energy_relative else "absolute"
    return attrs

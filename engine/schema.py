"""The output vocabulary: every axis, variable, dtype, unit, CF flag table and global attribute
that conesurvey writes, and which variables a (method, scene) produces.

The API (:func:`engine.evaluate`, :func:`engine.survey`), the streamed survey runs and
:func:`engine.simulate` all read their names and attributes from here; nothing else defines an
output name. Units follow CF/UDUNITS (``radian``, ``m s-1``, ``"1"`` for dimensionless); no CF
standard_name fits these quantities, so none is invented. Flag variables are int8 with int8
``flag_values`` and space-separated ``flag_meanings`` (CF 1.11, section 3.5).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ._version import __version__
from .kernels.effects import BY_NAME, EFFECTS
from .kernels.fate import FATE_NAMES
from .kernels.geometry import CLASS_NAMES
from .kernels.hybrid import HYBRID_FATE_NAMES
from .kernels.protocol import EVENT_NAMES, STATUS_FLAGS
from .methods import METHODS, get_method

if TYPE_CHECKING:
    from .horizon import Horizon
    from .scene import Scene

__all__ = ["DIMS", "LAUNCH_DIMS", "GRID_DIMS", "RELEASE", "FINGERPRINT_ATTR", "Variable", "AXES",
           "RESULTS", "TRAJECTORY", "axis_attrs", "variable_attrs", "variable_dims",
           "result_variables", "result_attrs", "survey_attrs", "map_kind", "map_summary",
           "grid_dims", "launch_dims"]  # fmt: skip

#: The four survey axes, in the order of a survey's dims.
DIMS = ("alpha", "energy", "h", "Lz")
#: The axes of a survey over launch states (the sphere released with u = 0).
LAUNCH_DIMS = ("alpha", "r0", "v0", "w0")
#: How a launch on a scene with kinetic friction (``Scene.mu_k``) may differ from rolling: the
#: radial speed and the contact point's slip velocity at release (axes of its launch grid).
RELEASE = ("u0", "slip_u", "slip_v")
#: The axes of a survey over launch states on a scene with kinetic friction.
SLIDING_LAUNCH_DIMS = (*LAUNCH_DIMS, *RELEASE)
#: Every kind of survey grid, by its dims: the one place that lists them.
GRID_DIMS = (DIMS, LAUNCH_DIMS, SLIDING_LAUNCH_DIMS)
#: The invariants a survey over launch states stores as variables.
INVARIANTS = ("energy", "h", "Lz")
#: Global attribute of a finished survey file holding the survey's fingerprint.
FINGERPRINT_ATTR = "survey_fingerprint"


@dataclass(frozen=True)
class Variable:
    """One output variable: dtype, units (None for flag variables), long name, CF flags."""

    dtype: str
    units: str | None
    long_name: str
    flags: tuple[str, ...] | None = None
    #: The flags' codes (None: 0, 1, ... in order).
    codes: tuple[int, ...] | None = None
    #: The axes of the (alpha, energy, h, L_z) grid it depends on (None: every axis); it is
    #: stored on those dims only (:func:`variable_dims`).
    depends: tuple[str, ...] | None = None

    def attrs(self) -> dict[str, Any]:
        """CF attributes: units and long_name, or long_name and int8 flag_values/meanings."""
        out: dict[str, Any] = {}
        if self.units is not None:
            out["units"] = self.units
        out["long_name"] = self.long_name
        if self.flags is not None:
            codes = range(len(self.flags)) if self.codes is None else self.codes
            out["flag_values"] = np.array(codes, dtype=self.dtype)
            out["flag_meanings"] = " ".join(self.flags)
        return out


def _f(units: str, long_name: str, depends: tuple[str, ...] | None = None) -> Variable:
    return Variable("float64", units, long_name, depends=depends)


#: The survey axes (also the coordinates of :func:`engine.evaluate`'s results).
AXES: dict[str, Variable] = {
    "alpha": _f("radian", "half-aperture of the cone"),
    "energy": _f("J", "radial energy calE = E/(1+k) - k M h^2/(2(1+k))"),
    "h": _f("m s-1", "spin invariant h = w - L_z cos(alpha)/(M r sin^2 alpha)"),
    "Lz": _f("kg m2 s-1", "axial angular momentum of the centre of mass"),
    "r0": _f("m", "launch radius: distance of the centre from the vertex of its cone"),
    "v0": _f("m s-1", "launch azimuthal speed r sin(alpha) dtheta/dt (radial speed 0)"),
    "w0": _f("m s-1", "launch spin about the normal times the radius, a omega_nu"),
    "u0": _f("m s-1", "launch radial speed dr/dt along the generatrix (outward > 0)"),
    "slip_u": _f("m s-1", "launch slip velocity of the contact point along the generatrix"),
    "slip_v": _f("m s-1", "launch slip velocity of the contact point along the parallel"),
}
_FAM = ("alpha", "h", "Lz")  # what a property of an (alpha, h, L_z) family depends on
_ENERGY_RELATIVE = _f("1", "energy offset from the potential minimum, (calE - V_min)/|V_min|")

#: Every result variable of a map, in file order.
RESULTS: dict[str, Variable] = {
    "orbit_class": Variable("int8", None, "orbit class", CLASS_NAMES),
    "r_min": _f("m", "inner turning point (distance from the vertex of the centre's cone)"),
    "r_max": _f("m", "outer turning point (+inf for escaping orbits)"),
    "r_circ": _f("m", "radius of the circular orbit (minimum of the effective potential)", _FAM),
    "period": _f("s", "radial period (time from r_max to the next r_max)"),
    "apsidal_angle": _f(
        "radian", "azimuth swept from r_min to r_max (to infinity for escaping orbits)"
    ),
    "precession_rate": _f("radian s-1", "apsidal precession rate (2 psi - 2 pi) / T_r"),
    "mu_required": _f("1", "smallest friction coefficient that keeps the sphere rolling"),
    # the closed form on a cone with a rim or a friction limit
    "end_r": _f("m", "where rolling on this cone ends (slip onset or the rim), from r_min out"),
    "end_time": _f("s", "time from r_min to where rolling on this cone ends"),
    "end_theta": _f("radian", "azimuth swept from r_min to where rolling on this cone ends"),
    # one-period maps of an integrator
    "n_steps": Variable("int64", "1", "accepted integrator steps"),
    "energy_drift": _f(
        "1",
        "|E(t) - E(0)| / max(|E(0)|, kinetic energy at start) at the end t of the integration "
        "(r_max: the period is twice the time to it, by time symmetry)",
    ),
    "status": Variable("int8", None, "integrator status", STATUS_FLAGS),
    # fate maps
    "fate": Variable(
        "int8", None, "what happened to the sphere (integration of the scene)", FATE_NAMES
    ),  # fmt: skip
    "fate_time": _f("s", "time from the start to the fate (the horizon if still rolling)"),
    "fate_r": _f("m", "r where the fate happened"),
    "fate_theta": _f("radian", "azimuth swept from the start to the fate"),
    "revolutions": _f("1", "revolutions about the axis completed before the fate"),
    "energy_lost": _f("J", "total energy lost from the start to the fate, E(0) - E(t)"),
    "invariant_drift": _f(
        "1",
        "integration error of the energy balance, |E(t) + W(t) - E(0)| / max(|E(0)|, kinetic "
        "energy at start), W the work done against rolling resistance",
    ),
    # fate maps of a scene with kinetic friction (the sliding model): the effects table adds them
    "slide_time": _f("s", "total time spent sliding from the start to the fate"),
    "slip_episodes": Variable("int32", "1", "times it started sliding (-1: no orbit)"),
    "fate_speed": _f("m s-1", "speed of the centre at the fate (or the horizon)"),
    "final_energy": _f("J", "radial energy calE of the last rolling orbit (NaN: none)"),
    "final_h": _f("m s-1", "spin invariant h of the last rolling orbit (NaN: none)"),
    "final_Lz": _f("kg m2 s-1", "L_z of the last rolling orbit (NaN: none)"),
    "lost_rolling_resistance": _f("J", "energy lost to rolling resistance (both modes)"),
    "lost_sliding_friction": _f("J", "energy lost to kinetic friction (and sticking)"),
    "lost_spin_friction": _f("J", "energy lost to spin friction (both modes)"),
    # surveys with an energy axis relative to V_min: calE = V_min + energy |V_min|
    "V_min": _f("J", "minimum of the effective potential V(r) (NaN: V has none)", _FAM),
    "energy_absolute": _f("J", "radial energy calE (absolute) = V_min + energy |V_min|"),
    # surveys over launch states: the invariants of each launch
    **{name: AXES[name] for name in INVARIANTS},
    # engine.integrated.evaluate_integrated with rolling resistance (one period, not a map)
    "energy_loss": _f("J", "total energy lost over the first radial period"),
}
#: The closed form's variables (every map holds them).
CLOSED_FORM = ("orbit_class", "r_min", "r_max", "r_circ", "period", "apsidal_angle",
               "precession_rate", "mu_required")  # fmt: skip
#: The ``fate`` of a fate map of the sliding model (a slip is a transition, not an end).
_CODES = tuple(i for i, n in enumerate(HYBRID_FATE_NAMES) if n != "slipped")
SLIDING_FATE = Variable("int8", None, "what happened to the sphere (rolling, sliding, ...)",
                        tuple(HYBRID_FATE_NAMES[i] for i in _CODES), _CODES)  # fmt: skip
#: What a one-period integrator map adds; it also replaces period, apsidal angle and precession.
INTEGRATED = ("n_steps", "energy_drift", "status")
#: Closed-form variables a one-period map replaces by the integrator's own values.
REPLACED_BY_INTEGRATION = ("period", "apsidal_angle", "precession_rate")
#: What a fate map adds.
FATE = ("fate", "fate_time", "fate_r", "fate_theta", "revolutions", "energy_lost",
        "invariant_drift", "n_steps")  # fmt: skip

#: The kinds of map, and what each says about its variables (the ``map_kind`` attribute).
MAP_KINDS = {
    "closed form": "every variable is exact (closed form) for the scene's cone",
    "one period": "period, apsidal angle and precession rate integrated over one radial period; "
    "the other variables exact (closed form)",
    "fate": "orbit_class and the orbit's geometry describe the launch orbit on the ideal "
    "lossless cone (closed form); fate and the variables after it describe the scene "
    "(integrated from the start to the first terminal event or the horizon)",
    "sliding fate": "orbit_class and the orbit's geometry describe the rolling launch orbit on "
    "the ideal lossless cone (closed form); fate and the variables after it describe the "
    "scene's whole story (a slip is a transition: the sphere slides under kinetic friction and "
    "may roll again), integrated from the start to spill, rest, the vertex or the horizon",
}
#: The kinds of map that follow each orbit to its fate.
FATE_KINDS = ("fate", "sliding fate")
#: Variable ``comment`` in fate maps: which variables come from where.
_FATE_COMMENTS = {
    **{n: "the launch orbit on the ideal lossless cone (closed form)" for n in CLOSED_FORM},
    **{n: "the scene, integrated" for n in FATE},
    **{n: "the scene, integrated" for n in dict(BY_NAME["sliding"].variables)["fate"]},
}


#: Variables of :func:`engine.simulate` along its ``time`` and ``event`` dims.
TRAJECTORY: dict[str, Variable] = {
    "time": _f("s", "time since the start at r_min"),
    "r": _f("m", "distance of the centre from the vertex of its cone"),
    "theta": _f("radian", "azimuth of the centre (unwrapped)"),
    "u": _f("m s-1", "radial velocity dr/dt along the generatrix"),
    "v": _f("m s-1", "azimuthal velocity r sin(alpha) dtheta/dt"),
    "w": _f("m s-1", "spin about the normal times the radius, a omega_nu"),
    "x": _f("m", "Cartesian x of the centre"),
    "y": _f("m", "Cartesian y of the centre"),
    "z": _f("m", "Cartesian z of the centre (cone axis, up)"),
    "E_drift": _f("J", "total energy minus its initial value"),
    "Lz_drift": _f("kg m2 s-1", "L_z minus its initial value"),
    "h_drift": _f("m s-1", "spin invariant h minus its initial value"),
    "friction_ratio": _f("1", "friction needed over normal force |F|/N (slip where > mu)"),
    **{
        f"quat_{c}": _f("1", f"attitude quaternion, {c} component (body to fixed frame)")
        for c in "wxyz"
    },
    "quat_norm_error": _f("1", "|q| - 1 of the attitude quaternion"),
    "contact_speed": _f(
        "m s-1",
        "speed of the sphere's material point at the contact |R_dot + omega x (-a nu)|, "
        "omega from the quaternion (0 when rolling)",
    ),
    "event_time": _f("s", "time of the event"),
    "event_kind": Variable("int8", None, "event kind", EVENT_NAMES),
    "event_r": _f("m", "r at the event"),
    "event_theta": _f("radian", "theta at the event"),
}


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
        return _ENERGY_RELATIVE.attrs()
    return AXES[name].attrs()


def variable_attrs(name: str, kind: str | None = None) -> dict[str, Any]:
    """CF attributes of a result or trajectory variable (in a map of ``kind``, with a comment
    saying where its values come from)."""
    var = RESULTS.get(name) or TRAJECTORY[name]
    if name == "fate" and kind == "sliding fate":
        var = SLIDING_FATE
    attrs = var.attrs()
    if kind in FATE_KINDS and name in _FATE_COMMENTS:
        attrs["comment"] = _FATE_COMMENTS[name]
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
    """The dims of the survey grid whose axes include ``names`` (a Dataset's dims, a survey
    file's axes): the longest of :data:`GRID_DIMS` all of whose launch axes are named."""
    present = set(names)
    if present & set(RELEASE):
        return SLIDING_LAUNCH_DIMS
    return LAUNCH_DIMS if "r0" in present else DIMS


def launch_dims(scene: Scene) -> tuple[str, ...]:
    """The dims of a survey over launch states of ``scene``: the release's radial speed and
    slip velocity are axes too where it has kinetic friction (the sliding model)."""
    return SLIDING_LAUNCH_DIMS if "sliding" in scene.effects else LAUNCH_DIMS


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


def map_kind(method: str, scene: Scene) -> str:
    """What a map of ``scene`` by ``method`` is (:data:`MAP_KINDS`): integrators follow a scene
    with a dissipative effect or one that brings terminal events (the effects table) to each
    orbit's fate; otherwise over one period."""
    if not get_method(method).integrates:
        return "closed form"
    if any("sliding contact" in BY_NAME[e].needs for e in scene.effects):
        return "sliding fate"
    if any(BY_NAME[e].dissipative or BY_NAME[e].events for e in scene.effects):
        return "fate"
    return "one period"


def result_variables(
    method: str, scene: Scene, energy_relative: bool = False, launch: bool = False
) -> dict[str, np.dtype]:
    """Names and dtypes of the variables a map of ``scene`` by ``method`` holds, in file order
    (``launch``: a survey over launch states, which stores the invariants too)."""
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
    method: str, scene: Scene, energy_relative: bool = False, launch: bool = False
) -> list[str]:
    """What a map of ``scene`` by ``method`` will hold, in lines for people (``conesurvey
    validate``): which methods honour each effect the scene names, the kind of map, its
    variables."""
    lines = []
    for effect in scene.effects:
        able = [m.name for m in METHODS.values() if m.honours(effect)]
        lines.append(f"effect {effect}: honoured by {', '.join(able)}")
    kind = map_kind(method, scene)
    lines.append(f"map    {kind}: {MAP_KINDS[kind]}")
    names = result_variables(method, scene, energy_relative, launch)
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

"""The output variables, as data: every axis, result, trajectory and event variable conesurvey
writes (dtype, units, long name, CF flags, the axes it depends on), the variable lists of each
kind of map and what each kind of map means. :mod:`engine.schema` says which of them a map
holds, and with which attributes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .kernels.effects import BY_NAME
from .kernels.fate import FATE_NAMES
from .kernels.fate_codes import FATE_LIFTED_OFF
from .kernels.geometry import CLASS_NAMES
from .kernels.hybrid import HYBRID_FATE_NAMES
from .kernels.protocol import EVENT_NAMES, STATUS_FLAGS
from .kernels.routh import CLASS_NAMES as SURFACE_CLASS_NAMES

__all__ = ["Variable", "AXES", "RESULTS", "TRAJECTORY", "MAP_KINDS", "FATE_KINDS", "SURFACE_KIND"]


#: The invariants a survey over launch states stores as variables.
INVARIANTS = ("energy", "h", "Lz")


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
    "backspin": _f("m s-1", "launch backspin a omega0 = slip_u - u0, the slip beyond u0"),
    # surveys over launches on a surface of revolution (engine.surfaces)
    "rho0": _f("m", "launch position: distance of the centre from the axis"),
    "z0": _f("m", "launch position: height of the centre (the cylinder)"),
    "radius": _f(
        "m", "the surface's radius (bowl, paraboloid: of curvature at the bottom; cylinder)"
    ),  # fmt: skip
    "scale": _f("1", "the surface's scale (funnel: m2; power law: m(1-n); see surface_kind)"),
    "hole": _f("m", "radius of the funnel's hole"),
    "n": _f("1", "the power law's exponent"),
}
#: The axes of a survey on a surface, in their order: the surface's parameters, then the launch.
SURFACE_AXES = ("alpha", "radius", "scale", "hole", "n", "rho0", "z0", "v0", "w0")
_FAM = ("alpha", "h", "Lz")  # what a property of an (alpha, h, L_z) family depends on
ENERGY_RELATIVE = _f("1", "energy offset from the potential minimum, (calE - V_min)/|V_min|")

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
    "fate_spin": _f("m s-1", "spin a omega_nu about the normal at the fate (or the horizon)"),
    "final_energy": _f("J", "radial energy calE of the last rolling orbit (NaN: none)"),
    "final_h": _f("m s-1", "spin invariant h of the last rolling orbit (NaN: none)"),
    "final_Lz": _f("kg m2 s-1", "L_z of the last rolling orbit (NaN: none)"),
    "lost_effects": _f(
        "J",
        "energy lost to the effects acting through forces: rolling resistance and any "
        "applied effect (both modes)",
    ),
    "lost_sliding_friction": _f("J", "energy lost to kinetic friction (and sticking)"),
    "lost_spin_friction": _f("J", "energy lost to spin friction (both modes)"),
    # surveys with an energy axis relative to V_min: calE = V_min + energy |V_min|
    "V_min": _f("J", "minimum of the effective potential V(r) (NaN: V has none)", _FAM),
    "energy_absolute": _f("J", "radial energy calE (absolute) = V_min + energy |V_min|"),
    # surveys over launch states: the invariants of each launch
    **{name: AXES[name] for name in INVARIANTS},
    # maps on a surface of revolution (Routh's reduction: engine.routh)
    "rho_min": _f(
        "m",
        "inner turning point: the centre's distance from the axis (cylinder: its lowest height)",
    ),  # fmt: skip
    "rho_max": _f(
        "m",
        "outer turning point: the centre's distance from the axis (cylinder: "
        "its highest height; +inf for escaping orbits)",
    ),  # fmt: skip
    "routh_L": _f(
        "kg m2 s-1",
        "Routh's first integral: M rho v at the surface's reference point (on a cone L_z)",
    ),  # fmt: skip
    "routh_w": _f(
        "m s-1",
        "Routh's second integral: w - rho v tan(b)/rho^2 at the surface's "
        "reference point (on a cone h)",
    ),  # fmt: skip
    # engine.integrated.evaluate_integrated with rolling resistance (one period, not a map)
    "energy_loss": _f("J", "total energy lost over the first radial period"),
}
#: The closed form's variables (every map holds them).
CLOSED_FORM = ("orbit_class", "r_min", "r_max", "r_circ", "period", "apsidal_angle",
               "precession_rate", "mu_required")  # fmt: skip
#: The ``fate`` of a fate map of the sliding model (a slip is a transition, not an end; such
#: maps run on the cone, whose normal force never vanishes: no lifted_off).
_CODES = tuple(i for i, n in enumerate(HYBRID_FATE_NAMES) if n not in ("slipped", "lifted_off"))
SLIDING_FATE = Variable("int8", None, "what happened to the sphere (rolling, sliding, ...)",
                        tuple(HYBRID_FATE_NAMES[i] for i in _CODES), _CODES)  # fmt: skip
#: The ``fate`` of a fate map on a surface of revolution: the cone's fates, and lifting off.
SURFACE_FATE = Variable(
    "int8", None, "what happened to the sphere (integration of the scene)",
    (*FATE_NAMES, "lifted_off"), (*range(len(FATE_NAMES)), FATE_LIFTED_OFF),
)  # fmt: skip
#: The exact variables of a map on a surface of revolution (every such map holds them).
SURFACE_EXACT = ("orbit_class", "rho_min", "rho_max", "period", "apsidal_angle",
                 "precession_rate", "routh_L", "routh_w")  # fmt: skip
#: The ``orbit_class`` of a map on a surface of revolution.
SURFACE_CLASS = Variable("int8", None, "orbit class (Routh's reduction)", SURFACE_CLASS_NAMES)
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
    "surface exact": "every variable is exact for the scene's surface (Routh's reduction: the "
    "two linear integrals along the meridian, turning points and quadratures)",
    "surface one period": "period, apsidal angle and precession rate integrated over one "
    "radial period; the other variables exact (Routh's reduction)",
    "surface fate": "orbit_class and the orbit's geometry describe the launch orbit on the "
    "ideal lossless surface (Routh's reduction); fate and the variables after it describe the "
    "scene (integrated from the launch to the first terminal event or the horizon)",
}
#: The kinds of map that follow each orbit to its fate.
FATE_KINDS = ("fate", "sliding fate", "surface fate")
#: The kind of map on a surface of revolution, by the cone's kind of the same map.
SURFACE_KIND = {"closed form": "surface exact", "one period": "surface one period",
                "fate": "surface fate"}  # fmt: skip
#: Variable ``comment`` in fate maps: which variables come from where.
FATE_COMMENTS = {
    **{n: "the launch orbit on the ideal lossless cone (closed form)" for n in CLOSED_FORM},
    **{n: "the scene, integrated" for n in FATE},
    **{n: "the scene, integrated" for n in dict(BY_NAME["sliding"].variables)["fate"]},
}


#: Variables of :func:`engine.simulate` along its ``time`` and ``event`` dims.
TRAJECTORY: dict[str, Variable] = {
    "time": _f("s", "time since the start at r_min"),
    "r": _f("m", "distance of the centre from the vertex of its cone"),
    "q": _f("1", "the surface's meridian parameter of the contact (engine.kernels.meridian)"),
    "rho": _f("m", "distance of the centre from the axis"),
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
    "event_rho": _f("m", "the centre's distance from the axis at the event"),
    "event_theta": _f("radian", "theta at the event"),
}

"""One trajectory of the rolling sphere, integrated and returned as an xarray Dataset."""

from __future__ import annotations

import math
from numbers import Real
from typing import Any

import numpy as np
import xarray as xr

from ._version import __version__
from .checks import (
    PlanError,
    check_launch,
    check_max_steps,
    check_method,
    check_number,
    check_positive,
    check_release,
    check_rtol,
    check_scene,
)
from .kernels.cone import (
    coefficients,
    contact_forces_of,
    contact_velocity,
    invariants,
    invariants_of,
)
from .kernels.cone_starts import initial_state, orbit_start, tolerance_scales
from .kernels.fate import REST_SPEED
from .kernels.geometry import BOUNDED, CIRCULAR, CIRCULAR_TOL, CLASS_NAMES, HYPERBOLIC, ideal_orbit
from .kernels.layouts import ATTITUDE, P_V_REST
from .kernels.protocol import (
    FAILURE,
    HORIZON,
    NORMAL_ENDS,
    OK,
    RECORD_EVERY_DT,
    RECORD_STEPS,
    STATUS_MESSAGES,
)
from .kernels.roots import free_fall_r_min
from .methods import DEFAULT_RTOL, MODEL_BY_NAME, check_model
from .scene import Scene
from .schema import TRAJECTORY, effect_variables
from .simulate_hybrid import hybrid_trajectory
from .simulate_surface import check_surface_launch, simulate_surface
from .surfaces import Surface
from .trajectory_run import TrajectoryRun

__all__ = ["simulate", "DEFAULT_MAX_STEPS"]

#: Step budget of one simulation (a guard against runaway runs, not a tuning knob).
DEFAULT_MAX_STEPS = 100_000_000


def _capacities(alpha, energy, h, Lz, scene, t_end, periods, dt_out) -> tuple[int, int]:
    """First guess of the event and trajectory buffer sizes (grown on demand)."""
    T = float(ideal_orbit(alpha, energy, h, Lz, scene.params(alpha), CIRCULAR_TOL)[4])
    if periods is not None:
        cap_ev = 2 * int(periods) + 2
        span = 1.05 * periods * T
    else:
        cap_ev = int(2 * t_end / T) + 4 if math.isfinite(T) and T > 0 else 64
        span = t_end
    if dt_out is not None and math.isfinite(span):
        cap_tr = min(int(span / dt_out) + 3, 1 << 24)
    else:
        cap_tr = 4096
    return cap_ev, cap_tr


def _start_radius(alpha, energy, h, Lz, scene, p, periods):
    """(r0, r1, r2, rc, class name) of the orbit's start at r_min; ValueError if impossible."""
    cls = int(ideal_orbit(alpha, energy, h, Lz, scene.params(alpha), CIRCULAR_TOL)[0])
    ok, r1, r2, rc = orbit_start(p, energy, h, Lz)
    if cls == HYPERBOLIC:
        if periods is not None:
            raise ValueError(
                f"energy={energy!r}: the orbit escapes (hyperbolic), it has no radial period; "
                "give t_end instead of periods"
            )
        A, B, _ = coefficients(alpha, h, Lz, scene.M, scene.g, scene.k)
        r0 = float(free_fall_r_min(energy, A, B))
        return r0, r0, math.inf, rc, CLASS_NAMES[cls]
    if cls == CIRCULAR and periods is not None:
        raise ValueError(
            f"energy={energy!r} is within {CIRCULAR_TOL:g} of the circular minimum: the orbit "
            "has no apsides to count; give t_end instead of periods"
        )
    if cls not in (BOUNDED, CIRCULAR):
        raise ValueError(
            f"energy={energy!r}, h={h!r}, Lz={Lz!r} on alpha={alpha!r}: the orbit is "
            f"{CLASS_NAMES[cls]}, not one that can be integrated from r_min"
        )
    if not ok:  # circular within the class tolerance but just below V_min: start at r_c
        return rc, rc, rc, rc, CLASS_NAMES[cls]
    return r1, r1, r2, rc, CLASS_NAMES[cls]


def _launch_radius(alpha, energy, h, Lz, scene, p, periods, r0):
    """(r0, r1, r2, rc, class name) of a start at the launch point ``r0``; ValueError if the
    orbit does not reach it or ``periods`` cannot be counted on it."""
    r0 = check_number("r0", r0)
    cls = int(ideal_orbit(alpha, energy, h, Lz, scene.params(alpha), CIRCULAR_TOL)[0])
    ok, r1, r2, rc = orbit_start(p, energy, h, Lz)
    if cls == HYPERBOLIC:
        A, B, _ = coefficients(alpha, h, Lz, scene.M, scene.g, scene.k)
        r1, r2 = float(free_fall_r_min(energy, A, B)), math.inf
    elif not ok and cls == CIRCULAR:
        r1 = r2 = rc
    if not (r0 > 0.0 and r1 * (1 - 1e-9) <= r0 <= r2 * (1 + 1e-9)):
        raise ValueError(f"r0={r0!r} is not on the orbit (energy={energy!r}, h={h!r}, "
                         f"Lz={Lz!r}), whose radii are {r1:.6g} .. {r2:.6g} m")  # fmt: skip
    if periods is not None and cls not in (BOUNDED,):
        raise ValueError(f"the orbit is {CLASS_NAMES[cls]}: it has no radial period to "
                         "count; give t_end instead of periods")  # fmt: skip
    return r0, r1, r2, rc, CLASS_NAMES[cls]


def simulate(
    alpha: float | None = None,
    energy: float | None = None,
    h: float | None = None,
    Lz: float | None = None,
    scene: Scene | None = None,
    t_end: float | None = None,
    periods: int | None = None,
    method: str = "rk45",
    rtol: float = DEFAULT_RTOL,
    *,
    dt_out: float | None = None,
    max_steps: int = DEFAULT_MAX_STEPS,
    u0: float = 0.0,
    slip_u: float = 0.0,
    slip_v: float = 0.0,
    r0: float | None = None,
    surface: Surface | None = None,
    rho0: float | None = None,
    z0: float | None = None,
    v0: float | None = None,
    w0: float | None = None,
) -> xr.Dataset:
    """Integrate one trajectory from the inner turning point r_min (u = 0, theta = 0, t = 0),
    or from a launch point ``r0`` of the orbit.

    Parameters
    ----------
    alpha : half-aperture [rad], in (0, pi/2).
    energy : radial energy calE = E/(1+k) - k M h^2/(2(1+k)) [J].
    h : spin invariant [m/s]. Lz : axial angular momentum [kg m^2/s], nonzero.
    scene : the scene (default ``Scene()``); its effects are compiled in, the others out.
    t_end : duration [s]; or ``periods``: number of radial periods (apsis-to-apsis pairs: the
        run stops at the 2*periods-th apsis). Exactly one of the two.
    method : "rk45" (Dormand-Prince 5(4)), "dop853" (Dormand-Prince 8(5,3)) or "symplectic"
        (time-transformed leapfrog, 6th-order Yoshida; conservative scenes without attitude).
    rtol : relative tolerance, in [1e-14, 1e-3].
    dt_out : output spacing [s] on the dense output; None records every step.
    max_steps : step budget.
    u0, slip_u, slip_v : radial speed at the start and the contact point's slip velocity
        (along the generatrix and the parallel) [m/s]; nonzero only on a scene with ``mu_k``.
    r0 : start here [m] instead of at r_min, at rest radially (plus ``u0``): a launch at r0,
        whose invariants (``engine.invariants``, with u = 0) are energy, h, Lz, so that r0 is
        a turning point of the orbit (a fate map over launch states starts there too). r0
        must lie between the orbit's turning points (to 1e-9 relative); any orbit class
        that reaches it (a spilling or escaping orbit too).

    On a scene with kinetic friction ``mu_k`` the trajectory follows the ball through its modes
    (rolling, sliding, rolling again; docs/physics.md "Sliding, rolling again, and spin
    friction"), to ``t_end`` only: the variables add ``mode``, ``p1``, ``p2``, ``slip_speed``,
    the energy and the work of each dissipation; the events are the mode changes and ends of
    :func:`engine.story.story` (slip, roll, spin_stop, spin_go, rest, spill, vertex, horizon,
    failed) with the state there (``event_u``, ``event_v``, ``event_w``, ``event_p1``,
    ``event_p2``), ``attrs["fate"]`` the story's fate.

    Returns
    -------
    xarray.Dataset with dimension ``time`` (r, theta, u, v, w, Cartesian x, y, z of the centre,
    drifts E - E0, L_z - L_z0, h - h0; the quaternion and the contact-point speed with the
    attitude; |F|/N with the slip check) and dimension ``event`` (event_time, event_kind,
    event_r, event_theta; kinds pericentre, apocentre, spill, slip, rest, vertex, horizon,
    failed). Attributes hold the inputs, the scene, the initial invariants and the exit status.

    A trajectory ends, it does not crash, and its last event says where: spilling over the
    rim, slipping, coming to rest and entering the vertex region end the run as events with
    their status; a run to ``t_end`` ends with the event "horizon" there, one of ``periods``
    on its last apsis; a failed integration (step budget, step size underflow, non-finite
    state) returns the trajectory up to the failure, an event "failed" there, and the status
    saying why. With rolling resistance a sphere that stops stays at rest if the resistance
    can hold it on the slope and friction can too (else it slips there), and otherwise starts
    again from rest (docs/physics.md "Effects beyond the ideal cone").

    On a ``surface`` of revolution (``engine.surfaces``) the trajectory starts at a launch
    instead: the centre at ``rho0`` [m] from the axis (the cylinder: height ``z0``), with
    ``v0`` along the parallel, spin ``w0`` and ``u0`` along the meridian [m/s] (alpha, energy,
    h and Lz not given); its variables are the meridian parameter ``q``, ``rho``, theta, u, v,
    w, x, y, z and ``E_drift``, its events carry ``event_rho``; rk45 and dop853 only.

    Raises
    ------
    ValueError for invalid arguments or an orbit that cannot start at r_min.
    """
    scene = check_scene(scene)
    if surface is not None or rho0 is not None or z0 is not None:
        if r0 is not None:
            raise PlanError("r0", "is a launch on the cone; on a surface give rho0 (or z0)", r0)
        return _on_surface(surface, dict(alpha=alpha, energy=energy, h=h, Lz=Lz),
                           dict(rho0=rho0, z0=z0, v0=v0, w0=w0, u0=u0), scene, method, rtol,
                           t_end, periods, dt_out, max_steps)  # fmt: skip
    for name, value in (("v0", v0), ("w0", w0)):
        if value is not None:
            raise PlanError(name, "is a launch on a surface: give surface= and rho0=", value)
    if alpha is None or energy is None or h is None or Lz is None:
        raise ValueError("give the orbit (alpha, energy, h, Lz), or a launch on a surface "
                         "(surface=, rho0=, v0=, w0=)")  # fmt: skip
    point = {"alpha": alpha, "energy": energy, "h": h, "Lz": Lz}
    alpha, energy, h, Lz = (check_number(n, x) for n, x in point.items())
    if Lz == 0.0:
        raise PlanError("Lz", "must be nonzero (a radial orbit through the axis)", Lz)
    m = check_method(method, scene, integrator=True)
    rtol = check_rtol(rtol, m)
    t_end, n_apsides, dt_out, max_steps = _span(t_end, periods, dt_out, max_steps)
    release = {"u0": u0, "slip_u": slip_u, "slip_v": slip_v}
    launch = {n: check_number(n, x) for n, x in release.items()}
    for name, value in launch.items():
        check_release(name, value, scene)
    check_launch(launch, scene)  # their energies within the run's range
    if scene.mu_k is not None and periods is not None:
        raise ValueError(f"periods={periods!r}: a scene with mu_k (sliding) has no radial "
                         "period to count; give t_end instead")  # fmt: skip

    effects = scene.effects_mask
    p = scene.params(alpha)
    if r0 is None:
        r0, r1, r2, rc, cls_name = _start_radius(alpha, energy, h, Lz, scene, p, periods)
    else:
        r0, r1, r2, rc, cls_name = _launch_radius(alpha, energy, h, Lz, scene, p, periods, r0)
    if scene.mu_k is not None:
        return hybrid_trajectory(alpha, energy, h, Lz, r0, scene, m.kernel_id, method, rtol,
                                 t_end, dt_out, int(max_steps), launch["u0"], launch["slip_u"],
                                 launch["slip_v"], cls_name)  # fmt: skip
    y0 = initial_state(p, effects, r0, energy, h, Lz)
    y0[2] = 0.0  # r0 is a turning point
    sc = tolerance_scales(p, effects, y0, energy, h, Lz, r1, r2, rc)
    p[P_V_REST] = REST_SPEED * rtol * max(sc[2], abs(y0[3]))
    run = TrajectoryRun(m.kernel_id, effects, p, (energy, h, Lz), rtol, rtol * sc, int(max_steps))
    run.capacities(*_capacities(alpha, energy, h, Lz, scene, t_end, periods, dt_out))
    t_stop = math.inf if t_end is None else t_end
    record = RECORD_STEPS if dt_out is None else RECORD_EVERY_DT
    status = run.follow(y0, t_stop, n_apsides, record, dt_out or 0.0)
    return _dataset(scene, effects, p, method, rtol, alpha, energy, h, Lz, cls_name, y0, status,
                    run, periods is None)  # fmt: skip


def _on_surface(surface, orbit, launch, scene, method, rtol, t_end, periods, dt_out,
                max_steps) -> xr.Dataset:  # fmt: skip
    """:func:`simulate` on a surface: its inputs checked, then :func:`simulate_surface`."""
    why = "is the cone's orbit; on a surface the start is a launch"
    surface, values = check_surface_launch(surface, orbit, why, launch)
    values["u0"] = check_number("u0", launch["u0"])
    m = check_method(method, scene, integrator=True)
    check_model(m, MODEL_BY_NAME["surface"], scene)
    rtol = check_rtol(rtol, m)
    t_end, n_apsides, dt_out, max_steps = _span(t_end, periods, dt_out, max_steps)
    return simulate_surface(surface, values, scene, m, rtol, t_end, n_apsides, dt_out,
                            max_steps)  # fmt: skip


def _span(t_end, periods, dt_out, max_steps) -> tuple[float | None, int, float | None, int]:
    """(t_end, apsides to stop at (0: none), dt_out, max_steps) of a trajectory, checked:
    exactly one of t_end (> 0) and periods (a positive integer)."""
    if (t_end is None) == (periods is None):
        raise ValueError(f"give exactly one of t_end and periods; got t_end={t_end!r}, "
                         f"periods={periods!r}")  # fmt: skip
    if t_end is not None:
        t_end = check_positive("t_end", t_end)
    n_apsides = 0
    if periods is not None:
        if (
            isinstance(periods, bool)
            or not isinstance(periods, Real)
            or not (float(periods).is_integer() and periods >= 1)
        ):
            raise PlanError("periods", "must be a positive integer", periods)
        n_apsides = 2 * int(periods)
    if dt_out is not None:
        dt_out = check_positive("dt_out", dt_out)
    return t_end, n_apsides, dt_out, check_max_steps(max_steps)


def _dataset(scene, effects, p, method, rtol, alpha, energy, h, Lz, cls_name, y0, status,
             run, to_time) -> xr.Dataset:  # fmt: skip
    t, Y, rate, ev_t, ev_kind, ev_y = run.arrays()
    if status not in NORMAL_ENDS:  # the run failed: say where, as an event
        ev_t = np.append(ev_t, run.t_final)
        ev_kind = np.append(ev_kind, np.int8(FAILURE))
        ev_y = np.vstack([ev_y, Y[-1:]]) if Y.shape[0] else np.vstack([ev_y, y0[None]])
    elif status == OK and to_time:  # it ran to t_end: the horizon is where it ended
        ev_t = np.append(ev_t, run.t_final)
        ev_kind = np.append(ev_kind, np.int8(HORIZON))
        ev_y = np.vstack([ev_y, run.y_final[None]])
    M, g, k = scene.M, scene.g, scene.k
    s, c = math.sin(alpha), math.cos(alpha)
    r, th, u, v, w = (Y[:, i] for i in range(5))
    E_t, Lz_t, h_t = invariants_of.py_func(r, u, v, w, s, c, M, g, k)
    E0, Lz0, h0 = invariants(y0, p)
    columns: dict[str, Any] = {
        "r": r,
        "theta": th,
        "u": u,
        "v": v,
        "w": w,
        "x": r * s * np.cos(th),
        "y": r * s * np.sin(th),
        "z": r * c,
        "E_drift": E_t - E0,
        "Lz_drift": Lz_t - Lz0,
        "h_drift": h_t - h0,
    }
    if "friction_ratio" in effect_variables(scene, "trajectory"):
        F, N = contact_forces_of.py_func(r, v, w, s, c, c / s, M, g, k / (1 + k))
        columns["friction_ratio"] = np.abs(F) / N
    if effects & ATTITUDE:
        q = Y[:, 5:9]
        for i, name in enumerate("wxyz"):
            columns[f"quat_{name}"] = q[:, i]
        columns["quat_norm_error"] = np.linalg.norm(q, axis=1) - 1.0
        columns["contact_speed"] = _contact_speed(Y, rate, p)
    data = {name: (("time",), col, TRAJECTORY[name].attrs()) for name, col in columns.items()}
    events = {
        "event_time": ev_t,
        "event_kind": ev_kind.astype(np.int8),
        "event_r": ev_y[:, 0],
        "event_theta": ev_y[:, 1],
    }
    data.update({n: (("event",), col, TRAJECTORY[n].attrs()) for n, col in events.items()})
    ds = xr.Dataset(data, coords={"time": (("time",), t, TRAJECTORY["time"].attrs())})
    ds.time.encoding["_FillValue"] = None
    ds.attrs.update(
        {
            "title": "trajectory of a sphere rolling inside a cone",
            "source": f"conesurvey {__version__}",
            "method": method,
            "rtol": rtol,
            "alpha": alpha,
            "energy": energy,
            "h": h,
            "Lz": Lz,
            "orbit_class": cls_name,
            "E0": E0,
            "Lz0": Lz0,
            "h0": h0,
            "status": int(status),
            "status_message": STATUS_MESSAGES[status],
            "n_steps": run.n_acc,
            "n_rejected": run.n_rej,
        }
    )
    ds.attrs.update(scene.as_attrs())
    return ds


def _contact_speed(Y: np.ndarray, rate: np.ndarray, p: np.ndarray) -> np.ndarray:
    """|R_dot + omega x (-a nu)| at each recorded point (see model.contact_velocity)."""
    out = np.empty(Y.shape[0])
    for i in range(Y.shape[0]):
        vx, vy, vz = contact_velocity(Y[i], rate[i], p)
        out[i] = math.sqrt(vx * vx + vy * vy + vz * vz)
    return out

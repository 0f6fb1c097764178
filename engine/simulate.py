"""One trajectory of the rolling sphere, integrated and returned as an xarray Dataset."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr
from numba import literally

from . import __version__
from ._jit import kernel
from .integrated import call_specialized, check_method, check_rtol, scene_params
from .kernels.geometry import CIRCULAR_TOL, orbit_point
from .kernels.integrators import (
    BUFFER_FULL,
    EVENT_NAMES,
    OK,
    RECORD_EVERY_DT,
    RECORD_STEPS,
    SLIPPED,
    SPILLED,
    STATUS_MESSAGES,
    SYMPLECTIC,
    initial_state,
    orbit_start,
    rk_run,
    tolerance_scales,
)
from .kernels.physics import BOUNDED, CIRCULAR, CLASS_NAMES, HYPERBOLIC, coefficients
from .kernels.roots import free_fall_r_min
from .kernels.scenes import ATTITUDE, SLIP_CHECK, effects_mask, invariants
from .kernels.symplectic import DEFAULT_ORDER, initial_z, sym_run
from .scene import Scene

__all__ = ["simulate", "DEFAULT_MAX_STEPS"]

#: Step budget of one simulation (a guard against runaway runs, not a tuning knob).
DEFAULT_MAX_STEPS = 100_000_000


@kernel
def solve_rk(method, effects, y0, p, rtol, atol, t_end, n_apsides, max_steps, record, dt_out,
             ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
    """:func:`engine.kernels.integrators.rk_run` compiled for a literal method and effect set."""
    literally(method)
    literally(effects)
    return rk_run(method, effects, y0, p, rtol, atol, t_end, n_apsides, max_steps, record, dt_out,
                  ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate)  # fmt: skip


@kernel
def solve_symplectic(effects, z0, p, energy, h, Lz, order, rtol, t_end, n_apsides, max_steps,
                     record, dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y):  # fmt: skip
    """:func:`engine.kernels.symplectic.sym_run` compiled for a literal effect set."""
    literally(effects)
    return sym_run(effects, z0, p, energy, h, Lz, order, rtol, t_end, n_apsides, max_steps,
                   record, dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y)  # fmt: skip


def _real(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number; got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite; got {value!r}")
    return v


def _attrs(units: str, long_name: str, **extra: Any) -> dict[str, Any]:
    return {"units": units, "long_name": long_name, **extra}


def _capacities(alpha, energy, h, Lz, scene, t_end, periods, dt_out) -> tuple[int, int]:
    """First guess of the event and trajectory buffer sizes (grown on demand)."""
    T = float(orbit_point(alpha, energy, h, Lz, scene.M, scene.g, scene.k, math.inf,
                          CIRCULAR_TOL)[4])  # fmt: skip
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
    cls = int(orbit_point(alpha, energy, h, Lz, scene.M, scene.g, scene.k, math.inf,
                          CIRCULAR_TOL)[0])  # fmt: skip
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


def simulate(
    alpha: float,
    energy: float,
    h: float,
    Lz: float,
    scene: Scene | None = None,
    t_end: float | None = None,
    periods: int | None = None,
    method: str = "rk45",
    rtol: float = 1e-10,
    *,
    dt_out: float | None = None,
    max_steps: int = DEFAULT_MAX_STEPS,
) -> xr.Dataset:
    """Integrate one trajectory from the inner turning point r_min (u = 0, theta = 0, t = 0).

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

    Returns
    -------
    xarray.Dataset with dimension ``time`` (r, theta, u, v, w, Cartesian x, y, z of the centre,
    drifts E - E0, L_z - L_z0, h - h0; the quaternion and the contact-point speed with the
    attitude; |F|/N with the slip check) and dimension ``event`` (event_time, event_kind,
    event_r, event_theta; kinds pericentre, apocentre, spill, slip). Attributes hold the
    inputs, the scene, the initial invariants and the exit status. Spilling over the rim and
    slipping end the run (they are events, not errors).

    Raises
    ------
    ValueError for invalid arguments or an orbit that cannot start at r_min; RuntimeError when
    the integration fails (step budget exhausted, step size underflow, non-finite state).
    """
    scene = Scene() if scene is None else scene
    if not isinstance(scene, Scene):
        raise ValueError(f"scene must be an engine.Scene; got {scene!r}")
    alpha = _real("alpha", alpha)
    if not 0.0 < alpha < math.pi / 2:
        raise ValueError(f"alpha must lie in the open interval (0, pi/2); got {alpha!r}")
    energy = _real("energy", energy)
    h = _real("h", h)
    Lz = _real("Lz", Lz)
    if Lz == 0.0:
        raise ValueError("Lz must be nonzero (Lz=0.0 is a radial orbit through the axis)")
    mid = check_method(method, scene)
    rtol = check_rtol(rtol)
    if (t_end is None) == (periods is None):
        raise ValueError(f"give exactly one of t_end and periods; got t_end={t_end!r}, "
                         f"periods={periods!r}")  # fmt: skip
    if t_end is not None:
        t_end = _real("t_end", t_end)
        if not t_end > 0.0:
            raise ValueError(f"t_end must be > 0; got {t_end!r}")
    n_apsides = 0
    if periods is not None:
        if isinstance(periods, bool) or not float(periods).is_integer() or periods < 1:
            raise ValueError(f"periods must be a positive integer; got {periods!r}")
        n_apsides = 2 * int(periods)
    if dt_out is not None:
        dt_out = _real("dt_out", dt_out)
        if not dt_out > 0.0:
            raise ValueError(f"dt_out must be > 0; got {dt_out!r}")
    if int(max_steps) < 1:
        raise ValueError(f"max_steps must be >= 1; got {max_steps!r}")

    effects = effects_mask(scene.effects)
    p = scene_params(scene, alpha)
    r0, r1, r2, rc, cls_name = _start_radius(alpha, energy, h, Lz, scene, p, periods)
    y0 = initial_state(p, effects, r0, energy, h, Lz)
    y0[2] = 0.0  # r0 is a turning point
    record = RECORD_STEPS if dt_out is None else RECORD_EVERY_DT
    t_stop = math.inf if t_end is None else t_end
    n = y0.shape[0]
    cap_ev, cap_tr = _capacities(alpha, energy, h, Lz, scene, t_end, periods, dt_out)
    if mid != SYMPLECTIC:
        atol = rtol * tolerance_scales(p, effects, y0, energy, h, Lz, r1, r2, rc)
    while True:  # integration is deterministic: a run that ran out of room is redone larger
        ev_t, ev_kind, ev_y = np.empty(cap_ev), np.empty(cap_ev, np.int8), np.empty((cap_ev, n))
        tr_t, tr_y = np.empty(cap_tr), np.empty((cap_tr, n))
        tr_rate = np.empty((cap_tr if effects & ATTITUDE else 0, n))
        if mid == SYMPLECTIC:
            z0 = initial_z(p, r0, 0.0, energy, h, Lz)
            args = (
                effects,
                z0,
                p,
                energy,
                h,
                Lz,
                DEFAULT_ORDER,
                rtol,
                t_stop,
                n_apsides,
                int(max_steps),
                record,
                dt_out or 0.0,
                ev_t,
                ev_kind,
                ev_y,
                tr_t,
                tr_y,
            )
            res = call_specialized(solve_symplectic, args, (0,))
        else:
            args = (
                mid,
                effects,
                y0,
                p,
                rtol,
                atol,
                t_stop,
                n_apsides,
                int(max_steps),
                record,
                dt_out or 0.0,
                ev_t,
                ev_kind,
                ev_y,
                tr_t,
                tr_y,
                tr_rate,
            )
            res = call_specialized(solve_rk, args, (0, 1))
        status, n_acc, n_rej, t_final = int(res[0]), int(res[1]), int(res[2]), float(res[3])
        n_ev, n_tr = int(res[5]), int(res[6])
        if status != BUFFER_FULL:
            break
        if n_ev == cap_ev:
            cap_ev *= 4
        if n_tr == cap_tr:
            cap_tr *= 4
    if status not in (OK, SPILLED, SLIPPED):
        raise RuntimeError(
            f"simulate({method!r}) failed at t={t_final:.17g} s after {n_acc} steps: "
            f"{STATUS_MESSAGES[status]}"
        )
    return _dataset(
        scene, effects, p, method, rtol, alpha, energy, h, Lz, cls_name, y0, status, n_acc, n_rej,
        tr_t[:n_tr], tr_y[:n_tr], tr_rate[:n_tr], ev_t[:n_ev], ev_kind[:n_ev], ev_y[:n_ev],
    )  # fmt: skip


def _dataset(scene, effects, p, method, rtol, alpha, energy, h, Lz, cls_name, y0, status,
             n_acc, n_rej, t, Y, rate, ev_t, ev_kind, ev_y) -> xr.Dataset:  # fmt: skip
    M, g, k = scene.M, scene.g, scene.k
    s, c = math.sin(alpha), math.cos(alpha)
    r, th, u, v, w = (Y[:, i] for i in range(5))
    Lz_t = M * r * v * s
    h_t = w - Lz_t * c / (M * r * s * s)
    E_t = 0.5 * (1 + k) * M * (u * u + v * v) + 0.5 * k * M * w * w + M * g * r * c
    E0, Lz0, h0 = invariants(y0, p)
    T = ("time",)
    data: dict[str, Any] = {
        "r": (T, r, _attrs("m", "distance of the centre from the vertex of its cone")),
        "theta": (T, th, _attrs("radian", "azimuth of the centre (unwrapped)")),
        "u": (T, u, _attrs("m s-1", "radial velocity dr/dt along the generatrix")),
        "v": (T, v, _attrs("m s-1", "azimuthal velocity r sin(alpha) dtheta/dt")),
        "w": (T, w, _attrs("m s-1", "spin about the normal times the radius, a omega_nu")),
        "x": (T, r * s * np.cos(th), _attrs("m", "Cartesian x of the centre")),
        "y": (T, r * s * np.sin(th), _attrs("m", "Cartesian y of the centre")),
        "z": (T, r * c, _attrs("m", "Cartesian z of the centre (cone axis, up)")),
        "E_drift": (T, E_t - E0, _attrs("J", "total energy minus its initial value")),
        "Lz_drift": (T, Lz_t - Lz0, _attrs("kg m2 s-1", "L_z minus its initial value")),
        "h_drift": (T, h_t - h0, _attrs("m s-1", "spin invariant h minus its initial value")),
    }
    if effects & SLIP_CHECK:
        N = M * (g * s + v * v * c / (r * s))
        F = k / (1 + k) * M * (g * c + c / (r * s) * v * w)
        data["friction_ratio"] = (T, np.abs(F) / N, _attrs(
            "1", "friction needed over normal force |F|/N (slip where > mu)"))  # fmt: skip
    if effects & ATTITUDE:
        q = Y[:, 5:9]
        for i, name in enumerate(("w", "x", "y", "z")):
            data[f"quat_{name}"] = (T, q[:, i], _attrs(
                "1", f"attitude quaternion, {name} component (body to fixed frame)"))  # fmt: skip
        data["quat_norm_error"] = (T, np.linalg.norm(q, axis=1) - 1.0,
                                   _attrs("1", "|q| - 1 of the attitude quaternion"))  # fmt: skip
        data["contact_speed"] = (T, _contact_speed(Y, rate, p), _attrs(
            "m s-1", "speed of the sphere's material point at the contact "
            "|R_dot + omega x (-a nu)|, omega from the quaternion (0 when rolling)"))  # fmt: skip
    E = ("event",)
    kind_attrs = {
        "long_name": "event kind",
        "flag_values": np.arange(len(EVENT_NAMES), dtype=np.int8),
        "flag_meanings": " ".join(EVENT_NAMES),
    }
    data["event_time"] = (E, ev_t, _attrs("s", "time of the event"))
    data["event_kind"] = (E, ev_kind.astype(np.int8), kind_attrs)
    data["event_r"] = (E, ev_y[:, 0], _attrs("m", "r at the event"))
    data["event_theta"] = (E, ev_y[:, 1], _attrs("radian", "theta at the event"))
    ds = xr.Dataset(data, coords={"time": (T, t, _attrs("s", "time since the start at r_min"))})
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
            "n_steps": int(n_acc),
            "n_rejected": int(n_rej),
        }
    )
    ds.attrs.update(scene.as_attrs())
    return ds


def _contact_speed(Y: np.ndarray, rate: np.ndarray, p: np.ndarray) -> np.ndarray:
    """|R_dot + omega x (-a nu)| at each recorded point (see scenes.contact_velocity)."""
    from .kernels.scenes import contact_velocity

    out = np.empty(Y.shape[0])
    for i in range(Y.shape[0]):
        vx, vy, vz = contact_velocity(Y[i], rate[i], p)
        out[i] = math.sqrt(vx * vx + vy * vy + vz * vz)
    return out

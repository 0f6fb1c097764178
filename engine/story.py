"""One launch's whole story, and fate maps over launch states that may slide (the user-facing
side of :mod:`engine.hybrid`): a ball released with a radial speed and a slip velocity (thrown
without spin, with backspin), on a scene with kinetic friction ``mu_k``."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .checks import (
    PlanError,
    check_count,
    check_launch_values,
    check_method,
    check_number,
    check_release,
    check_rtol,
    check_scene,
    check_surface_fits,
)
from .fates import Horizon, require_horizon
from .hybrid import HYBRID_STATE, hybrid_fates, hybrid_setup, whole_story
from .kernels.cone import set_alpha
from .kernels.hybrid import HYBRID_FATE_NAMES, HYBRID_ROWS
from .kernels.hybrid_step import HYBRID_EVENT_NAMES
from .kernels.meridian import centre
from .kernels.model import SURFACE
from .kernels.surface_starts import set_point
from .launch import invariants
from .methods import MODEL_BY_NAME, check_model
from .scene import Scene
from .simulate_surface import check_surface_launch
from .surface_maps import surface_params, surface_points
from .surfaces import Surface

__all__ = ["launch_fates", "story"]


def _horizon(horizon_time: float | None, horizon_revolutions: float | None) -> tuple[float, float]:
    hz = require_horizon(Horizon(horizon_time, horizon_revolutions))
    return hz.t_max, hz.theta_max


def launch_fates(
    alpha: Any,
    r0: Any,
    v0: Any,
    w0: Any,
    *,
    u0: Any = 0.0,
    slip_u: Any = 0.0,
    slip_v: Any = 0.0,
    scene: Scene,
    method: str = "dop853",
    rtol: float = 1e-10,
    horizon_time: float | None = None,
    horizon_revolutions: float | None = None,
) -> dict[str, np.ndarray]:
    """Fates of launches (numpy broadcasting of all state arguments): released at ``r0`` [m]
    with radial speed ``u0``, azimuthal speed ``v0``, spin ``w0`` = a omega_nu and the contact
    point's slip velocity (``slip_u`` along the generatrix, ``slip_v`` along the parallel)
    [m/s]. A ball thrown without spin has slip_u = u0 (and slip_v = v0); backspin makes slip_u
    larger. Returns the arrays of :func:`hybrid_fates`, shaped like the broadcast inputs, plus
    ``fate_name``."""
    scene = check_scene(scene, sliding=True)
    rtol = check_rtol(rtol, check_method(method, scene, integrator=True))
    t_max, theta_max = _horizon(horizon_time, horizon_revolutions)
    launch = dict(alpha=alpha, r0=r0, v0=v0, w0=w0, u0=u0, slip_u=slip_u, slip_v=slip_v)
    arrs = np.broadcast_arrays(*check_launch_values(launch, scene))
    shape = arrs[0].shape
    flat = [a.ravel() for a in arrs]
    inv = invariants(flat[0], flat[1], flat[4], flat[2], flat[3], scene)
    e_rest = inv["energy"] - 0.5 * scene.M * flat[4] * flat[4]  # as a launch map computes it
    res = hybrid_fates(flat[0], e_rest, inv["h"], inv["Lz"], flat[1], scene, method,
                       rtol, t_max, theta_max, u0=flat[4], slip_u=flat[5],
                       slip_v=flat[6])  # fmt: skip
    out = {k: v.reshape(shape) for k, v in res.items()}
    out["fate_name"] = np.array(HYBRID_FATE_NAMES, dtype=object)[out["fate"]]
    return out


def story(
    alpha: float | None = None,
    r0: float | None = None,
    v0: float | None = None,
    w0: float | None = None,
    *,
    u0: float = 0.0,
    slip_u: float = 0.0,
    slip_v: float = 0.0,
    scene: Scene,
    method: str = "dop853",
    rtol: float = 1e-10,
    horizon_time: float | None = None,
    horizon_revolutions: float | None = None,
    max_events: int = 10_000,
    surface: Surface | None = None,
    rho0: float | None = None,
    z0: float | None = None,
) -> dict[str, Any]:
    """One launch followed through its modes (arguments as :func:`launch_fates`, scalars); on
    a ``surface`` of revolution (``engine.surfaces``) the launch is the centre's distance from
    the axis ``rho0`` [m] (the cylinder: its height ``z0``) with ``v0``, ``w0``, ``u0`` [m/s]
    as :func:`engine.simulate` takes them, and no ``alpha`` or ``r0``.

    Returns ``fate`` (name), the rows of :data:`engine.kernels.hybrid.HYBRID_ROWS`, ``n_steps``
    and ``events``: a list of dicts (``kind``: slip, roll, spin_stop, spin_go, rest, spill,
    vertex, liftoff, horizon; ``t`` [s]; ``state``: dict of :data:`HYBRID_STATE`; a roll
    event's state is the one after the sticking impulse): the first ``max_events`` of them,
    with ``events_dropped`` the count of those that followed. On a surface ``r`` is the
    meridian parameter q (``engine.kernels.meridian``), each state and the end also give the
    centre's ``rho`` and ``z`` [m] (``fate_rho``, ``fate_z``), ``final_energy`` is the rolling
    end's energy E [J], and ``final_h``, ``final_Lz`` (the cone's invariants) are left out."""
    scene = check_scene(scene, sliding=True)
    m = check_method(method, scene, integrator=True)
    rtol = check_rtol(rtol, m)
    t_max, theta_max = _horizon(horizon_time, horizon_revolutions)
    max_events = check_count("max_events", max_events)
    slips = dict(u0=u0, slip_u=slip_u, slip_v=slip_v)
    if surface is not None or rho0 is not None or z0 is not None:
        launch = dict(rho0=rho0, z0=z0, v0=v0, w0=w0)
        return _on_surface(surface, dict(alpha=alpha, r0=r0), launch, slips, scene, m, rtol,
                           t_max, theta_max, max_events)  # fmt: skip
    given = dict(alpha=alpha, r0=r0, v0=v0, w0=w0)
    for name, value in given.items():
        if value is None:
            raise PlanError(name, "is needed: the launch on the cone (alpha, r0, v0, w0); or "
                            "a surface and its launch (surface=, rho0=, v0=, w0=)")  # fmt: skip
    launch = {n: check_number(n, x) for n, x in {**given, **slips}.items()}
    check_launch_values(launch, scene)
    alpha, r0, v0, w0, u0, slip_u, slip_v = launch.values()
    params, effects, spin = hybrid_setup(scene, theta_max)
    set_alpha(params, float(alpha))
    inv = invariants(alpha, r0, 0.0, v0, w0, scene)
    start = (inv["energy"], inv["h"], inv["Lz"], r0, u0, slip_u, slip_v)
    res = whole_story(m.kernel_id, params, effects, spin, scene, start, rtol, t_max,
                      capacity=max_events)  # fmt: skip
    return _told(res, max_events)


def _told(res: tuple, max_events: int, where: Any = None) -> dict[str, Any]:
    """The story's dict from :func:`.hybrid.whole_story`'s tuple; ``where(q)`` gives (rho, z)
    of a surface's meridian parameter (None: the cone)."""
    fate, f, steps, _, ev_t, ev_kind, ev_y = res
    out: dict[str, Any] = {"fate": HYBRID_FATE_NAMES[fate]}
    out.update({name: float(f[i]) for i, name in enumerate(HYBRID_ROWS)})
    if where is not None:
        out["fate_rho"], out["fate_z"] = where(out["fate_r"])
        del out["final_h"], out["final_Lz"]
    out["n_steps"] = int(steps)
    told = np.flatnonzero(ev_kind < len(HYBRID_EVENT_NAMES))  # without the kernel's own marks
    events = []  # (the sampled trajectory's): not events of the story
    for i in told[:max_events]:
        state = {name: float(ev_y[i, j]) for j, name in enumerate(HYBRID_STATE)}
        if where is not None:
            state["rho"], state["z"] = where(state["r"])
        events.append({"kind": HYBRID_EVENT_NAMES[ev_kind[i]], "t": float(ev_t[i]),
                       "state": state})  # fmt: skip
    out["events"] = events
    out["events_dropped"] = len(told) - len(events)
    return out


def _on_surface(surface, cone, launch, slips, scene, m, rtol, t_max, theta_max, max_events):
    """:func:`story` on a surface: its launch checked, then the surface model's story."""
    why = "is a launch on the cone; on a surface the launch is"
    surface, values = check_surface_launch(surface, cone, why, launch)
    for name, value in slips.items():
        values[name] = check_number(name, value)
        check_release(name, np.asarray(values[name]), scene)
    try:
        check_model(m, MODEL_BY_NAME["surface"], scene, story=True)
    except ValueError as exc:
        raise PlanError("method", str(exc), m.name, whole=True) from None
    check_surface_fits(surface, scene)
    pos, v0, w0, u0, slip_u, slip_v = values.values()
    s1, s2 = surface.shape
    params = surface_params(scene, surface)
    X = surface_points(np.array([s1]), np.array([s2]), np.array([pos]), np.array([v0]),
                       np.array([w0]), np.array([u0]))  # fmt: skip
    set_point(params, X, 0)
    params, effects, spin = hybrid_setup(scene, theta_max, params, SURFACE)
    start = (pos, v0, w0, math.nan, u0, slip_u, slip_v)
    res = whole_story(m.kernel_id, params, effects, spin, scene, start, rtol, t_max,
                      capacity=max_events)  # fmt: skip
    if HYBRID_FATE_NAMES[res[0]] == "no_orbit":
        raise PlanError(surface.position, f"not a place on the {surface.kind} where the ball "
                        "fits and touches, below its rim", pos)  # fmt: skip

    def where(q: float) -> tuple[float, float]:
        rho, z = centre.py_func(params, q)[:2]
        return float(rho), float(z)

    return _told(res, max_events, where)

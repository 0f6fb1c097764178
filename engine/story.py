"""One launch's whole story, and fate maps over launch states that may slide (the user-facing
side of :mod:`engine.hybrid`): a ball released with a radial speed and a slip velocity (thrown
without spin, with backspin), on a scene with kinetic friction ``mu_k``."""

from __future__ import annotations

from typing import Any

import numpy as np

from .checks import (
    check_count,
    check_launch_values,
    check_method,
    check_number,
    check_rtol,
    check_scene,
)
from .fates import Horizon, require_horizon
from .hybrid import HYBRID_STATE, hybrid_fates, hybrid_setup, whole_story
from .kernels.cone import set_alpha
from .kernels.hybrid import HYBRID_FATE_NAMES, HYBRID_ROWS
from .kernels.hybrid_step import HYBRID_EVENT_NAMES
from .launch import invariants
from .scene import Scene

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
    alpha: float,
    r0: float,
    v0: float,
    w0: float,
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
) -> dict[str, Any]:
    """One launch followed through its modes (arguments as :func:`launch_fates`, scalars).

    Returns ``fate`` (name), the rows of :data:`engine.kernels.hybrid.HYBRID_ROWS`, ``n_steps``
    and ``events``: a list of dicts (``kind``: slip, roll, spin_stop, spin_go, rest, spill,
    vertex, horizon; ``t`` [s]; ``state``: dict of :data:`HYBRID_STATE`; a roll event's state is
    the one after the sticking impulse): the first ``max_events`` of them, with
    ``events_dropped`` the count of those that followed."""
    scene = check_scene(scene, sliding=True)
    m = check_method(method, scene, integrator=True)
    rtol = check_rtol(rtol, m)
    t_max, theta_max = _horizon(horizon_time, horizon_revolutions)
    max_events = check_count("max_events", max_events)
    given = dict(alpha=alpha, r0=r0, v0=v0, w0=w0, u0=u0, slip_u=slip_u, slip_v=slip_v)
    launch = {n: check_number(n, x) for n, x in given.items()}
    check_launch_values(launch, scene)
    alpha, r0, v0, w0, u0, slip_u, slip_v = launch.values()
    params, effects, spin = hybrid_setup(scene, theta_max)
    set_alpha(params, float(alpha))
    inv = invariants(alpha, r0, 0.0, v0, w0, scene)
    res = whole_story(m.kernel_id, params, effects, spin, scene, inv["energy"], inv["h"],
                      inv["Lz"], (r0, u0, slip_u, slip_v), rtol, t_max,
                      capacity=max_events)  # fmt: skip
    fate, f, steps, _, ev_t, ev_kind, ev_y = res
    out: dict[str, Any] = {"fate": HYBRID_FATE_NAMES[fate]}
    out.update({name: float(f[i]) for i, name in enumerate(HYBRID_ROWS)})
    out["n_steps"] = int(steps)
    told = np.flatnonzero(ev_kind < len(HYBRID_EVENT_NAMES))  # without the kernel's own marks
    events = []  # (the sampled trajectory's): not events of the story
    for i in told[:max_events]:
        state = {name: float(ev_y[i, j]) for j, name in enumerate(HYBRID_STATE)}
        events.append({"kind": HYBRID_EVENT_NAMES[ev_kind[i]], "t": float(ev_t[i]),
                       "state": state})  # fmt: skip
    out["events"] = events
    out["events_dropped"] = len(told) - len(events)
    return out

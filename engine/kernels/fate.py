"""Fate maps: each orbit integrated from its start to its first terminal event or a horizon.

A fate run follows the run protocol (:func:`.orbit.run`) with the scene's terminal events
compiled in (the rim, the slip check, and with rolling resistance the stop and the vertex
region; with a horizon in revolutions, the azimuth), then says what happened
(:data:`FATE_NAMES`). Rolling resistance cannot push a sphere at rest backwards: when the
speed falls to the rest threshold (``P_V_REST``, 10 rtol times the orbit's speed scale) the
sphere stays at rest if the resistance can hold it there (cot(alpha) <= c_rr: only on nearly
flat cones); otherwise it starts again from rest, and rolls down towards the vertex
(docs/physics.md "Effects beyond the ideal cone").
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, prange

from .._jit import kernel, parallel_kernel
from .effects import DISSIPATIVE
from .model import (
    P_R_VERTEX,
    P_V_REST,
    holds_at_rest,
    invariants,
    kinetic_energy,
    set_alpha,
    state_size,
)
from .orbit import initial_state, orbit_start, run, tolerance_scales
from .protocol import (
    AT_VERTEX,
    OK,
    RECORD_NONE,
    RESTED,
    SLIPPED,
    SPILLED,
    copy_into,
    event_buffers,
)

#: What happened to an orbit (int8, CF flag_values 0..6).
NO_ORBIT = 0
ROLLING = 1
FATE_SPILLED = 2
FATE_SLIPPED = 3
FATE_REST = 4
FATE_VERTEX = 5
FAILED = 6
FATE_NAMES = ("no_orbit", "rolling", "spilled", "slipped", "rest", "vertex", "failed")
#: Rows of the float output of :func:`fate_points`.
FATE_ROWS = ("fate_time", "fate_r", "fate_theta", "revolutions", "energy_lost", "invariant_drift")
#: The rest threshold in units of rtol times the orbit's speed scale.
REST_SPEED = 10.0
#: Restarts from rest (a sphere that rolls down again) before a run is called failed.
MAX_RESTARTS = 10_000


@kernel
def _fate_of_status(status):
    if status == OK:
        return ROLLING
    if status == SPILLED:
        return FATE_SPILLED
    if status == SLIPPED:
        return FATE_SLIPPED
    if status == AT_VERTEX:
        return FATE_VERTEX
    return FAILED


@kernel
def fate_run(method, effects, p, y0, orbit, rtol, atol, t_horizon, max_steps):
    """Integrate from y0 at t = 0 to the first terminal event or ``t_horizon`` [s].

    Returns (fate, t [s], final state, steps taken). A stop by rolling resistance either ends
    the run (the sphere stays at rest) or restarts it from rest (module docstring).
    """
    n = y0.shape[0]
    y = y0.copy()
    ev_t, ev_kind, ev_y = event_buffers(4, n)
    t0 = 0.0
    steps = 0
    for _ in range(MAX_RESTARTS):
        res = run(method, effects, y, p, orbit, rtol, atol, t_horizon - t0, np.int64(-1),
                  max_steps - steps, np.int64(RECORD_NONE), 0.0, ev_t, ev_kind, ev_y, ev_t,
                  ev_y, ev_y)  # fmt: skip
        status = res[0]
        steps += res[1] + res[2]
        t = t0 + res[3]
        copy_into(res[4], y)
        if status != RESTED:
            return _fate_of_status(status), t, y, steps
        if holds_at_rest(p):
            return FATE_REST, t, y, steps
        y[2] = 0.0
        y[3] = 0.0
        t0 = t
        if steps >= max_steps:
            break
    return FAILED, t0, y, steps


@kernel
def fate_of(method, effects, p, energy, h, Lz, r_start, rtol, t_horizon, max_steps):
    """The fate of the orbit (calE, h, L_z) started at rest radially (u = 0) at ``r_start`` [m]
    (its r_min, or a launch radius), theta = 0, t = 0.

    Returns (fate, time [s], r [m], theta [rad], revolutions, energy lost [J], drift of the
    energy balance E + W [1], W the work of the dissipative forces, steps).
    """
    nan = math.nan
    if not (r_start >= 0.0 and math.isfinite(energy) and math.isfinite(Lz)):
        return NO_ORBIT, nan, nan, nan, nan, nan, nan, 0
    if r_start <= p[P_R_VERTEX]:  # through the axis (L_z = 0) or launched at the bottom
        return FATE_VERTEX, 0.0, r_start, 0.0, 0.0, 0.0, 0.0, 0
    ok, r1, r2, rc = orbit_start(p, energy, h, Lz)
    if not ok:
        r1 = r_start
        r2 = math.inf
    y0 = initial_state(p, effects, r_start, energy, h, Lz)
    y0[2] = 0.0  # a turning point: the start of a map's orbit, or a launch with u0 = 0
    sc = tolerance_scales(p, effects, y0, energy, h, Lz, min(r1, r_start), r2, rc)
    p[P_V_REST] = REST_SPEED * rtol * max(sc[2], abs(y0[3]))
    atol = sc * rtol
    fate, t, y, steps = fate_run(method, effects, p, y0, (energy, h, Lz), rtol, atol, t_horizon,
                                 max_steps)  # fmt: skip
    E0 = invariants(y0, p)[0]
    E1 = invariants(y, p)[0]
    work = y[state_size(effects) - 1] if effects & DISSIPATIVE else 0.0
    scale = max(abs(E0), kinetic_energy(y0, p))
    drift = abs(E1 + work - E0) / scale
    return fate, t, y[0], y[1], abs(y[1]) / (2.0 * math.pi), E0 - E1, drift, steps


@parallel_kernel
def fate_points(alpha, energy, h, Lz, r_start, params, method, effects, rtol, t_horizon,
                max_steps, out_fate, out_f, out_n):  # fmt: skip
    """:func:`fate_of` for every point, in parallel (``method``, ``effects``: literal ints).

    Writes ``out_fate`` int8[n], ``out_f`` float64[6, n] (rows :data:`FATE_ROWS`) and
    ``out_n`` int64[n] steps.
    """
    literally(method)
    literally(effects)
    for i in prange(alpha.shape[0]):
        p = params.copy()
        set_alpha(p, alpha[i])
        fate, t, r, th, rev, lost, drift, steps = fate_of(
            method, effects, p, energy[i], h[i], Lz[i], r_start[i], rtol, t_horizon, max_steps
        )
        out_fate[i] = fate
        out_f[0, i] = t
        out_f[1, i] = r
        out_f[2, i] = th
        out_f[3, i] = rev
        out_f[4, i] = lost
        out_f[5, i] = drift
        out_n[i] = steps

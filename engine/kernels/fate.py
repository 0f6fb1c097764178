"""Fate maps: each orbit integrated from its start to its first terminal event or a horizon.

A fate run follows the run protocol (:func:`.orbit.run`) with the scene's terminal events
compiled in (the rim, the slip check, the vertex region, and with rolling resistance the
stop; with a horizon in revolutions, the azimuth), then says what happened
(:data:`FATE_NAMES`). Rolling resistance cannot push a sphere at rest backwards: when the
speed falls to the rest threshold (``P_V_REST``, 10 rtol times the orbit's speed scale) the
stop is carried on to zero speed at the deceleration there (:func:`come_to_rest`); the
sphere stays at rest if the resistance can hold it there (cot(alpha) <= c_rr: only on nearly
flat cones) and friction can too (cot(alpha) <= mu, else it slips); otherwise it starts again
from rest, and rolls down towards the vertex (docs/physics.md "Effects beyond the ideal cone").

Where a run starts, as the closed form says (:func:`.geometry.scene_end`): an orbit that
starts beyond the rim has no orbit on this cone; a radial orbit (r_min = 0) leaves the vertex;
the vertex event is the centre *entering* its region, so an orbit that starts there at its
r_min leaves it first, and one that starts there moving inward has reached it at t = 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, prange

from .._jit import kernel, parallel_kernel
from .cone_starts import holds_at_rest as holds_at_rest  # the hybrid stories' (the cone's)
from .effects import DISSIPATIVE
from .fate_codes import (
    FAILED,
    FATE_LIFTED_OFF,
    FATE_NAMES,
    FATE_REST,
    FATE_ROWS,
    FATE_SLIPPED,
    FATE_SPILLED,
    FATE_VERTEX,
    NO_ORBIT,
    REST_SPEED,
    ROLLING,
    RUNS,
)
from .layouts import Y_R, Y_THETA, Y_U, Y_V, Y_W, state_size
from .model import (
    ROLLING_RESISTANCE,
    SLIP_CHECK,
    dissipated_power,
    energy,
    fate_start,
    kinetic_energy,
    motion_rates,
    set_point,
    slip_margin,
)
from .model import holds_at_rest as model_holds_at_rest
from .orbit import RUN_EVENTS, run
from .protocol import (
    APOCENTRE,
    AT_VERTEX,
    LIFTED_OFF,
    MAX_STEPS,
    OK,
    RECORD_NONE,
    RESTED,
    SLIP,
    SLIPPED,
    SPILLED,
    copy_into,
    event_buffers,
)

#: Restarts from rest (a sphere that rolls down again) before a run is called failed.
MAX_RESTARTS = 10_000
#: The fate vocabulary (:mod:`.fate_codes`), where the kernels and the API found it.
__all__ = ["FAILED", "FATE_NAMES", "FATE_REST", "FATE_ROWS", "FATE_SLIPPED", "FATE_SPILLED",
           "FATE_VERTEX", "NO_ORBIT", "REST_SPEED", "ROLLING", "holds_at_rest"]  # fmt: skip


@kernel
def fate_of_status(status):
    """The fate of a run that ended with ``status`` (:func:`run_restarting`'s: RESTED, the
    sphere stays at rest)."""
    if status == OK:
        return ROLLING
    if status == SPILLED:
        return FATE_SPILLED
    if status == SLIPPED:
        return FATE_SLIPPED
    if status == AT_VERTEX:
        return FATE_VERTEX
    if status == RESTED:
        return FATE_REST
    if status == LIFTED_OFF:
        return FATE_LIFTED_OFF
    return FAILED


@kernel
def come_to_rest(y, p, effects):
    """Carry a stop by rolling resistance from the rest threshold to zero speed, in place: the
    speed falls at the deceleration d|V|/dt of y, so it reaches 0 after dt = |V| / (-d|V|/dt)
    and the centre moves on by half the distance at constant speed (the error is of order
    (|V| dt)^2: the threshold squared); the work state takes the power's half too (the
    attitude is left as it is, a rotation of |V| dt / (2 a) ~ 1e-10 rad). Returns (dt [s],
    what happens at rest): RESTED if the sphere stays (the resistance holds it and the
    friction it then needs, the whole slope pull, is within mu N), SLIPPED if friction cannot
    hold it, OK if the resistance cannot (it starts again from rest)."""
    u = y[Y_U]
    v = y[Y_V]
    speed = math.sqrt(u * u + v * v)
    dt = 0.0
    if speed > 0.0:
        rates = motion_rates(y[Y_R], u, v, y[Y_W], p, effects)
        decel = -(u * rates[2] + v * rates[3]) / speed
        dt = speed / decel if decel > 0.0 else 0.0
        half = 0.5 * dt
        if effects & DISSIPATIVE:
            y[state_size(effects) - 1] += dissipated_power(y[Y_R], u, v, y[Y_W], p, effects) * half
        y[Y_R] += u * half
        y[Y_THETA] += rates[1] * half
        y[Y_W] += rates[4] * half
        y[Y_U] = 0.0
        y[Y_V] = 0.0
    if not model_holds_at_rest(p, y, effects):
        return dt, OK
    if effects & SLIP_CHECK:
        if slip_margin(y, p, effects) > 0.0:
            return dt, SLIPPED
    return dt, RESTED


@kernel
def starts_at_rest(effects, y, p):
    """Whether a run from y ends before it starts: a sphere at rest where rolling resistance
    holds it (status RESTED) or friction cannot (SLIPPED). Returns (ended, status)."""
    if effects & ROLLING_RESISTANCE:
        if y[Y_U] == 0.0 and y[Y_V] == 0.0:
            _, at_rest = come_to_rest(y, p, effects)
            return at_rest != OK, at_rest
    return False, OK


@kernel
def after_run(effects, status, y, p, t):
    """What follows a run that ended with ``status`` at state y (time t [s] since the start):
    the end (the run's status; at a stop by rolling resistance, RESTED where the sphere stays
    at rest, SLIPPED where friction cannot hold it), or a restart from rest (status OK). A
    stop is carried to zero speed in place (:func:`come_to_rest`). Returns (ended, status,
    t [s])."""
    if status != RESTED:
        return True, status, t
    dt, at_rest = come_to_rest(y, p, effects)
    return at_rest != OK, at_rest, t + dt


@kernel
def next_run(effects, status, y, p, t, restarts, steps, max_steps):
    """What follows a run that ended with ``status`` at state y, t [s] since the start, after
    ``restarts`` restarts and ``steps`` steps (:func:`after_run`), within the budget: a restart
    when ``steps`` >= ``max_steps`` or beyond :data:`MAX_RESTARTS` ends with status MAX_STEPS.
    Returns (ended, status, t [s]). The one restart rule of :func:`run_restarting` and of
    every lane's run (:func:`.lanes_fate.lane_run_ended`)."""
    ended, status, t = after_run(effects, status, y, p, t)
    if not ended and (steps >= max_steps or restarts + 1 >= MAX_RESTARTS):
        return True, MAX_STEPS, t
    return ended, status, t


@kernel
def run_restarting(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps,
                   record, dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
    """The run protocol (:func:`.orbit.run`: the same arguments and results) across stops by
    rolling resistance, the one rest/restart loop of the fate maps and ``engine.simulate``.

    Each stop is carried to zero speed (:func:`come_to_rest`): the stop's event and the last
    recorded state move there. It ends the run if the sphere stays at rest (status RESTED) or
    friction cannot hold it there (SLIPPED: the event becomes a slip); otherwise the sphere
    starts again from rest with time running on, recording on from the state at rest. Without
    recording only the last run's events are kept. A sphere that starts at rest where the
    resistance holds it stays (or slips) at t = 0. A restart beyond the budget (steps or
    :data:`MAX_RESTARTS`, :func:`next_run`): status MAX_STEPS.
    """
    y = y0.copy()
    n_acc = 0
    n_rej = 0
    n_ev = 0
    n_tr = 0
    t0 = 0.0
    ended, status = starts_at_rest(effects, y, p)
    if ended:
        return status, 0, 0, 0.0, y, 0, 0
    keep = record != RECORD_NONE
    restarts = 0
    while True:
        first = n_tr - 1 if n_tr > 0 else 0  # a restart's first state: the one at rest
        rate = tr_rate[first:] if tr_rate.shape[0] > 0 else tr_rate
        res = run(method, effects, y, p, orbit, rtol, atol, t_end - t0, n_apsides,
                  max_steps - n_acc - n_rej, record, dt_out, ev_t[n_ev:], ev_kind[n_ev:],
                  ev_y[n_ev:], tr_t[first:], tr_y[first:], rate)  # fmt: skip
        status = res[0]
        n_acc += res[1]
        n_rej += res[2]
        t = t0 + res[3]
        copy_into(res[4], y)
        for i in range(n_ev, n_ev + res[5]):
            ev_t[i] += t0
            if n_apsides > 0 and ev_kind[i] <= APOCENTRE:
                n_apsides -= 1
        for i in range(first, first + res[6]):
            tr_t[i] += t0
        n_ev += res[5]
        n_tr = first + res[6] if keep else 0
        stopped = status == RESTED
        ended, status, t = next_run(effects, status, y, p, t, restarts, n_acc + n_rej, max_steps)
        if stopped:  # the stop's event and last state, at zero speed
            if n_ev > 0:
                ev_t[n_ev - 1] = t
                copy_into(y, ev_y[n_ev - 1])
                if status == SLIPPED:
                    ev_kind[n_ev - 1] = SLIP
            if n_tr > 0:
                tr_t[n_tr - 1] = t
                copy_into(y, tr_y[n_tr - 1])
                if tr_rate.shape[0] > 0:
                    tr_rate[n_tr - 1, :] = 0.0
        if ended:
            return status, n_acc, n_rej, t, y, n_ev, n_tr
        t0 = t
        restarts += 1
        if not keep:
            n_ev = 0


@kernel
def fate_run(method, effects, p, y0, orbit, rtol, atol, t_horizon, max_steps):
    """Integrate from y0 at t = 0 to the first terminal event or ``t_horizon`` [s]:
    :func:`run_restarting` without recording. Returns (fate, t [s], final state, steps taken).
    """
    ev_t, ev_kind, ev_y = event_buffers(RUN_EVENTS, y0.shape[0])
    res = run_restarting(method, effects, y0, p, orbit, rtol, atol, t_horizon, np.int64(-1),
                         max_steps, np.int64(RECORD_NONE), 0.0, ev_t, ev_kind, ev_y, ev_t, ev_y,
                         ev_y)  # fmt: skip
    return fate_of_status(res[0]), res[3], res[4], res[1] + res[2]


@kernel
def fate_result(effects, p, y0, t0, work0, fate, t, y, steps):
    """:func:`fate_of`'s result tuple of a run from y0 (started at t0 [s] with the work work0
    [J] done) that ended with ``fate`` at state y, t [s] after its start, in ``steps``."""
    E0 = energy(y0, p, effects) + work0  # the energy at the start (the vertex for radial orbits)
    E1 = energy(y, p, effects)
    work = y[state_size(effects) - 1] if effects & DISSIPATIVE else 0.0
    scale = max(abs(E0), kinetic_energy(y0, p))
    drift = abs(E1 + work - E0) / scale
    return (
        fate,
        t0 + t,
        y[Y_R],
        y[Y_THETA],
        abs(y[Y_THETA]) / (2.0 * math.pi),
        E0 - E1,
        drift,
        steps,
    )


@kernel
def fate_of(method, effects, p, X, i, rtol, t_horizon, max_steps):
    """The fate of point i (the columns ``X[:, i]`` of the points array, p holding its
    geometry), started where the model starts it (the cone's: at rest radially (u = 0) at
    r_start, its r_min or a launch radius, theta = 0, t = 0; a radial orbit's r_min is the
    vertex, which it leaves: module docstring).

    Returns (fate, time [s], r [m], theta [rad], revolutions, energy lost [J], drift of the
    energy balance E + W [1], W the work of the dissipative forces, steps).
    """
    start, r, y0, t0, work0, atol, orbit = fate_start(effects, p, X, i, rtol)
    if start != RUNS:
        return ended_at_start(start, r)
    fate, t, y, steps = fate_run(method, effects, p, y0, orbit, rtol, atol, t_horizon - t0,
                                 max_steps)  # fmt: skip
    return fate_result(effects, p, y0, t0, work0, fate, t, y, steps)


@kernel
def ended_at_start(fate, r):
    """:func:`fate_of`'s result tuple of a point whose fate is decided at its start: no orbit
    (NaN numbers), or the vertex at radius r at t = 0."""
    if fate == NO_ORBIT:
        nan = math.nan
        return NO_ORBIT, nan, nan, nan, nan, nan, nan, 0
    return fate, 0.0, r, 0.0, 0.0, 0.0, 0.0, 0


@parallel_kernel
def fate_points(X, params, method, effects, rtol, t_horizon, max_steps, out_fate, out_f, out_n):
    """:func:`fate_of` for every point (the columns of the points array X: the model's inputs,
    the cone's (alpha, calE, h, L_z, r_start)), in parallel (``method``, ``effects``: literal
    ints).

    Writes ``out_fate`` int8[n], ``out_f`` float64[6, n] (rows :data:`FATE_ROWS`) and
    ``out_n`` int64[n] steps.
    """
    literally(method)
    literally(effects)
    for i in prange(X.shape[1]):
        p = params.copy()
        set_point(p, X, i, effects)
        res = fate_of(method, effects, p, X, i, rtol, t_horizon, max_steps)
        store_fate(out_fate, out_f, out_n, i, res)


@kernel
def store_fate(out_fate, out_f, out_n, i, res):
    """Write :func:`fate_of`'s result tuple for point i (``out_f`` rows :data:`FATE_ROWS`)."""
    fate, t, r, th, rev, lost, drift, steps = res
    out_fate[i] = fate
    out_f[0, i] = t
    out_f[1, i] = r
    out_f[2, i] = th
    out_f[3, i] = rev
    out_f[4, i] = lost
    out_f[5, i] = drift
    out_n[i] = steps

"""The ball's whole story: rolling, slipping, sliding, rolling again, spilling, stopping
(docs/physics.md "Sliding, rolling again, and spin friction").

:func:`hybrid_fate_of` follows one launch through its modes. Rolling without spin friction runs
on the rolling integrators exactly as a fate map does (:func:`.fate.fate_run`: the same steps,
events and stop), so an orbit that never slips gets today's fate bit for bit; sliding, and
rolling with spin friction, run on the hybrid steps of :mod:`.hybrid_step`. A switch is an
event of the mode it leaves (the slip, the return to rolling); each is recorded.

``spin`` (a literal: 0 or 1) compiles spin friction in; ``effects`` is the rolling scene's
literal effect set (with :data:`.model.SLIP_CHECK`: the static friction limit).
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, prange

from .._jit import kernel, parallel_kernel
from .fate import (
    FAILED,
    FATE_REST,
    FATE_SLIPPED,
    FATE_SPILLED,
    FATE_VERTEX,
    MAX_RESTARTS,
    NO_ORBIT,
    REST_SPEED,
    ROLLING,
    fate_run,
    holds_at_rest,
)
from .hybrid_step import (
    ARMED_ROLL,
    ARMED_SPIN,
    EV_REST,
    EV_RIM,
    EV_SLIP,
    EV_SPIN_GO,
    EV_SPIN_STOP,
    EV_STICK,
    EV_THETA,
    EV_VERTEX,
    SEG_FAILED,
    SEG_TIME,
    ev_y_stick,
    push_event,
    release_spin,
    rolling_invariants,
    segment,
)
from .model import (
    P_COS,
    P_G,
    P_K,
    P_M,
    P_R_VERTEX,
    P_RIM,
    P_SIN,
    P_V_REST,
    ROLLING_RESISTANCE,
    invariants,
    invariants_of,
    kinetic_energy,
    motion_rates,
    radial_energy,
    set_alpha,
    state_size,
)
from .orbit import initial_state, orbit_start, tolerance_scales
from .rk_codegen import tableau
from .sliding import (
    MODE_ROLLING,
    MODE_SLIDING,
    N_HYBRID,
    hold_margin,
    hybrid_energy,
    hybrid_params,
    spin_hold_margin,
    stick,
)

#: Fate codes beyond :data:`.fate.FATE_NAMES`: still sliding at the horizon.
SLIDING = 7
HYBRID_FATE_NAMES = ("no_orbit", "rolling", "spilled", "slipped", "rest", "vertex", "failed",
                     "sliding")  # fmt: skip
#: Rows of the float output of :func:`hybrid_fate_points`.
HYBRID_ROWS = ("fate_time", "fate_r", "fate_theta", "revolutions", "energy_lost",
               "invariant_drift", "slide_time", "slip_episodes", "fate_speed", "final_energy",
               "final_h", "final_Lz", "lost_rolling_resistance", "lost_sliding_friction",
               "lost_spin_friction")  # fmt: skip


@kernel
def _energy(y, hp, mode):
    """E [J] of the hybrid state: the rolling formula while rolling (as a fate map computes
    it), the sliding one otherwise."""
    if mode == MODE_ROLLING:
        return invariants_of(y[0], y[2], y[3], y[6], hp[P_SIN], hp[P_COS], hp[P_M], hp[P_G],
                             hp[P_K])[0]  # fmt: skip
    return hybrid_energy(y[0], y[2], y[3], y[4], y[5], y[6], hp)


@kernel
def hybrid_fate_of(method, effects, spin, p, mu_k, c_spin, energy, h, Lz, r_start, u0, slip_u,
                   slip_v, rtol, t_horizon, max_steps, ev_t, ev_kind, ev_y):  # fmt: skip
    """The whole story of the launch at ``r_start`` [m] on the rolling orbit (calE, h, L_z) (its
    v and w), with radial speed u0 [m/s] and the contact point's slip velocity (slip_u along
    the generatrix, slip_v along the parallel) [m/s] (0, 0: rolling).

    Returns (fate, floats (the rows :data:`HYBRID_ROWS`), steps, events recorded); the events
    (kind of :data:`.hybrid_step.HYBRID_EVENT_NAMES`, time, hybrid state) go to the buffers.
    """
    nan = math.nan
    out = np.full(len(HYBRID_ROWS), nan)
    if not (r_start >= 0.0 and math.isfinite(energy) and math.isfinite(Lz)):
        return NO_ORBIT, out, 0, 0
    if r_start > p[P_RIM]:  # beyond the rim, as a fate map says
        return NO_ORBIT, out, 0, 0
    M = p[P_M]
    e_true = energy + 0.5 * M * u0 * u0
    ok, r1, r2, rc = orbit_start(p, e_true, h, Lz)
    if not ok:
        r1 = r_start
        r2 = math.inf
    y0 = initial_state(p, effects, r_start, e_true, h, Lz)
    y0[2] = u0
    if r_start <= p[P_R_VERTEX]:  # in the vertex region: it ends there unless it leaves it
        leaves = u0 > 0.0 or (u0 == 0.0 and motion_rates(y0[0], 0.0, y0[3], y0[4], p,
                                                         effects)[2] > 0.0)  # fmt: skip
        if r_start == 0.0 or not leaves:
            out[:6] = np.array([0.0, r_start, 0.0, 0.0, 0.0, 0.0])
            return FATE_VERTEX, out, 0, 0
    sc = tolerance_scales(p, effects, y0, e_true, h, Lz, min(r1, r_start), r2, rc)
    p[P_V_REST] = REST_SPEED * rtol * max(max(sc[2], abs(y0[3])), max(abs(slip_u), abs(slip_v)))
    atol = sc * rtol
    hp = hybrid_params(p, mu_k, c_spin)
    y = np.zeros(N_HYBRID)
    y[0] = y0[0]
    y[2] = y0[2]
    y[3] = y0[3]
    y[4] = slip_v - y0[3]
    y[5] = y0[2] - slip_u
    y[6] = y0[4]
    vel = max(max(sc[2], sc[3]), max(sc[4], max(abs(slip_u), abs(slip_v))))
    hatol = np.empty(N_HYBRID)
    hatol[0] = atol[0]
    hatol[1] = rtol
    hatol[2] = atol[2]
    hatol[3] = atol[3]
    hatol[4] = rtol * vel
    hatol[5] = rtol * vel
    hatol[6] = atol[4]
    e_scale = max(abs(e_true), 0.5 * M * vel * vel)
    hatol[7] = rtol * e_scale
    hatol[8] = rtol * e_scale
    hatol[9] = rtol * e_scale
    mode = MODE_SLIDING if (slip_u != 0.0 or slip_v != 0.0) else MODE_ROLLING
    if mode == MODE_ROLLING:
        E0 = invariants(y0, p)[0]
        scale = max(abs(E0), kinetic_energy(y0, p))
    else:
        E0 = hybrid_energy(y[0], y[2], y[3], y[4], y[5], y[6], hp)
        scale = max(abs(E0), E0 - hybrid_energy(y[0], 0.0, 0.0, 0.0, 0.0, 0.0, hp))
    episodes = 1 if mode == MODE_SLIDING else 0
    stuck = spin == 1 and y[6] == 0.0 and spin_hold_margin(y, hp) <= 0.0
    armed = 0
    t = 0.0
    steps = 0
    n_ev = 0
    slide_time = 0.0
    restarts = 0
    fe = math.nan
    fh = math.nan
    fl = math.nan
    if mode == MODE_ROLLING:
        fe, fl, fh = energy, Lz, h
    nr = state_size(effects)
    S = tableau(method)[6]
    K = np.empty((S, N_HYBRID))
    ytmp = np.empty(N_HYBRID)
    ynew = np.empty(N_HYBRID)
    yev = np.empty(N_HYBRID)
    fate = FAILED
    while True:
        if steps >= max_steps or restarts > MAX_RESTARTS:
            fate = FAILED
            break
        if mode == MODE_ROLLING and spin == 0:
            yr = np.zeros(nr)
            yr[0] = y[0]
            yr[1] = y[1]
            yr[2] = y[2]
            yr[3] = y[3]
            yr[4] = y[6]
            if effects & ROLLING_RESISTANCE:
                yr[nr - 1] = y[7]
            if episodes == 0:
                ra = atol
                orb = (energy, h, Lz)
                yr = y0
            else:
                E1, Lz1, h1 = invariants(yr, p)
                e1 = radial_energy(E1, h1, M, p[P_K])
                orb = (e1, h1, Lz1)
                ok1, q1, q2, qc = orbit_start(p, e1, h1, Lz1)
                if not ok1:
                    q1 = yr[0]
                    q2 = math.inf
                ra = tolerance_scales(p, effects, yr, e1, h1, Lz1, min(q1, yr[0]), q2, qc) * rtol
            f, dt, yr, st = fate_run(method, effects, p, yr, orb, rtol, ra, t_horizon - t,
                                     max_steps - steps)  # fmt: skip
            t += dt
            steps += st
            y[0] = yr[0]
            y[1] = yr[1]
            y[2] = yr[2]
            y[3] = yr[3]
            y[4] = -yr[3]
            y[5] = yr[2]
            y[6] = yr[4]
            if effects & ROLLING_RESISTANCE:
                y[7] = yr[nr - 1]
            if f != FATE_SLIPPED:
                fate = f
                if f == FATE_SPILLED:
                    n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, t, EV_RIM, y)
                elif f == FATE_VERTEX:
                    n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, t, EV_VERTEX, y)
                elif f == FATE_REST:
                    n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, t, EV_REST, y)
                break
            n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, t, EV_SLIP, y)
            mode = MODE_SLIDING
            episodes += 1
            armed &= ARMED_SPIN
            continue
        end, t, st, dt, armed = segment(method, y, hp, mode, stuck, armed, t, t_horizon, rtol,
                                        hatol, max_steps - steps, K, ytmp, ynew, yev)  # fmt: skip
        steps += st
        if mode == MODE_SLIDING:
            slide_time += dt
        if end == SEG_FAILED:
            fate = FAILED
            break
        if end == SEG_TIME or end == EV_THETA:
            fate = SLIDING if mode == MODE_SLIDING else ROLLING
            if end == EV_THETA:
                n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, t, end, y)
            break
        n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, t, end, y)
        if end == EV_RIM:
            fate = FATE_SPILLED
            break
        if end == EV_VERTEX:
            fate = FATE_VERTEX
            break
        if end == EV_SLIP:
            mode = MODE_SLIDING
            episodes += 1
            armed &= ARMED_SPIN
        elif end == EV_STICK:
            yt = y.copy()
            stick(yt, hp)
            if hold_margin(yt, hp) <= 0.0:
                stick(y, hp)
                ev_y_stick(ev_y, n_ev - 1, y)
                mode = MODE_ROLLING
                fe, fh, fl = rolling_invariants(y, hp)
            armed &= ARMED_SPIN
        elif end == EV_SPIN_STOP:  # |w| down to the threshold: the rest of it to spin friction
            y[9] += 0.5 * hp[P_K] * M * y[6] * y[6]
            y[6] = 0.0
            stuck = spin_hold_margin(y, hp) <= 0.0
            armed &= ARMED_ROLL
        elif end == EV_SPIN_GO:
            stuck = False
            release_spin(y, hp)
            armed &= ARMED_ROLL
        elif end == EV_REST:
            if holds_at_rest(p):
                fate = FATE_REST
                break
            y[2] = 0.0
            y[3] = 0.0
            y[4] = 0.0
            y[5] = 0.0
            restarts += 1
    if mode == MODE_SLIDING:
        fe = math.nan
        fh = math.nan
        fl = math.nan
    E1 = _energy(y, hp, mode)
    if mode == MODE_ROLLING and episodes == 0 and spin == 0:
        yr = y0.copy()
        yr[0] = y[0]
        yr[2] = y[2]
        yr[3] = y[3]
        yr[4] = y[6]
        E1 = invariants(yr, p)[0]
    work = y[7] + y[8] + y[9]
    out[0] = t
    out[1] = y[0]
    out[2] = y[1]
    out[3] = abs(y[1]) / (2.0 * math.pi)
    out[4] = E0 - E1
    out[5] = abs(E1 + work - E0) / scale
    out[6] = slide_time
    out[7] = episodes
    out[8] = math.sqrt(y[2] * y[2] + y[3] * y[3])
    out[9] = fe
    out[10] = fh
    out[11] = fl
    out[12] = y[7]
    out[13] = y[8]
    out[14] = y[9]
    return fate, out, steps, n_ev


@parallel_kernel
def hybrid_fate_points(alpha, energy, h, Lz, r_start, u0, slip_u, slip_v, params, mu_k, c_spin,
                       method, effects, spin, rtol, t_horizon, max_steps, out_fate, out_f,
                       out_n):  # fmt: skip
    """:func:`hybrid_fate_of` for every point, in parallel (``method``, ``effects``, ``spin``:
    literal ints). Writes ``out_fate`` int8[n], ``out_f`` float64[len(HYBRID_ROWS), n] and
    ``out_n`` int64[n] steps."""
    literally(method)
    literally(effects)
    literally(spin)
    for i in prange(alpha.shape[0]):
        p = params.copy()
        set_alpha(p, alpha[i])
        ev_t = np.empty(0)
        ev_kind = np.empty(0, np.int8)
        ev_y = np.empty((0, N_HYBRID))
        fate, f, steps, _ = hybrid_fate_of(method, effects, spin, p, mu_k, c_spin, energy[i],
                                           h[i], Lz[i], r_start[i], u0[i], slip_u[i],
                                           slip_v[i], rtol, t_horizon, max_steps, ev_t,
                                           ev_kind, ev_y)  # fmt: skip
        out_fate[i] = fate
        for j in range(f.shape[0]):
            out_f[j, i] = f[j]
        out_n[i] = steps


@kernel
def hybrid_story(method, effects, spin, p, mu_k, c_spin, energy, h, Lz, r_start, u0, slip_u,
                 slip_v, rtol, t_horizon, max_steps, capacity):  # fmt: skip
    """:func:`hybrid_fate_of` of one launch with its events kept (at most ``capacity``):
    (fate, floats, steps, n_events, event times, kinds, states)."""
    literally(method)
    literally(effects)
    literally(spin)
    ev_t = np.empty(capacity)
    ev_kind = np.empty(capacity, np.int8)
    ev_y = np.empty((capacity, N_HYBRID))
    fate, f, steps, n_ev = hybrid_fate_of(method, effects, spin, p, mu_k, c_spin, energy, h, Lz,
                                          r_start, u0, slip_u, slip_v, rtol, t_horizon,
                                          max_steps, ev_t, ev_kind, ev_y)  # fmt: skip
    return fate, f, steps, n_ev, ev_t, ev_kind, ev_y

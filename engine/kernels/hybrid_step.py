"""Adaptive Runge-Kutta steps of the hybrid state (:mod:`.sliding`) and its events.

The steps use the tableaux of :data:`.tableaux.RK_TABLEAUX` (the literal ``method`` id, as the
rolling integrators) with the same error norm and step-size controller (:mod:`.rk`), written
as loops over the components. An event is located by re-stepping from the start of the step
that crossed it (Illinois' rule on the fraction of the step), so the state at an event is a
Runge-Kutta step of the method's order: no dense output is needed.

Events (:data:`HYBRID_EVENT_NAMES`): a function g of the state that fires where it reaches 0
from below (the slip and the spin's release: above 0) within a step. Which are on depends on
the mode (rolling or sliding), the spin stick and the arming of the return to rolling
(docs/physics.md "Switching between rolling and sliding").
"""

from __future__ import annotations

import math

from .._jit import kernel
from .model import (
    P_COS,
    P_CRR,
    P_G,
    P_K,
    P_M,
    P_MU,
    P_R_VERTEX,
    P_RIM,
    P_SIN,
    P_THETA_MAX,
    P_V_REST,
    invariants_of,
    radial_energy,
)
from .protocol import EPS
from .rk import step_decide, step_error
from .rk_codegen import controller, tableau
from .sliding import (
    H_C_SPIN,
    MODE_ROLLING,
    MODE_SLIDING,
    N_HYBRID,
    hold_margin,
    hybrid_rhs,
    slip_speed,
    spin_hold_margin,
)

EV_RIM = 0
EV_VERTEX = 1
EV_THETA = 2
EV_SLIP = 3
EV_STICK = 4
EV_SPIN_STOP = 5
EV_SPIN_GO = 6
EV_REST = 7
N_EVENTS = 8
HYBRID_EVENT_NAMES = ("spill", "vertex", "horizon", "slip", "roll", "spin_stop", "spin_go",
                      "rest")  # fmt: skip
#: Bits of ``armed``: the return to rolling (the slip speed has exceeded twice the threshold
#: since the last switch) and the spin's stop (|w| has, since the last stop or release).
ARMED_ROLL = 1
ARMED_SPIN = 2
#: The slip within this many stop thresholds may be declared stopped when a step cannot make it
#: smaller (:func:`stalled`).
STALL_BAND = 1000.0
#: Largest number of function evaluations (re-steps) to locate one event.
LOCATE_ITERATIONS = 60


@kernel
def hybrid_attempt(method, y, h, hp, mode, stuck, K, ytmp, ynew, rtol, atol):
    """One step of size h [s] from y with K[0] = f(y) given: writes the stages K[1..ns],
    ``ynew`` and K[ns] = f(ynew); returns the scaled error (accept when <= 1)."""
    A, C, E, E3, P, ns, S, q, beta, bw, fmax = tableau(method)
    n = y.shape[0]
    for i in range(1, ns + 1):
        for j in range(n):
            acc = 0.0
            for m in range(i):
                acc += A[i, m] * K[m, j]
            ytmp[j] = y[j] + h * acc
        hybrid_rhs(ytmp, hp, mode, stuck, K[i])
    e5 = 0.0
    e3 = 0.0
    for j in range(n):
        ynew[j] = ytmp[j]
        sc = atol[j] + rtol * max(abs(y[j]), abs(ynew[j]))
        d = 0.0
        d3 = 0.0
        for m in range(ns + 1):
            d += E[m] * K[m, j]
            d3 += E3[m] * K[m, j]
        e5 += (d / sc) ** 2
        e3 += (d3 / sc) ** 2
    if e3 > 0.0:
        return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n) if e5 != 0.0 else 0.0
    return abs(h) * math.sqrt(e5 / n)


@kernel
def event_value(kind, y, hp, mode, stuck, armed, ref):
    """g(y) of event ``kind``, or -inf where it is off. ``ref`` = (sign of w, slip direction
    (d1, d2)) at the start of the step: the spin's stop is w crossing 0, and the return to
    rolling is the slip's component along its direction at the step's start falling to the
    threshold (so a step that carries the slip through zero still fires it)."""
    w_sign, sd1, sd2 = ref
    off = -math.inf
    if kind == EV_RIM:
        return y[0] - hp[P_RIM]
    if kind == EV_VERTEX:
        return hp[P_R_VERTEX] - y[0]
    if kind == EV_THETA:
        return abs(y[1]) - hp[P_THETA_MAX]
    if kind == EV_SLIP:
        return hold_margin(y, hp) if mode == MODE_ROLLING and hp[P_MU] < math.inf else off
    if kind == EV_STICK:
        if mode != MODE_SLIDING or not armed & ARMED_ROLL:
            return off
        return hp[P_V_REST] - ((y[2] - y[5]) * sd1 + (y[3] + y[4]) * sd2)
    if kind == EV_SPIN_STOP:
        if stuck or hp[H_C_SPIN] == 0.0 or w_sign == 0.0 or not armed & ARMED_SPIN:
            return off
        return hp[P_V_REST] - w_sign * y[6]
    if kind == EV_SPIN_GO:
        return spin_hold_margin(y, hp) if stuck else off
    if kind == EV_REST:
        if mode != MODE_ROLLING or hp[P_CRR] == 0.0:  # the stop needs rolling resistance
            return off
        return hp[P_V_REST] - math.sqrt(y[2] * y[2] + y[3] * y[3])
    return off


@kernel
def fired(kind, g0, g1):
    """Whether event ``kind`` happened in a step whose start and end give g0 and g1."""
    if kind == EV_SLIP or kind == EV_SPIN_GO:
        return g0 <= 0.0 and g1 > 0.0
    return g0 < 0.0 and g1 >= 0.0


@kernel
def locate(method, kind, y0, h, hp, mode, stuck, armed, ref, K, ytmp, yout, rtol, atol, g0,
           g1):  # fmt: skip
    """The fraction theta in (0, 1] of the step h [s] from y0 where event ``kind`` fires (the
    upper end of the final bracket, where it has fired), with the state there in ``yout``.
    K[0] must hold f(y0); it is kept."""
    lo = 0.0
    hi = 1.0
    glo = g0
    ghi = g1
    side = 0
    for _ in range(LOCATE_ITERATIONS):
        if (hi - lo) * abs(h) <= 4e-16 * abs(h) + 1e-300:
            break
        th = (lo * ghi - hi * glo) / (ghi - glo) if ghi != glo else 0.5 * (lo + hi)
        if not (lo < th < hi):
            th = 0.5 * (lo + hi)
        hybrid_attempt(method, y0, th * h, hp, mode, stuck, K, ytmp, yout, rtol, atol)
        g = event_value(kind, yout, hp, mode, stuck, armed, ref)
        if fired(kind, glo, g):
            hi = th
            ghi = g
            if side == -1:
                glo *= 0.5
            side = -1
        else:
            lo = th
            glo = g
            if side == 1:
                ghi *= 0.5
            side = 1
        if hi - lo < 1e-15:
            break
    hybrid_attempt(method, y0, hi * h, hp, mode, stuck, K, ytmp, yout, rtol, atol)
    return hi


@kernel
def step_controller(method):
    """The controller constants of ``method`` (:func:`.rk_codegen.controller`)."""
    return controller(method)


@kernel
def decide(e_err, r_new, h, err_old, rejected, ctl):
    """The rolling integrators' step decision (:func:`.rk.step_decide`) for the hybrid steps."""
    return step_decide(step_error(e_err, r_new, ctl), h, err_old, rejected, ctl)


@kernel
def first_event(method, y0, y1, h, hp, mode, stuck, armed, K, ytmp, yout, rtol, atol):
    """The earliest event of the accepted step y0 -> y1 of size h [s]: (kind or -1, theta);
    its state is left in ``yout`` (K[0] = f(y0) is kept)."""
    w_ref = y0[6] if y0[6] != 0.0 else y1[6]  # a spin leaving zero: the way it went
    w_sign = 0.0 if w_ref == 0.0 else math.copysign(1.0, w_ref)
    sl = slip_speed(y0)
    isl = 1.0 / sl if sl > 0.0 else 0.0
    ref = (w_sign, (y0[2] - y0[5]) * isl, (y0[3] + y0[4]) * isl)
    best = -1
    best_th = 2.0
    for kind in range(N_EVENTS):
        g0 = event_value(kind, y0, hp, mode, stuck, armed, ref)
        if g0 == -math.inf:
            continue
        g1 = event_value(kind, y1, hp, mode, stuck, armed, ref)
        if fired(kind, g0, g1):
            th = locate(method, kind, y0, h, hp, mode, stuck, armed, ref, K, ytmp, ytmp,
                        rtol, atol, g0, g1)  # fmt: skip
            if th < best_th:
                best = kind
                best_th = th
    if best >= 0:
        hybrid_attempt(method, y0, best_th * h, hp, mode, stuck, K, ytmp, yout, rtol, atol)
    return best, best_th


@kernel
def kink_step(method, y, h, hp, mode, stuck, armed, K):
    """The step [s] to retry with when the attempt of size h [s] from y (stages in K) went
    through a kink of the right-hand side that an armed event must stop at, else h.

    The kinks: the slip s = 0 while sliding with the return to rolling armed, where kinetic
    friction turns (reverses) with the slip; the spin w = 0 with spin friction on, the spin not
    stuck and its stop armed, where the spin couple jumps. A stage went through one when its
    slip has a component <= 0 along the slip at y (its spin: the sign of w at y flipped). Such
    a step cannot be trusted (the error estimate of a step across a kink can pass, and a run
    of them keeps |s| a few times the stop threshold forever: docs/physics.md "Reaching the
    switch"), so it is retried with min(h/2, the time the slip (spin) takes at its rate at y
    to fall to half the stop threshold)."""
    A = tableau(method)[0]
    ns = tableau(method)[5]
    v_rest = hp[P_V_REST]
    s1 = y[2] - y[5]
    s2 = y[3] + y[4]
    sl = math.sqrt(s1 * s1 + s2 * s2)
    slip_on = mode == MODE_SLIDING and armed & ARMED_ROLL and sl > v_rest
    w0 = y[6]
    spin_on = not stuck and hp[H_C_SPIN] > 0.0 and armed & ARMED_SPIN and abs(w0) > v_rest
    if not slip_on and not spin_on:
        return h
    slip_x = False
    spin_x = False
    for i in range(1, ns + 1):
        a2 = 0.0
        a3 = 0.0
        a4 = 0.0
        a5 = 0.0
        a6 = 0.0
        for m in range(i):
            a2 += A[i, m] * K[m, 2]
            a3 += A[i, m] * K[m, 3]
            a4 += A[i, m] * K[m, 4]
            a5 += A[i, m] * K[m, 5]
            a6 += A[i, m] * K[m, 6]
        if slip_on and (s1 + h * (a2 - a5)) * s1 + (s2 + h * (a3 + a4)) * s2 <= 0.0:
            slip_x = True
        if spin_on and (w0 + h * a6) * w0 <= 0.0:
            spin_x = True
    if not slip_x and not spin_x:
        return h
    h_new = 0.5 * h
    if slip_x:
        rate = -((K[0, 2] - K[0, 5]) * s1 + (K[0, 3] + K[0, 4]) * s2) / sl
        if rate > 0.0:
            h_new = min(h_new, (sl - 0.5 * v_rest) / rate)
    if spin_x:
        rate = -math.copysign(1.0, w0) * K[0, 6]
        if rate > 0.0:
            h_new = min(h_new, (abs(w0) - 0.5 * v_rest) / rate)
    return h_new


@kernel
def stalled(y, ynew, K, hp):
    """Whether the accepted sliding step y -> ynew (K[0] = f(y)) left the slip no smaller along
    its direction at y although friction is slowing it there (its rate along that direction is
    < 0), with the slip within :data:`STALL_BAND` times the stop threshold: the slip is then
    as near zero as the integration resolves it (docs/physics.md "Reaching the switch")."""
    s1 = y[2] - y[5]
    s2 = y[3] + y[4]
    sl = math.sqrt(s1 * s1 + s2 * s2)
    if not 0.0 < sl <= STALL_BAND * hp[P_V_REST]:
        return False
    rate = (K[0, 2] - K[0, 5]) * s1 + (K[0, 3] + K[0, 4]) * s2
    along = (ynew[2] - ynew[5]) * s1 + (ynew[3] + ynew[4]) * s2
    return rate < 0.0 and along >= sl * sl


#: Segment ends of :func:`segment` beyond the event kinds of :mod:`.hybrid_step`.
SEG_TIME = 100
SEG_FAILED = 101


@kernel
def segment(method, y, hp, mode, stuck, armed, t, t_end, rtol, atol, max_steps, K, ytmp, ynew,
            yev):  # fmt: skip
    """Integrate the hybrid state y in ``mode`` from t [s] to its first event or t_end.

    Returns (end: an event kind, :data:`SEG_TIME` or :data:`SEG_FAILED`; t [s]; attempts;
    time spent [s]; armed). y is updated in place (to the event's state)."""
    A, C, E, E3, P, ns, S, q, beta, bw, fmax = tableau(method)
    ctl = step_controller(method)
    n = y.shape[0]
    hybrid_rhs(y, hp, mode, stuck, K[0])
    d0 = 0.0
    d1 = 0.0
    for j in range(n):
        sc = atol[j] + rtol * abs(y[j])
        d0 += (y[j] / sc) ** 2
        d1 += (K[0, j] / sc) ** 2
    h = 0.01 * math.sqrt(d0 / d1) if d1 > 1e-10 and d0 > 1e-10 else 1e-6
    err_old = 1e-4
    rejected = False
    steps = 0
    t0 = t
    while True:
        if steps >= max_steps:
            return SEG_FAILED, t, steps, t - t0, armed
        h_try = min(h, t_end - t)
        if not h_try > 16.0 * EPS * abs(t) and h_try < h:
            return SEG_TIME, t, steps, t - t0, armed
        if not h_try > 16.0 * EPS * abs(t):
            return SEG_FAILED, t, steps, t - t0, armed
        err = hybrid_attempt(method, y, h_try, hp, mode, stuck, K, ytmp, ynew, rtol, atol)
        steps += 1
        h_kink = kink_step(method, y, h_try, hp, mode, stuck, armed, K)
        if h_kink < h_try:  # a stage went through s = 0 or w = 0: retry short of it
            h = h_kink
            rejected = True
            continue
        accepted, h_used, h_next, err_old, rejected = decide(err, ynew[0], h_try, err_old,
                                                             rejected, ctl)  # fmt: skip
        if not accepted:
            h = h_used
            continue
        kind, th = first_event(method, y, ynew, h_try, hp, mode, stuck, armed, K, ytmp, yev,
                               rtol, atol)  # fmt: skip
        if kind < 0 and mode == MODE_SLIDING and armed & ARMED_ROLL and stalled(y, ynew, K, hp):
            kind = EV_STICK  # the slip is as near zero as the steps can follow it
            th = 1.0
            for j in range(n):
                yev[j] = ynew[j]
        if kind >= 0:
            for j in range(n):
                y[j] = yev[j]
            t += th * h_try
            return kind, t, steps, t - t0, armed
        for j in range(n):
            y[j] = ynew[j]
            K[0, j] = K[ns, j]
            if not math.isfinite(y[j]):
                return SEG_FAILED, t, steps, t - t0, armed
        t += h_try
        if mode == MODE_SLIDING and slip_speed(y) > 2.0 * hp[P_V_REST]:
            armed |= ARMED_ROLL
        if not stuck and abs(y[6]) > 2.0 * hp[P_V_REST]:
            armed |= ARMED_SPIN
        if t >= t_end:
            return SEG_TIME, t, steps, t - t0, armed
        h = h_next


@kernel
def rolling_invariants(y, hp):
    """(calE [J], h [m/s], L_z) of the rolling hybrid state y."""
    M = hp[P_M]
    k = hp[P_K]
    E, Lz, h = invariants_of(y[0], y[2], y[3], y[6], hp[P_SIN], hp[P_COS], M, hp[P_G], k)
    return radial_energy(E, h, M, k), h, Lz


@kernel
def ev_y_stick(ev_y, i, y):
    """Replace the recorded state of event i by y (the state after the sticking impulse)."""
    if 0 <= i < ev_y.shape[0]:
        for j in range(N_HYBRID):
            ev_y[i, j] = y[j]


@kernel
def push_event(ev_t, ev_kind, ev_y, n_ev, t, kind, y):
    """Record event ``kind`` at t [s] with state y if there is room; returns the count."""
    if n_ev < ev_t.shape[0]:
        ev_t[n_ev] = t
        ev_kind[n_ev] = kind
        for j in range(N_HYBRID):
            ev_y[n_ev, j] = y[j]
    return n_ev + 1


@kernel
def release_spin(y, hp):
    """The spin leaves the stick: w = 0, not stuck (the couple is then static Coulomb friction
    at w = 0, :func:`.sliding.couples`, and the spin's sign is taken from where it goes)."""
    y[6] = 0.0

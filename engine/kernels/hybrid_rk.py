"""One accepted Runge-Kutta step of the hybrid state (:mod:`.sliding`), with every rule of the
step in one place: the attempt, the retry of a step through a kink, the step decision and the
arming of the stops. The story (:func:`.hybrid_step.segment`) and the sampled trajectory
(:func:`.trajectory.trace_stretches`) both step with :func:`advance`.

The steps use the tableaux of :data:`.tableaux.RK_TABLEAUX` (the literal ``method`` id, as the
rolling integrators) with the same error norm and step-size controller (:mod:`.rk`), written
as loops over the components.
"""

from __future__ import annotations

import math

from .._jit import kernel
from .contact import domain_floor
from .layouts import P_CRR, P_V_REST
from .protocol import EPS
from .rk import step_decide, step_error
from .rk_codegen import controller, tableau
from .sliding import (
    H_C_SPIN,
    MODE_SLIDING,
    YH_P1,
    YH_P2,
    YH_R,
    YH_U,
    YH_V,
    YH_W,
    hybrid_rhs,
    slip_speed,
)

#: Bits of ``armed``: the return to rolling (the slip speed has exceeded twice the threshold
#: since the last switch), the spin's stop (|w| has, since the last stop or release) and the
#: tangential spin's stop while sliding (|(p1, p2)| has, where rolling resistance can hold it
#: at zero: c_rr > mu_k; docs/physics.md "Rolling resistance while sliding").
ARMED_ROLL = 1
ARMED_SPIN = 2
ARMED_ROT = 4
#: The slip within this many stop thresholds may be declared stopped when a step cannot make it
#: smaller (:func:`stalled`).
STALL_BAND = 1000.0
#: Outcomes of :func:`advance`: a step accepted; t_end within rounding of t (no step taken);
#: the step size fell below rounding of t; the step budget is spent.
ADV_OK = 0
ADV_REACHED = 1
ADV_TOO_SMALL = 2
ADV_MAX_STEPS = 3


@kernel
def hybrid_attempt(method, model, y, h, hp, mode, stuck, K, ytmp, ynew, rtol, atol):
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
        hybrid_rhs(model, ytmp, hp, mode, stuck, K[i])
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
def step_controller(method):
    """The controller constants of ``method`` (:func:`.rk_codegen.controller`)."""
    return controller(method)


@kernel
def decide(e_err, r_new, h, err_old, rejected, ctl):
    """The rolling integrators' step decision (:func:`.rk.step_decide`) for the hybrid steps."""
    return step_decide(step_error(e_err, r_new, ctl), h, err_old, rejected, ctl)


@kernel
def first_step(model, y, hp, mode, stuck, K, rtol, atol):
    """Writes K[0] = f(y) and returns the first trial step [s] from y (1 % of the state's
    scaled size over its scaled rate, as the rolling integrators start)."""
    hybrid_rhs(model, y, hp, mode, stuck, K[0])
    d0 = 0.0
    d1 = 0.0
    for j in range(y.shape[0]):
        sc = atol[j] + rtol * abs(y[j])
        d0 += (y[j] / sc) ** 2
        d1 += (K[0, j] / sc) ** 2
    return 0.01 * math.sqrt(d0 / d1) if d1 > 1e-10 and d0 > 1e-10 else 1e-6


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
    s1 = y[YH_U] - y[YH_P2]
    s2 = y[YH_V] + y[YH_P1]
    sl = math.sqrt(s1 * s1 + s2 * s2)
    slip_on = mode == MODE_SLIDING and armed & ARMED_ROLL and sl > v_rest
    w0 = y[YH_W]
    spin_on = not stuck and hp[H_C_SPIN] > 0.0 and armed & ARMED_SPIN and abs(w0) > v_rest
    q1 = y[YH_P1]
    q2 = y[YH_P2]
    ql = math.sqrt(q1 * q1 + q2 * q2)
    rot_on = mode == MODE_SLIDING and armed & ARMED_ROT and ql > v_rest
    u0 = y[YH_U]
    v0 = y[YH_V]
    speed = math.sqrt(u0 * u0 + v0 * v0)
    rest_on = mode != MODE_SLIDING and hp[P_CRR] > 0.0 and speed > v_rest
    if not slip_on and not spin_on and not rot_on and not rest_on:
        return h
    slip_x = False
    spin_x = False
    rot_x = False
    rest_x = False
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
        if rot_on and (q1 + h * a4) * q1 + (q2 + h * a5) * q2 <= 0.0:
            rot_x = True
        if rest_on and (u0 + h * a2) * u0 + (v0 + h * a3) * v0 <= 0.0:
            rest_x = True
    if not slip_x and not spin_x and not rot_x and not rest_x:
        return h
    h_new = 0.5 * h
    if slip_x:
        rate = -((K[0, YH_U] - K[0, YH_P2]) * s1 + (K[0, YH_V] + K[0, YH_P1]) * s2) / sl
        if rate > 0.0:
            h_new = min(h_new, (sl - 0.5 * v_rest) / rate)
    if spin_x:
        rate = -math.copysign(1.0, w0) * K[0, YH_W]
        if rate > 0.0:
            h_new = min(h_new, (abs(w0) - 0.5 * v_rest) / rate)
    if rot_x:
        rate = -(K[0, YH_P1] * q1 + K[0, YH_P2] * q2) / ql
        if rate > 0.0:
            h_new = min(h_new, (ql - 0.5 * v_rest) / rate)
    if rest_x:
        rate = -(K[0, YH_U] * u0 + K[0, YH_V] * v0) / speed
        if rate > 0.0:
            h_new = min(h_new, (speed - 0.5 * v_rest) / rate)
    return h_new


@kernel
def advance(method, model, y, t, t_end, h, hp, mode, stuck, armed, K, ytmp, ynew, rtol, atol, ctl,
            err_old, rejected, steps, max_steps):  # fmt: skip
    """Attempt steps from (t, y) towards t_end [s], first of size h [s], until one is accepted:
    a step through a kink (:func:`kink_step`) is retried short of it, a step the decision
    (:func:`decide`) rejects is retried with the smaller size it gives. K[0] must hold f(y).

    Returns (outcome (:data:`ADV_OK` and the others), the accepted step h_try [s], the next
    step [s], err_old, rejected, steps (attempts counted on from ``steps``)). On ADV_OK the
    accepted state is in ``ynew`` and K[ns] = f(ynew); y is not changed."""
    while True:
        if steps >= max_steps:
            return ADV_MAX_STEPS, 0.0, h, err_old, rejected, steps
        h_try = min(h, t_end - t)
        if not h_try > 16.0 * EPS * abs(t):
            if h_try < h:  # t_end is within rounding of t
                return ADV_REACHED, 0.0, h, err_old, rejected, steps
            return ADV_TOO_SMALL, 0.0, h, err_old, rejected, steps
        err = hybrid_attempt(method, model, y, h_try, hp, mode, stuck, K, ytmp, ynew, rtol, atol)
        steps += 1
        h_kink = kink_step(method, y, h_try, hp, mode, stuck, armed, K)
        if h_kink < h_try:  # a stage went through s = 0 or w = 0: retry short of it
            h = h_kink
            rejected = True
            continue
        inside = ynew[YH_R] - domain_floor(model, hp)  # > 0: in the model's domain
        accepted, h_used, h_next, err_old, rejected = decide(err, inside, h_try, err_old,
                                                             rejected, ctl)  # fmt: skip
        if accepted:
            return ADV_OK, h_try, h_next, err_old, rejected, steps
        h = h_used


@kernel
def arm(y, hp, mode, stuck, armed):
    """``armed`` after an accepted step to y: the return to rolling once the slip speed exceeds
    twice the stop threshold while sliding, the spin's stop once |w| does (not stuck), the
    tangential spin's stop once |(p1, p2)| does while sliding (where it can stop:
    :func:`rot_stops`)."""
    if mode == MODE_SLIDING and slip_speed(y) > 2.0 * hp[P_V_REST]:
        armed |= ARMED_ROLL
    if not stuck and abs(y[YH_W]) > 2.0 * hp[P_V_REST]:
        armed |= ARMED_SPIN
    if mode == MODE_SLIDING and rot_stops(hp):
        if math.sqrt(y[YH_P1] * y[YH_P1] + y[YH_P2] * y[YH_P2]) > 2.0 * hp[P_V_REST]:
            armed |= ARMED_ROT
    return armed


@kernel
def rot_stops(hp):
    """Whether rolling resistance can stop and hold the tangential spin (p1, p2) while sliding:
    wherever there is rolling resistance. Where the couple that holds (p1, p2) at zero (kinetic
    friction's, at most mu_k N a, with the frame's turning) is within c_rr N a the spin stops
    and stays at zero, even with c_rr < mu_k (on a curved meridian the frame's terms can cancel
    friction's); otherwise it leaves zero at once (docs/physics.md "Rolling resistance while
    sliding")."""
    return hp[P_CRR] > 0.0


@kernel
def stalled(y, ynew, K, hp):
    """Whether the accepted sliding step y -> ynew (K[0] = f(y)) left the slip no smaller along
    its direction at y although friction is slowing it there (its rate along that direction is
    < 0), with the slip within :data:`STALL_BAND` times the stop threshold: the slip is then
    as near zero as the integration resolves it (docs/physics.md "Reaching the switch")."""
    return _stalled_pair(y[YH_U] - y[YH_P2], y[YH_V] + y[YH_P1], ynew[YH_U] - ynew[YH_P2],
                         ynew[YH_V] + ynew[YH_P1], K[0, YH_U] - K[0, YH_P2],
                         K[0, YH_V] + K[0, YH_P1], hp)  # fmt: skip


@kernel
def stalled_rot(y, ynew, K, hp):
    """:func:`stalled` for the tangential spin (p1, p2) while sliding, on its way to zero (its
    direction turns ever faster as it shrinks, as the slip's does)."""
    return _stalled_pair(y[YH_P1], y[YH_P2], ynew[YH_P1], ynew[YH_P2], K[0, YH_P1], K[0, YH_P2], hp)


@kernel
def _stalled_pair(s1, s2, n1, n2, r1, r2, hp):
    """Whether the pair (s1, s2) (rate (r1, r2)) within :data:`STALL_BAND` stop thresholds of
    zero, slowing along its direction, came out of a step as (n1, n2) no smaller along it."""
    sl = math.sqrt(s1 * s1 + s2 * s2)
    if not 0.0 < sl <= STALL_BAND * hp[P_V_REST]:
        return False
    return r1 * s1 + r2 * s2 < 0.0 and n1 * s1 + n2 * s2 >= sl * sl

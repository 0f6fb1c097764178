"""The hybrid state's events (:mod:`.sliding`) and one segment of one mode: the steps of
:func:`.hybrid_rk.advance` up to the first event.

An event is located by re-stepping from the start of the step that crossed it (Illinois' rule
on the fraction of the step), so the state at an event is a Runge-Kutta step of the method's
order: no dense output is needed.

Events (:data:`HYBRID_EVENT_NAMES`): a function g of the state that fires where it reaches 0
from below (the slip and the spin's release: above 0) within a step. Which are on depends on
the mode (rolling or sliding), the spin stick and the arming of the return to rolling
(docs/physics.md "Switching between rolling and sliding").

The step kernels of :mod:`.hybrid_rk` and its ``ARMED_*`` bits are also importable from here.
"""

from __future__ import annotations

import math

from .._jit import kernel
from .contact import contact_frame, leaves_contact
from .hybrid_rk import (
    ADV_OK,
    ADV_REACHED,
    ARMED_ROLL,
    ARMED_ROT,
    ARMED_SPIN,
    STALL_BAND,
    advance,
    arm,
    decide,
    first_step,
    hybrid_attempt,
    kink_step,
    stalled,
    stalled_rot,
    step_controller,
)
from .layouts import P_CRR, P_MU, P_R_VERTEX, P_RIM, P_THETA_MAX, P_V_REST
from .rk_codegen import tableau
from .sliding import (
    H_C_SPIN,
    MODE_ROLLING,
    MODE_SLIDING,
    N_HYBRID,
    YH_P1,
    YH_P2,
    YH_R,
    YH_THETA,
    YH_U,
    YH_V,
    YH_W,
    hold_margin,
    slip_speed,
    spin_hold_margin,
)

__all__ = [
    "ARMED_ROLL",
    "ARMED_ROT",
    "ARMED_SPIN",
    "STALL_BAND",
    "decide",
    "hybrid_attempt",
    "kink_step",
    "stalled",
    "step_controller",
]

EV_RIM = 0
EV_VERTEX = 1
EV_THETA = 2
EV_SLIP = 3
EV_STICK = 4
EV_SPIN_STOP = 5
EV_SPIN_GO = 6
EV_REST = 7
#: The normal force falls to zero: the sphere leaves the surface (only on a model whose normal
#: force can vanish, :func:`.contact.leaves_contact`; the cone's cannot).
EV_LIFTOFF = 8
#: The tangential spin (p1, p2) stopped while sliding (rolling resistance holds it at zero from
#: there: docs/physics.md "Rolling resistance while sliding"). Located like the others, but
#: not one of the story's events (:data:`HYBRID_EVENT_NAMES`): it is recorded for the sampled
#: trajectory, which splits its stretches there, and left out of what the story reports.
EV_ROT_STOP = 9
N_EVENTS = 10
#: Recorded, never located: the slip reached the return threshold but static friction could
#: not hold the rolling, so the sphere slides on (its return disarmed). Not a ``roll``: left
#: out of the story's events like :data:`EV_ROT_STOP`.
EV_NO_HOLD = 10
HYBRID_EVENT_NAMES = ("spill", "vertex", "horizon", "slip", "roll", "spin_stop", "spin_go",
                      "rest", "liftoff")  # fmt: skip
#: The bits of ``armed`` (:data:`.hybrid_rk.ARMED_ROLL`, ``ARMED_SPIN``, ``ARMED_ROT``) that each
#: event kind keeps for the stretch after it: a slip or a return to rolling disarms the return
#: (and the tangential spin's stop, a sliding rule), a spin's stop or release the spin's stop,
#: the tangential spin's stop itself, a return that does not hold the return (each is armed
#: again by :func:`.hybrid_rk.arm`), a restart from rest keeps them all (the ends keep nothing).
ARMED_KEPT = (0, 0, 0, ARMED_SPIN, ARMED_SPIN, ARMED_ROLL | ARMED_ROT, ARMED_ROLL | ARMED_ROT,
              ARMED_ROLL | ARMED_SPIN | ARMED_ROT, 0, ARMED_ROLL | ARMED_SPIN,
              ARMED_SPIN | ARMED_ROT)  # fmt: skip
#: Largest number of function evaluations (re-steps) to locate one event.
LOCATE_ITERATIONS = 60


@kernel
def event_value(model, kind, y, hp, mode, stuck, armed, ref):
    """g(y) of event ``kind``, or -inf where it is off. ``ref`` = (sign of w, slip direction
    (d1, d2), tangential spin direction (q1, q2), velocity (u, v)) at the start of the step:
    the spin's stop is w crossing 0, and the return to rolling is the slip's component along
    its direction at the step's start falling to the threshold (so a step that carries the
    slip through zero still fires it); the tangential spin's stop likewise; the rest fires on
    a velocity turned back through zero too (:func:`.protocol.rest_value`)."""
    w_sign, sd1, sd2, qd1, qd2, u0, v0 = ref
    off = -math.inf
    if kind == EV_RIM:
        return y[YH_R] - hp[P_RIM]
    if kind == EV_VERTEX:
        return hp[P_R_VERTEX] - y[YH_R]
    if kind == EV_THETA:
        return abs(y[YH_THETA]) - hp[P_THETA_MAX]
    if kind == EV_SLIP:
        return hold_margin(model, y, hp) if mode == MODE_ROLLING and hp[P_MU] < math.inf else off
    if kind == EV_STICK:
        if mode != MODE_SLIDING or not armed & ARMED_ROLL:
            return off
        return hp[P_V_REST] - ((y[YH_U] - y[YH_P2]) * sd1 + (y[YH_V] + y[YH_P1]) * sd2)
    if kind == EV_SPIN_STOP:
        if stuck or hp[H_C_SPIN] == 0.0 or w_sign == 0.0 or not armed & ARMED_SPIN:
            return off
        return hp[P_V_REST] - w_sign * y[YH_W]
    if kind == EV_SPIN_GO:
        return spin_hold_margin(model, y, hp) if stuck else off
    if kind == EV_REST:
        if mode != MODE_ROLLING or hp[P_CRR] == 0.0:  # the stop needs rolling resistance
            return off
        if y[YH_U] * u0 + y[YH_V] * v0 <= 0.0:  # turned back through zero: the stop was on the way
            return hp[P_V_REST]  # (as .protocol.rest_value)
        return hp[P_V_REST] - math.sqrt(y[YH_U] * y[YH_U] + y[YH_V] * y[YH_V])
    if kind == EV_LIFTOFF:
        if not leaves_contact(model):
            return off
        return -contact_frame(model, y[YH_R], y[YH_U], y[YH_V], hp)[1]
    if kind == EV_ROT_STOP:
        if mode != MODE_SLIDING or not armed & ARMED_ROT:
            return off
        return hp[P_V_REST] - (y[YH_P1] * qd1 + y[YH_P2] * qd2)
    return off


@kernel
def fired(kind, g0, g1):
    """Whether event ``kind`` happened in a step whose start and end give g0 and g1."""
    if kind == EV_SLIP or kind == EV_SPIN_GO or kind == EV_LIFTOFF:  # lift-off: N < 0
        return g0 <= 0.0 and g1 > 0.0
    return g0 < 0.0 and g1 >= 0.0


@kernel
def locate(method, model, kind, y0, h, hp, mode, stuck, armed, ref, K, ytmp, yout, rtol, atol, g0,
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
        hybrid_attempt(method, model, y0, th * h, hp, mode, stuck, K, ytmp, yout, rtol, atol)
        g = event_value(model, kind, yout, hp, mode, stuck, armed, ref)
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
    hybrid_attempt(method, model, y0, hi * h, hp, mode, stuck, K, ytmp, yout, rtol, atol)
    return hi


@kernel
def first_event(method, model, y0, y1, h, hp, mode, stuck, armed, K, ytmp, yout, rtol, atol):
    """The earliest event of the accepted step y0 -> y1 of size h [s]: (kind or -1, theta);
    its state is left in ``yout`` (K[0] = f(y0) is kept)."""
    w_ref = y0[YH_W] if y0[YH_W] != 0.0 else y1[YH_W]  # a spin leaving zero: the way it went
    w_sign = 0.0 if w_ref == 0.0 else math.copysign(1.0, w_ref)
    sl = slip_speed(y0)
    isl = 1.0 / sl if sl > 0.0 else 0.0
    ql = math.sqrt(y0[YH_P1] * y0[YH_P1] + y0[YH_P2] * y0[YH_P2])
    iql = 1.0 / ql if ql > 0.0 else 0.0
    ref = (w_sign, (y0[YH_U] - y0[YH_P2]) * isl, (y0[YH_V] + y0[YH_P1]) * isl, y0[YH_P1] * iql,
           y0[YH_P2] * iql, y0[YH_U], y0[YH_V])  # fmt: skip
    best = -1
    best_th = 2.0
    for j in range(N_EVENTS):
        # lift-off first: where N reaches zero the couples and limits proportional to N do
        # too (a spin held by c_spin N lets go there), and the ball has left: its event wins
        kind = EV_LIFTOFF if j == 0 else (j - 1 if j <= EV_LIFTOFF else j)
        g0 = event_value(model, kind, y0, hp, mode, stuck, armed, ref)
        if g0 == -math.inf:
            continue
        g1 = event_value(model, kind, y1, hp, mode, stuck, armed, ref)
        if fired(kind, g0, g1):
            th = locate(method, model, kind, y0, h, hp, mode, stuck, armed, ref, K, ytmp, ytmp,
                        rtol, atol, g0, g1)  # fmt: skip
            if th < best_th:
                best = kind
                best_th = th
    if best >= 0:
        hybrid_attempt(method, model, y0, best_th * h, hp, mode, stuck, K, ytmp, yout, rtol, atol)
    return best, best_th


#: Segment ends of :func:`segment` beyond the event kinds of :mod:`.hybrid_step`.
SEG_TIME = 100
SEG_FAILED = 101


@kernel
def segment(method, model, y, hp, mode, stuck, armed, t, t_end, rtol, atol, max_steps, K, ytmp,
            ynew, yev):  # fmt: skip
    """Integrate the hybrid state y in ``mode`` from t [s] to its first event or t_end.

    Returns (end: an event kind, :data:`SEG_TIME` or :data:`SEG_FAILED`; t [s]; attempts;
    time spent [s]; armed). y is updated in place (to the event's state)."""
    ns = tableau(method)[5]
    ctl = step_controller(method)
    n = y.shape[0]
    h = first_step(model, y, hp, mode, stuck, K, rtol, atol)
    err_old = 1e-4
    rejected = False
    steps = 0
    t0 = t
    while True:
        st, h_try, h, err_old, rejected, steps = advance(method, model, y, t, t_end, h, hp, mode,
                                                         stuck, armed, K, ytmp, ynew, rtol, atol,
                                                         ctl, err_old, rejected, steps,
                                                         max_steps)  # fmt: skip
        if st == ADV_REACHED:
            return SEG_TIME, t, steps, t - t0, armed
        if st != ADV_OK:
            return SEG_FAILED, t, steps, t - t0, armed
        kind, th = first_event(method, model, y, ynew, h_try, hp, mode, stuck, armed, K, ytmp, yev,
                               rtol, atol)  # fmt: skip
        if kind < 0 and mode == MODE_SLIDING and armed & ARMED_ROLL and stalled(y, ynew, K, hp):
            kind = EV_STICK  # the slip is as near zero as the steps can follow it
            th = 1.0
            for j in range(n):
                yev[j] = ynew[j]
        if kind < 0 and mode == MODE_SLIDING and armed & ARMED_ROT and stalled_rot(y, ynew, K,
                                                                                  hp):  # fmt: skip
            kind = EV_ROT_STOP  # the tangential spin, likewise
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
        armed = arm(y, hp, mode, stuck, armed)
        if t >= t_end:
            return SEG_TIME, t, steps, t - t0, armed


@kernel
def ev_y_stick(ev_y, i, y):
    """Replace the recorded state of event i by y (the state after the sticking impulse)."""
    if 0 <= i < ev_y.shape[0]:
        for j in range(N_HYBRID):
            ev_y[i, j] = y[j]


@kernel
def release_spin(y, hp):
    """The spin leaves the stick: w = 0, not stuck (the couple is then static Coulomb friction
    at w = 0, :func:`.sliding.couples`, and the spin's sign is taken from where it goes)."""
    y[YH_W] = 0.0

"""Sliding, rolling again and spin friction: the right-hand sides of the hybrid model
(docs/physics.md "Sliding, rolling again, and spin friction"), as numba kernels.

The equations are written once for any surface of revolution (:func:`frame_rates`), in the
meridian frame the model gives at the centre (:func:`.contact.contact_frame`: the cone's, a
surface's). ``model`` (the contact key, :func:`.contact.contact_key`: a literal, the first
parameter of every kernel here that reads the frame) picks the model's frame and the applied
effects at compile time.

The hybrid state (length :data:`N_HYBRID`), the same in both modes::

    r, theta, u, v          the centre on its meridian (as in engine.kernels.model)
    p1, p2, w               a omega in (e1, e2, nu): the full angular velocity as speeds [m/s]
    W_effects               work the effects acting through forces took: rolling resistance
                            and the applied ones (:data:`.contact.APPLIED`) [J]
    W_slide, W_spin         work done against sliding friction and spin friction [J]

While rolling p1 = -v and p2 = u (the rolling constraint) and the rates keep them so. The
parameters: the scene's array then :data:`H_MU_K`, :data:`H_C_SPIN` (:func:`hybrid_params`).
Every effect acts in both modes: rolling resistance by the rules this module writes (static at
zero tangential spin), and each applied effect (a force f on the centre, a couple T on the
sphere: :func:`.forces.effect_terms`, the same function the rolling models ask) through the
same equations as the contact's friction, f in the centre's rates, T in the spin's; their
power is the rate of ``W_effects`` (docs/physics.md "Effects in both modes"). The spin-stick
flag ``stuck`` says that static spin friction holds w = 0 (its rate is then exactly 0).

Every formula is arithmetic only: ``.py_func`` of the scalar kernels runs in plain Python.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally

from .._jit import kernel
from .contact import APPLIED, contact_frame, height_energy
from .forces import effect_terms, taken_power
from .layouts import P_CRR, P_K, P_M, P_MU
from .model import N_PARAMS

#: Hybrid parameter array: the scene's ``model.P_*`` entries, then these two.

H_MU_K = N_PARAMS  # kinetic friction coefficient
H_C_SPIN = N_PARAMS + 1  # spin-friction coefficient (couple c_spin a N)
N_HYBRID_PARAMS = N_PARAMS + 2
#: The hybrid state (both modes): the centre (r, theta, u, v), the contact point's slip seen as
#: the spin's tangential parts (p1, p2), the spin about the normal w, the work taken by the
#: effects acting through forces (rolling resistance and the applied ones), sliding friction and
#: spin friction [J].
HYBRID_STATE = ("r", "theta", "u", "v", "p1", "p2", "w", "W_effects", "W_sliding_friction",
                "W_spin_friction")  # fmt: skip
#: Length of the hybrid state, and its components' places (never indexed by number).
N_HYBRID = len(HYBRID_STATE)
(YH_R, YH_THETA, YH_U, YH_V, YH_P1, YH_P2, YH_W, YH_WORK_EFFECTS, YH_WORK_SLIDE,
 YH_WORK_SPIN) = range(N_HYBRID)  # fmt: skip
#: Modes.
MODE_ROLLING = 0
MODE_SLIDING = 1
#: Relative band of the spin stick: the spin stays stuck while the couple it needs is at most
#: c_spin N (1 + SPIN_BAND).
SPIN_BAND = 1e-9


@kernel
def hybrid_params(p, mu_k, c_spin):
    """The hybrid parameter array: a copy of the scene's ``p`` with mu_k and c_spin appended."""
    hp = np.empty(N_HYBRID_PARAMS)
    for i in range(N_PARAMS):
        hp[i] = p[i]
    hp[H_MU_K] = mu_k
    hp[H_C_SPIN] = c_spin
    return hp


@kernel
def applied(model, hp, u, v, p1, p2, w, N):
    """(f1, f2, T1/a, T2/a, T3/a) [N] of the applied effects the contact key ``model`` holds
    (:data:`.contact.APPLIED`; rolling resistance is not among them), at the sphere's state in
    either mode: :func:`.forces.effect_terms`. All 0 (compiled out) without any."""
    if model & APPLIED:
        return effect_terms(model, hp, u, v, p1, p2, w, N, 0.0, 0.0)
    return 0.0, 0.0, 0.0, 0.0, 0.0


@kernel
def spin_hold(frame, u, v, p1, p2, kM, g3):
    """T3/a [N] that holds w = 0 (dw/dt = 0 in :func:`frame_rates`) beside the applied couple
    g3: k M (kappa u p1 + sin(b)/rho v p2) - g3."""
    kappa = frame[4]
    kp = frame[5]
    return kM * (kappa * u * p1 + kp * v * p2) - g3


@kernel
def frame_rates(frame, u, v, p1, p2, w, f1, f2, t1, t2, t3, M, kM):
    """(du/dt, dv/dt, dp1/dt, dp2/dt, dw/dt) of a sphere on any surface of revolution, in the
    frame (e1 along the centre's meridian, e2 along its parallel, nu from the contact to the
    centre) that the model gives at the centre (``frame`` = :func:`.contact.contact_frame`'s:
    dtheta/dt, N, g sin b, cos(b)/rho, kappa, sin(b)/rho, dr/ds), under the contact's friction
    (f1, f2) [N] and the couples (T1, T2, T3)/a [N] (docs/physics.md "Equations of motion
    while sliding"):

        du/dt  = cos(b)/rho v^2 - g sin b + f1/M
        dv/dt  = -cos(b)/rho u v + f2/M
        dp1/dt = cos(b)/rho v p2 + kappa u w + (f2 + T1/a)/(k M)
        dp2/dt = -cos(b)/rho v p1 + sin(b)/rho v w + (T2/a - f1)/(k M)
        dw/dt  = -kappa u p1 - sin(b)/rho v p2 + (T3/a)/(k M)

    (the frame turns at kappa u about -e2 and at dtheta/dt about the axis; Newton for the
    centre, Euler about it, each seen in the turning frame)."""
    c = frame[3]
    kappa = frame[4]
    kp = frame[5]
    udot = v * v * c - frame[2] + f1 / M
    vdot = -u * v * c + f2 / M
    p1dot = p2 * v * c + kappa * u * w + (f2 + t1) / kM
    p2dot = -p1 * v * c + kp * v * w + (t2 - f1) / kM
    wdot = -kappa * u * p1 - kp * v * p2 + t3 / kM
    return udot, vdot, p1dot, p2dot, wdot


@kernel
def couples(p1, p2, w, N, stuck, hold, hp):
    """(T1/a, T2/a, T3/a) [N]: rolling resistance against (p1, p2) and spin friction against w,
    in (e1, e2, nu). ``hold`` is the spin couple that keeps w = 0 (:func:`spin_hold`): with
    ``stuck`` it is the couple; at w = 0 otherwise the couple is static Coulomb friction, hold
    clamped to c_spin N (so a spin leaving zero meets the full couple at once)."""
    t1 = 0.0
    t2 = 0.0
    pt = math.sqrt(p1 * p1 + p2 * p2)
    if pt > 0.0:
        f = hp[P_CRR] * N / pt
        t1 = -f * p1
        t2 = -f * p2
    cs = hp[H_C_SPIN] * N
    if stuck:
        t3 = hold
    elif w > 0.0:
        t3 = -cs
    elif w < 0.0:
        t3 = cs
    else:
        t3 = min(max(hold, -cs), cs)
    return t1, t2, t3


@kernel
def free_slip_rate(frame, u, v, p1, p2, w, t1, t2, kM):
    """(D1, D2) [m/s^2]: the slip velocity's rate without the contact force f, ds/dt of
    :func:`frame_rates` at f = 0 (s = (u - p2, v + p1))."""
    c = frame[3]
    kp = frame[5]
    d1 = v * v * c + p1 * v * c - frame[2] - kp * v * w - t2 / kM
    d2 = (p2 - u) * v * c + frame[4] * u * w + t1 / kM
    return d1, d2


@kernel
def clamp_pair(h1, h2, cap):
    """(h1, h2) if its size is at most cap (held: True), else scaled to size cap (False): a
    static couple, which gives at most its limit."""
    hl = math.sqrt(h1 * h1 + h2 * h2)
    if hl <= cap:
        return h1, h2, True
    return h1 * (cap / hl), h2 * (cap / hl), False


@kernel
def sliding_rates(model, r, u, v, p1, p2, w, stuck, hp):
    """Rates of the hybrid state while sliding (module docstring; physics "Equations of motion
    while sliding"): (rdot, thetadot, udot, vdot, p1dot, p2dot, wdot, P_effects, P_slide,
    P_spin), the last three the powers [W] the effects acting through forces, sliding friction
    and spin friction take (the frictions' >= 0).

    At zero tangential spin (p1 = p2 = 0 exactly) rolling resistance is static, as the spin
    couple is at w = 0: it holds (p1, p2) = 0 with any couple up to c_rr N a (their rates are
    then exactly 0), and beyond that gives c_rr N a against the way they leave zero (physics
    "Rolling resistance while sliding"). An applied effect's force (e1, e2) moves the centre
    and its couple (g1, g2, g3) turns the sphere (:func:`applied`)."""
    M = hp[P_M]
    kM = hp[P_K] * M
    frame = contact_frame(model, r, u, v, hp)
    N = frame[1]
    e1, e2, g1, g2, g3 = applied(model, hp, u, v, p1, p2, w, N)
    hold = spin_hold(frame, u, v, p1, p2, kM, g3)
    t1, t2, t3 = couples(p1, p2, w, N, stuck, hold, hp)
    if model & APPLIED:
        t1 += g1
        t2 += g2
        t3 += g3
    s1 = u - p2
    s2 = v + p1
    sl = math.sqrt(s1 * s1 + s2 * s2)
    fk = hp[H_MU_K] * N
    static_rr = p1 == 0.0 and p2 == 0.0 and hp[P_CRR] > 0.0
    if sl > 0.0:
        f1 = -fk * s1 / sl
        f2 = -fk * s2 / sl
    else:  # the slip starts along D (physics "Switching between rolling and sliding")
        if static_rr:  # at rest: along the centre's pull ((p1, p2) held at 0)
            d1 = v * v * frame[3] - frame[2]
            d2 = -u * v * frame[3]
        else:
            d1, d2 = free_slip_rate(frame, u, v, p1, p2, w, t1, t2, kM)
        if model & APPLIED:
            d1 += e1 / M
            d2 += e2 / M
        dl = math.sqrt(d1 * d1 + d2 * d2)
        f1 = -fk * d1 / dl if dl > 0.0 else 0.0
        f2 = -fk * d2 / dl if dl > 0.0 else 0.0
    held = False
    if static_rr:  # the couple that keeps p1dot = p2dot = 0, up to c_rr N
        kappa_w = kM * frame[4] * u * w
        t1, t2, held = clamp_pair(-f2 - kappa_w - g1, f1 - kM * frame[5] * v * w - g2,
                                  hp[P_CRR] * N)  # fmt: skip
        if model & APPLIED:
            t1 += g1
            t2 += g2
    udot, vdot, p1dot, p2dot, wdot = frame_rates(frame, u, v, p1, p2, w, f1, f2, t1, t2, t3, M,
                                                 kM)  # fmt: skip
    p_effects = hp[P_CRR] * N * math.sqrt(p1 * p1 + p2 * p2)
    if model & APPLIED:
        udot += e1 / M
        vdot += e2 / M
        p_effects += taken_power(e1, e2, g1, g2, g3, u, v, p1, p2, w)
    if held:
        p1dot = 0.0
        p2dot = 0.0
    if stuck:
        wdot = 0.0
    p_slide = fk * sl
    p_spin = 0.0 if stuck else hp[H_C_SPIN] * N * abs(w)
    return u * frame[6], frame[0], udot, vdot, p1dot, p2dot, wdot, p_effects, p_slide, p_spin


@kernel
def rolling_rest_couple(udot, vdot, N, hp):
    """(T1/a, T2/a [N], held) of rolling resistance on a sphere rolling at rest (u = v = 0),
    where (udot, vdot) is the pull of the other forces: static, it opposes the pull up to
    c_rr N (as :func:`.model.motion_rates` does at zero speed), and holds the sphere (held)
    if that is enough; (0, 0, False) without rolling resistance."""
    if hp[P_CRR] == 0.0:
        return 0.0, 0.0, False
    m1k = hp[P_M] * (1.0 + hp[P_K])
    return clamp_pair(m1k * vdot, -m1k * udot, hp[P_CRR] * N)


@kernel
def rolling_rates(model, r, u, v, w, stuck, hp):
    """Rates of the hybrid state while rolling (p1 = -v, p2 = u kept): :func:`frame_rates`
    with the friction that keeps the slip zero eliminated, rolling resistance, the applied
    effects' force (e1, e2) and couple (g1, g2, g3) (they enter as in every rolling model:
    :mod:`.forces`) and the spin couple (which enters dw/dt only); with k' = k/(1+k)

        du/dt = cos(b)/rho v^2 + k' sin(b)/rho v w - g sin(b)/(1+k) + (e1 + g2)/(M (1+k))
        dv/dt = -cos(b)/rho u v - k' kappa u w + (e2 - g1)/(M (1+k))
        dw/dt = (kappa - sin(b)/rho) u v + g3/(k M)   (the rolling model's, :mod:`.surface`)."""
    M = hp[P_M]
    k = hp[P_K]
    kk = k / (1.0 + k)
    frame = contact_frame(model, r, u, v, hp)
    N = frame[1]
    c = frame[3]
    kappa = frame[4]
    kp = frame[5]
    e1, e2, g1, g2, g3 = applied(model, hp, u, v, -v, u, w, N)
    t1, t2, t3 = couples(-v, u, w, N, stuck, spin_hold(frame, u, v, -v, u, k * M, g3), hp)
    udot = v * v * c + kk * kp * v * w - frame[2] / (1.0 + k)
    vdot = -u * v * c - kk * kappa * u * w
    if model & APPLIED:
        udot += (e1 + g2) / (M * (1.0 + k))
        vdot += (e2 - g1) / (M * (1.0 + k))
        t3 += g3
    held = False
    if u == 0.0 and v == 0.0:  # at rest the resistance is static (:func:`rolling_rest_couple`)
        t1, t2, held = rolling_rest_couple(udot, vdot, N, hp)
    udot = 0.0 if held else udot + t2 / (M * (1.0 + k))
    vdot = 0.0 if held else vdot - t1 / (M * (1.0 + k))
    wdot = 0.0 if stuck else (kappa - kp) * u * v + t3 / (k * M)
    p_effects = hp[P_CRR] * N * math.sqrt(u * u + v * v)
    if model & APPLIED:
        p_effects += taken_power(e1, e2, g1, g2, g3, u, v, -v, u, w)
    p_spin = 0.0 if stuck else hp[H_C_SPIN] * N * abs(w)
    return u * frame[6], frame[0], udot, vdot, -vdot, udot, wdot, p_effects, 0.0, p_spin


@kernel
def hybrid_rhs(model, y, hp, mode, stuck, out):
    """dy/dt of the hybrid state in ``mode`` into ``out`` (length :data:`N_HYBRID`)."""
    literally(model)  # (called from Python too: the tests)
    if mode == MODE_SLIDING:
        d = sliding_rates(model, y[YH_R], y[YH_U], y[YH_V], y[YH_P1], y[YH_P2], y[YH_W], stuck,
                          hp)  # fmt: skip
    else:
        d = rolling_rates(model, y[YH_R], y[YH_U], y[YH_V], y[YH_W], stuck, hp)
    for j in range(N_HYBRID):
        out[j] = d[j]


@kernel
def hybrid_energy(model, r, u, v, p1, p2, w, hp):
    """E [J] = M (u^2 + v^2)/2 + k M (p1^2 + p2^2 + w^2)/2 + M g z (the model's height)."""
    M = hp[P_M]
    return (
        0.5 * M * (u * u + v * v)
        + 0.5 * hp[P_K] * M * (p1 * p1 + p2 * p2 + w * w)
        + height_energy(model, r, hp)
    )


@kernel
def slip_speed(y):
    """|s| [m/s], s = (u - p2, v + p1)."""
    s1 = y[YH_U] - y[YH_P2]
    s2 = y[YH_V] + y[YH_P1]
    return math.sqrt(s1 * s1 + s2 * s2)


@kernel
def rolling_friction(model, y, hp):
    """(f1, f2) [N]: the contact force that makes ds/dt = 0 in the state y, f = -k M D/(1+k)
    (with rolling resistance and the applied effects; spin friction does not enter), and N
    [N]."""
    r, u, v, p1, p2, w = y[YH_R], y[YH_U], y[YH_V], y[YH_P1], y[YH_P2], y[YH_W]
    frame = contact_frame(model, r, u, v, hp)
    N = frame[1]
    k = hp[P_K]
    M = hp[P_M]
    kM = k * M
    e1, e2, g1, g2, g3 = applied(model, hp, u, v, p1, p2, w, N)
    t1, t2, _ = couples(p1, p2, w, N, True, 0.0, hp)
    if u == 0.0 and v == 0.0 and p1 == 0.0 and p2 == 0.0:  # rolling at rest: static resistance
        pull = v * v * frame[3] + k / (1.0 + k) * frame[5] * v * w
        pull -= frame[2] / (1.0 + k)
        pull_v = -u * v * frame[3]
        if model & APPLIED:
            pull += (e1 + g2) / (M * (1.0 + k))
            pull_v += (e2 - g1) / (M * (1.0 + k))
        t1, t2, _ = rolling_rest_couple(pull, pull_v, N, hp)
    if model & APPLIED:
        t1 += g1
        t2 += g2
    d1, d2 = free_slip_rate(frame, u, v, p1, p2, w, t1, t2, kM)
    if model & APPLIED:
        d1 += e1 / M
        d2 += e2 / M
    c = -kM / (1.0 + k)
    return c * d1, c * d2, N


@kernel
def hold_margin(model, y, hp):
    """|f_roll| - mu N [N]: > 0 where static friction cannot hold the rolling motion (N < 0
    counts as 0: the ball leaving the surface is the lift-off, not a slip)."""
    f1, f2, N = rolling_friction(model, y, hp)
    return math.sqrt(f1 * f1 + f2 * f2) - hp[P_MU] * (0.0 if N < 0.0 else N)


@kernel
def spin_hold_margin(model, y, hp):
    """|couple that holds w = 0| - c_spin N (1 + :data:`SPIN_BAND`) [N] (> 0: the spin cannot
    stay stuck). The band keeps a spin whose needed couple grazes the limit from sticking and
    unsticking without end (docs/physics.md "Spin stick")."""
    u, v, p1, p2 = y[YH_U], y[YH_V], y[YH_P1], y[YH_P2]
    frame = contact_frame(model, y[YH_R], u, v, hp)
    cs = hp[H_C_SPIN] * (0.0 if frame[1] < 0.0 else frame[1])  # N < 0: the lift-off's
    kM = hp[P_K] * hp[P_M]
    g3 = applied(model, hp, u, v, p1, p2, y[YH_W], frame[1])[4]
    hold = spin_hold(frame, u, v, p1, p2, kM, g3)
    return abs(hold) - cs * (1.0 + SPIN_BAND)


@kernel
def stick(y, hp):
    """Remove the remaining slip by the friction impulse J = -k M s/(1+k) at the contact
    (conserves the angular momentum about the contact point); returns the energy it takes
    [J], k M |s|^2/(2(1+k)), which is booked to sliding friction (y[YH_WORK_SLIDE])."""
    k = hp[P_K]
    s1 = y[YH_U] - y[YH_P2]
    s2 = y[YH_V] + y[YH_P1]
    j1 = -k * s1 / (1.0 + k)  # J/M
    j2 = -k * s2 / (1.0 + k)
    y[YH_U] += j1
    y[YH_V] += j2
    y[YH_P1] += j2 / k
    y[YH_P2] -= j1 / k
    # exactly on the rolling constraint (the impulse does it up to rounding)
    y[YH_P1] = -y[YH_V]
    y[YH_P2] = y[YH_U]
    lost = 0.5 * k * hp[P_M] * (s1 * s1 + s2 * s2) / (1.0 + k)
    y[YH_WORK_SLIDE] += lost
    return lost

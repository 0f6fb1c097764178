"""Geometric integration of the conservative scene: time-transformed leapfrog + Yoshida composition.

L_z and h are exact invariants of the conservative scene, so the motion reduces to the radial
Hamiltonian H(r, p) = p^2/(2M) + V(r), V = A/r^2 + B/r + C r (docs/physics.md), with the azimuth
by quadrature, thetadot = L_z/(M sin^2(alpha) r^2), and v, w functions of r. H is separable, so a
splitting into drift (r moves with p) and kick (p and theta move with r) integrates it.

Near the axis (small L_z) and at the pericentre of eccentric free-fall orbits the natural time
scale shrinks by many orders of magnitude. The steps are therefore uniform in a fictitious time s,
ds = Omega(r) dt, with Omega^2 = (6A/r^4 + 2|B|/r^3 + C/r)/M the inverse square of the local
dynamical time (each term: the time scale of the centrifugal barrier, of the 1/r term and of
gravity). The base step is the time-transformed leapfrog (TTL) of Mikkola & Aarseth (2002,
Celest. Mech. 84, 343): drift(h/2) with dt = (h/2)/W, kick(h) with dt = h/Omega(r), drift(h/2),
where W is an auxiliary variable that follows Omega along the orbit (dW/ds = Omega'(r) rdot/Omega).
It is explicit, second order and time-symmetric, so Yoshida's symmetric compositions raise it to
order 4 or 6; with Omega constant it is the plain (symplectic) Stormer-Verlet leapfrog, and with
the time transformation it stays reversible, which for these periodic orbits gives the same
behaviour as a symplectic method: the energy error oscillates and stays bounded, with no
secular drift. The fixed step in s follows from rtol: h = STEP_SCALE[order] rtol^(1/order).

Events (apsides: p = 0; the rim; slip onset) and output times are located by Brent's method on
the partial step, i.e. by re-taking the composed step with a shorter s-step, which keeps the
method's order. Dissipative effects and the attitude (needs the full rigid-body state) are
refused with status UNSUPPORTED (:data:`UNSUPPORTED_EFFECTS`).

Phase-space vector z: (r [m], p = M u [kg m/s], theta [rad], t [s], W [1/s]).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .cone import P_ALPHA, P_COS, P_SIN, coefficients
from .effects import CAPABILITIES, needing_any
from .layouts import P_G, P_K, P_M, Y_R, Y_THETA, Y_U, Y_V, Y_W
from .protocol import (
    BUFFER_FULL,
    EPS,
    FIRST_TERMINAL,
    LAST_TERMINAL,
    MAX_STEPS,
    NONFINITE,
    OK,
    PERICENTRE,
    RECORD_EVERY_DT,
    RECORD_STEPS,
    UNSUPPORTED,
    brent_next,
    brent_start,
    brent_update,
    copy_into,
    event_value,
    events_full,
    kind_enabled,
    push_event,
    push_state,
    record_apsis,
    start_protocol,
    status_of,
    terminal_crossed,
)
from .tableaux import LEAPFROG, YOSHIDA4, YOSHIDA6

#: Kernel id of the method (Runge-Kutta pairs take the ids 0, 1, ... of their tableaux).
SYMPLECTIC = 100
#: What this method can do (:data:`.effects.CAPABILITIES`; ``engine.methods`` says why not the
#: rest): it integrates the conservative radial Hamiltonian, which dissipative forces break, and
#: it does not carry the rigid body's attitude.
SUPPORTS = ("terminal events",)
#: Effects this method cannot honour (those needing what it cannot do): runs return UNSUPPORTED.
UNSUPPORTED_EFFECTS = needing_any(set(CAPABILITIES) - set(SUPPORTS))

#: Default composition order of the "symplectic" method.
DEFAULT_ORDER = 6
#: s-step = STEP_SCALE[order] * rtol ** (1 / order), indexed by order (2, 4, 6).
STEP_SCALE = (0.0, 0.0, 2.0, 0.0, 1.5, 0.0, 1.6)
#: Largest s-step (a fraction of a dynamical time).
MAX_STEP = 0.5

# Fields of z.
Z_R = 0
Z_P = 1
Z_TH = 2
Z_T = 3
Z_W = 4

# Target of the partial-step root finder besides the event kinds of .protocol.
_TARGET_TIME = 100


@kernel
def weights(order):
    """Composition weights of order 2, 4 or 6."""
    if order == 4:
        return YOSHIDA4
    if order == 6:
        return YOSHIDA6
    return LEAPFROG


@kernel
def step_size(order, rtol):
    """Fixed step in s (units of the local dynamical time) for a relative tolerance rtol."""
    return min(MAX_STEP, STEP_SCALE[order] * rtol ** (1.0 / order))


@kernel
def omega(r, cf):
    """(Omega [1/s], dOmega/dr [1/(s m)]): inverse local dynamical time at r.

    Omega^2 = (6A/r^4 + 2|B|/r^3 + C/r)/M + (u(r)^2 + v(r)^2)/r^2: the time scales of the
    centrifugal barrier, of the 1/r term and of gravity, plus the kinematic rate |velocity|/r,
    with the orbit's u(r)^2 = 2 (calE - V(r))/M and v(r)^2 = 2 A0/(M r^2). It is smooth in r
    (u^2 is not clamped at the turning points) and positive on and near the orbit; off it, the
    kinematic term is dropped.
    """
    A = cf[0]
    B = cf[1]
    C = cf[2]
    iM = cf[5]
    energy = cf[6]
    A0 = cf[7]
    ir = 1.0 / r
    ir2 = ir * ir
    ir3 = ir2 * ir
    ir4 = ir2 * ir2
    aB = abs(B)
    f = 6.0 * A * ir4 + 2.0 * aB * ir3 + C * ir
    df = -24.0 * A * ir4 * ir - 6.0 * aB * ir4 - C * ir2
    # (u^2 + v^2)/r^2 with M u^2 = 2 (calE - A/r^2 - B/r - C r), M v^2 = 2 A0 / r^2
    g = 2.0 * energy * ir2 - 2.0 * (A - A0) * ir4 - 2.0 * B * ir3 - 2.0 * C * ir
    dg = -4.0 * energy * ir3 + 8.0 * (A - A0) * ir4 * ir + 6.0 * B * ir4 + 2.0 * C * ir2
    if f + g > 0.0:
        f += g
        df += dg
    om = math.sqrt(f * iM)
    return om, 0.5 * df * iM / om


@kernel
def ttl_coefficients(p, energy, h, Lz):
    """[A, B, C, M, K_theta = L_z/(M sin^2 alpha), 1/M, calE, A0 = L_z^2/(2 M sin^2 alpha)]
    of the reduced radial problem."""
    M = p[P_M]
    s = p[P_SIN]
    A, B, C = coefficients(p[P_ALPHA], h, Lz, M, p[P_G], p[P_K])
    cf = np.empty(8)
    cf[6] = energy
    cf[7] = Lz * Lz / (2.0 * M * s * s)
    cf[0] = A
    cf[1] = B
    cf[2] = C
    cf[3] = M
    cf[4] = Lz / (M * s * s)
    cf[5] = 1.0 / M
    return cf


@kernel
def ttl_step(z, h, wts, cf):
    """One composed TTL step of size h in s, in place (``cf`` from :func:`ttl_coefficients`)."""
    A = cf[0]
    B = cf[1]
    C = cf[2]
    Kth = cf[4]
    iM = cf[5]
    for i in range(wts.shape[0]):
        hs = wts[i] * h
        dt = 0.5 * hs / z[Z_W]
        z[Z_R] += dt * z[Z_P] * iM
        z[Z_T] += dt
        r = z[Z_R]
        om, dom = omega(r, cf)
        dts = hs / om
        ir = 1.0 / r
        vp = (-2.0 * A * ir - B) * ir * ir + C
        p_new = z[Z_P] - dts * vp
        z[Z_TH] += dts * Kth * ir * ir
        z[Z_W] += hs * dom * (z[Z_P] + p_new) * 0.5 * iM / om
        z[Z_P] = p_new
        dt = 0.5 * hs / z[Z_W]
        z[Z_R] += dt * z[Z_P] * iM
        z[Z_T] += dt


@kernel
def full_state(z, p, h, Lz, out):
    """(r, theta, u, v, w) of the phase-space vector z into ``out``."""
    M = p[P_M]
    s = p[P_SIN]
    r = z[Z_R]
    out[Y_R] = r
    out[Y_THETA] = z[Z_TH]
    out[Y_U] = z[Z_P] / M
    out[Y_V] = Lz / (M * r * s)
    out[Y_W] = h + Lz * p[P_COS] / (M * r * s * s)


@kernel
def _target(kind, effects, z, p, h, Lz, t_target, buf):
    """Root-finder target: time (t - t_target), apsis (p) or a terminal event function of z."""
    if kind == _TARGET_TIME:
        return z[Z_T] - t_target
    if kind == PERICENTRE:
        return z[Z_P]
    full_state(z, p, h, Lz, buf)
    return event_value(kind, buf, p, effects)


@kernel
def locate(kind, effects, z0, hstep, wts, cf, p, h, Lz, t_target, g0, g1, zt, buf, st):
    """Partial s-step sigma in [0, hstep] where the target function crosses 0 (Brent, xtol
    4 eps hstep); the state there is left in ``zt``."""
    brent_start(st, 0.0, hstep, g0, g1)
    sig = hstep
    for _ in range(100):
        done, sig = brent_next(st, 4.0 * EPS * hstep)
        if done:
            break
        copy_into(z0, zt)
        ttl_step(zt, sig, wts, cf)
        brent_update(st, _target(kind, effects, zt, p, h, Lz, t_target, buf))
    sig = min(max(sig, 0.0), hstep)
    copy_into(z0, zt)
    ttl_step(zt, sig, wts, cf)
    return sig


@kernel
def sym_fixed(z0, p, energy, h, Lz, order, hstep, n_steps):
    """z after n_steps composed steps of size hstep in s (for order tests)."""
    cf = ttl_coefficients(p, energy, h, Lz)
    wts = weights(order)
    z = z0.copy()
    for _ in range(n_steps):
        ttl_step(z, hstep, wts, cf)
    return z


@kernel
def initial_z(p, r0, u0, energy, h, Lz):
    """Phase-space vector at radius r0 [m] with radial velocity u0 [m/s] at t = 0, theta = 0
    (orbit calE = energy [J], h [m/s], L_z [kg m^2/s])."""
    cf = ttl_coefficients(p, energy, h, Lz)
    z = np.empty(5)
    z[Z_R] = r0
    z[Z_P] = p[P_M] * u0
    z[Z_TH] = 0.0
    z[Z_T] = 0.0
    z[Z_W] = omega(r0, cf)[0]
    return z


@kernel
def _step_events(effects, z, zn, hstep, wts, cf, p, h, Lz, t_end, g_aps, n_aps, n_apsides,
                 ev_t, ev_kind, ev_y, n_ev, zt, buf, st):  # fmt: skip
    """Events inside the step z -> zn: the end time, the first terminal event, the apsis before
    it. Returns (ok, sigma of the stop (2 hstep = none), stop status, is a terminal event,
    stop kind, g_aps, n_aps, n_ev); ok is False when the event buffers are full."""
    sig_stop = 2.0 * hstep
    stop_status = OK
    stop_kind = 0
    stop_is_event = False
    if zn[Z_T] >= t_end:
        sig_stop = locate(np.int64(_TARGET_TIME), effects, z, hstep, wts, cf, p, h, Lz, t_end,
                          z[Z_T] - t_end, zn[Z_T] - t_end, zt, buf, st)  # fmt: skip
    for kind in range(FIRST_TERMINAL, LAST_TERMINAL + 1):
        if not kind_enabled(effects, kind):
            continue
        g1 = _target(kind, effects, zn, p, h, Lz, 0.0, buf)
        g0 = _target(kind, effects, z, p, h, Lz, 0.0, buf)
        if terminal_crossed(kind, g0, g1):
            sig = locate(kind, effects, z, hstep, wts, cf, p, h, Lz, 0.0, g0, g1, zt, buf, st)
            if sig <= sig_stop:
                sig_stop = sig
                stop_status = status_of(kind)
                stop_kind = kind
                stop_is_event = True
    g1 = zn[Z_P]
    if n_apsides >= 0 and ((g_aps > 0.0 and g1 <= 0.0) or (g_aps < 0.0 and g1 >= 0.0)):
        sig = locate(np.int64(PERICENTRE), effects, z, hstep, wts, cf, p, h, Lz, 0.0, z[Z_P], g1,
                     zt, buf, st)  # fmt: skip
        if sig <= sig_stop:
            full_state(zt, p, h, Lz, buf)
            n_ev, g_aps, n_aps, reached = record_apsis(ev_t, ev_kind, ev_y, n_ev, zt[Z_T], buf,
                                                       g_aps, n_aps, n_apsides)  # fmt: skip
            if events_full(n_ev, ev_t):
                return False, sig_stop, stop_status, stop_is_event, stop_kind, g_aps, n_aps, n_ev
            if reached:
                sig_stop = sig
                stop_status = OK
                stop_is_event = False
    return True, sig_stop, stop_status, stop_is_event, stop_kind, g_aps, n_aps, n_ev


@kernel
def _samples(effects, z, zn, t_lim, t_end, dt_out, next_out, hstep, wts, cf, p, h, Lz, tr_t,
             tr_y, n_tr, zs, buf, st):  # fmt: skip
    """Record the state every ``dt_out`` seconds up to t_lim (partial steps located by Brent);
    returns (n_tr, next_out); n_tr < 0 when the trajectory buffers are full."""
    cap_tr = tr_t.shape[0]
    while next_out <= t_lim and next_out < t_end and n_tr < cap_tr:
        locate(np.int64(_TARGET_TIME), effects, z, hstep, wts, cf, p, h, Lz, next_out,
               z[Z_T] - next_out, zn[Z_T] - next_out, zs, buf, st)  # fmt: skip
        full_state(zs, p, h, Lz, buf)
        n_tr = push_state(tr_t, tr_y, n_tr, next_out, buf)
        next_out = n_tr * dt_out
    if n_tr == cap_tr:
        return -1, next_out
    return n_tr, next_out


@kernel
def sym_run(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps, record,
            dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
    """Integrate the conservative scene on the run protocol (:func:`.rk.rk_run` has the same
    signature and returns); states are full (r, theta, u, v, w). ``orbit`` = (calE, h, L_z)
    defines the reduced radial problem; y0 gives r and u at t = 0; ``atol`` and ``tr_rate`` are
    unused. Scenes with :data:`UNSUPPORTED_EFFECTS` return UNSUPPORTED."""
    energy, h, Lz = orbit
    cf = ttl_coefficients(p, energy, h, Lz)
    wts = weights(np.int64(DEFAULT_ORDER))
    hstep = step_size(np.int64(DEFAULT_ORDER), rtol)
    z = initial_z(p, y0[Y_R], y0[Y_U], energy, h, Lz)
    work = np.empty(3 * 5 + 2 * 5 + 8)
    zn, zt, zs = work[0:5], work[5:10], work[10:15]
    y, buf, st = work[15:20], work[20:25], work[25:]
    full_state(z, p, h, Lz, y)
    if effects & UNSUPPORTED_EFFECTS:
        return UNSUPPORTED, 0, 0, 0.0, y, 0, 0
    status, n_ev, n_tr = start_protocol(effects, y, p, record, ev_t, ev_kind, ev_y, tr_t, tr_y)
    if status != OK:
        return status, 0, 0, 0.0, y, n_ev, n_tr
    # Sign of the apsis function; at a turning point, the sign of pdot = -V'(r).
    r0 = z[Z_R]
    g_aps = z[Z_P] if z[Z_P] != 0.0 else -((-2.0 * cf[0] / r0 - cf[1]) / (r0 * r0) + cf[2])
    next_out = dt_out
    n_acc = 0
    n_aps = 0
    while True:
        if n_acc >= max_steps:
            status = MAX_STEPS
            break
        copy_into(z, zn)
        ttl_step(zn, hstep, wts, cf)
        if not (zn[Z_R] > 0.0 and math.isfinite(zn[Z_P]) and math.isfinite(zn[Z_W])):
            status = NONFINITE
            break
        n_acc += 1
        ok, sig_stop, stop_status, stop_is_event, stop_kind, g_aps, n_aps, n_ev = _step_events(
            effects, z, zn, hstep, wts, cf, p, h, Lz, t_end, g_aps, n_aps, n_apsides,
            ev_t, ev_kind, ev_y, n_ev, zt, buf, st)  # fmt: skip
        if not ok:
            n_ev = ev_t.shape[0]
            status = BUFFER_FULL
            break
        stopping = sig_stop <= hstep
        t_lim = zn[Z_T]
        if stopping:  # re-take the step up to the stop
            copy_into(z, zt)
            ttl_step(zt, sig_stop, wts, cf)
            t_lim = zt[Z_T]
            if stop_is_event:
                full_state(zt, p, h, Lz, buf)
                n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, zt[Z_T], stop_kind, buf)
                if events_full(n_ev, ev_t):
                    n_ev = ev_t.shape[0]
                    status = BUFFER_FULL
                    break
        if record == RECORD_EVERY_DT:
            n_tr, next_out = _samples(effects, z, zn, t_lim, t_end, dt_out, next_out, hstep, wts,
                                      cf, p, h, Lz, tr_t, tr_y, n_tr, zs, buf, st)  # fmt: skip
            if n_tr < 0:
                n_tr = tr_t.shape[0]
                status = BUFFER_FULL
                break
        copy_into(zt if stopping else zn, z)
        if record == RECORD_STEPS or (record == RECORD_EVERY_DT and stopping):
            full_state(z, p, h, Lz, buf)
            n_tr = push_state(tr_t, tr_y, n_tr, z[Z_T], buf)
            if n_tr < 0:
                n_tr = tr_t.shape[0]
                status = BUFFER_FULL
                break
        if stopping:
            status = stop_status
            break
    full_state(z, p, h, Lz, y)
    return status, n_acc, 0, z[Z_T], y, n_ev, n_tr

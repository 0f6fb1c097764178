"""Geometric integration of the conservative scene: time-transformed leapfrog + Yoshida composition.

L_z and h are exact invariants of the conservative scene, so the motion reduces to the radial
Hamiltonian H(r, p) = p^2/(2M) + V(r), V = A/r^2 + B/r + C r (physics.md), with the azimuth by
quadrature, thetadot = L_z/(M sin^2(alpha) r^2), and v, w functions of r. H is separable, so a
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
method's order. Rolling resistance (dissipative) and the attitude (needs the full rigid-body
state) are refused with status UNSUPPORTED.

Phase-space vector z: (r [m], p = M u [kg m/s], theta [rad], t [s], W [1/s]).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .integrators import (
    APOCENTRE,
    BUFFER_FULL,
    EPS,
    MAX_STEPS,
    NONFINITE,
    OK,
    PERICENTRE,
    RECORD_EVERY_DT,
    RECORD_NONE,
    RECORD_STEPS,
    SLIP,
    SLIPPED,
    SPILL,
    SPILLED,
    UNSUPPORTED,
    _copy,
    _copy_row,
    brent_next,
    brent_start,
    brent_update,
)
from .physics import coefficients
from .scenes import (
    ATTITUDE,
    P_COS,
    P_G,
    P_K,
    P_M,
    P_SIN,
    RIM,
    ROLLING_RESISTANCE,
    SLIP_CHECK,
    rim_margin,
    slip_margin,
)
from .tableaux import LEAPFROG, YOSHIDA4, YOSHIDA6

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

# Target of the partial-step root finder.
_TARGET_TIME = 4


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
    A, B, C = coefficients(p[0], h, Lz, M, p[P_G], p[P_K])
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
    out[0] = r
    out[1] = z[Z_TH]
    out[2] = z[Z_P] / M
    out[3] = Lz / (M * r * s)
    out[4] = h + Lz * p[P_COS] / (M * r * s * s)


@kernel
def _target(kind, z, p, h, Lz, t_target, buf):
    """Root-finder target: time (t - t_target), rim, slip or apsis (p) function of z."""
    if kind == _TARGET_TIME:
        return z[Z_T] - t_target
    if kind == SPILL:
        full_state(z, p, h, Lz, buf)
        return rim_margin(buf, p)
    if kind == SLIP:
        full_state(z, p, h, Lz, buf)
        return slip_margin(buf, p)
    return z[Z_P]


@kernel
def locate(kind, z0, hstep, wts, cf, p, h, Lz, t_target, g0, g1, zt, buf, st):
    """Partial s-step sigma in [0, hstep] where the target function crosses 0 (Brent, xtol
    4 eps hstep); the state there is left in ``zt``."""
    brent_start(st, 0.0, hstep, g0, g1)
    sig = hstep
    for _ in range(100):
        done, sig = brent_next(st, 4.0 * EPS * hstep)
        if done:
            break
        _copy(z0, zt)
        ttl_step(zt, sig, wts, cf)
        brent_update(st, _target(kind, zt, p, h, Lz, t_target, buf))
    sig = min(max(sig, 0.0), hstep)
    _copy(z0, zt)
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
def sym_run(effects, z0, p, energy, h, Lz, order, rtol, t_end, n_apsides, max_steps, record,
            dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y):  # fmt: skip
    """Integrate the conservative scene like :func:`.integrators.rk_run`, with the same buffers
    and returns (status, n_steps, 0, t, y, n_ev, n_tr); states are full (r, theta, u, v, w).
    Scenes with rolling resistance or attitude return UNSUPPORTED."""
    n = 5
    cf = ttl_coefficients(p, energy, h, Lz)
    A = cf[0]
    B = cf[1]
    C = cf[2]
    wts = weights(order)
    hstep = step_size(order, rtol)
    z = z0.copy()
    zn = np.empty(5)
    zt = np.empty(5)
    zs = np.empty(5)
    y = np.empty(n)
    buf = np.empty(n)
    st = np.empty(8)
    cap_ev = ev_t.shape[0]
    cap_tr = tr_t.shape[0]
    n_ev = 0
    n_tr = 0
    full_state(z, p, h, Lz, y)
    if effects & (ROLLING_RESISTANCE | ATTITUDE):
        return UNSUPPORTED, 0, 0, 0.0, y, 0, 0
    status = OK
    if record != RECORD_NONE:
        if cap_tr < 1:
            return BUFFER_FULL, 0, 0, 0.0, y, 0, 0
        tr_t[0] = 0.0
        _copy_row(y, tr_y, 0)
        n_tr = 1
    if effects & RIM:
        if rim_margin(y, p) >= 0.0:
            status = SPILLED
    if effects & SLIP_CHECK:
        if status == OK and slip_margin(y, p) > 0.0:
            status = SLIPPED
    if status != OK:
        if cap_ev < 1:
            return BUFFER_FULL, 0, 0, 0.0, y, 0, n_tr
        ev_t[0] = 0.0
        ev_kind[0] = SPILL if status == SPILLED else SLIP
        _copy_row(y, ev_y, 0)
        return status, 0, 0, 0.0, y, 1, n_tr
    # Sign of the apsis function; at a turning point, the sign of pdot = -V'(r).
    r0 = z[Z_R]
    g_aps = z[Z_P] if z[Z_P] != 0.0 else -((-2.0 * A / r0 - B) / (r0 * r0) + C)
    next_out = dt_out
    n_acc = 0
    n_aps = 0
    while True:
        if n_acc >= max_steps:
            status = MAX_STEPS
            break
        _copy(z, zn)
        ttl_step(zn, hstep, wts, cf)
        if not (zn[Z_R] > 0.0 and math.isfinite(zn[Z_P]) and math.isfinite(zn[Z_W])):
            status = NONFINITE
            break
        n_acc += 1
        sig_stop = 2.0 * hstep
        stop_status = OK
        stop_kind = 0
        stop_is_event = False
        if zn[Z_T] >= t_end:
            g0 = z[Z_T] - t_end
            g1 = zn[Z_T] - t_end
            sig_stop = locate(np.int64(_TARGET_TIME), z, hstep, wts, cf, p, h, Lz, t_end, g0, g1,
                              zt, buf, st)  # fmt: skip
        for kind in range(SPILL, SLIP + 1):
            if kind == SPILL and not effects & RIM:
                continue
            if kind == SLIP and not effects & SLIP_CHECK:
                continue
            g1 = _target(kind, zn, p, h, Lz, 0.0, buf)
            if g1 > 0.0 or (kind == SPILL and g1 == 0.0):
                g0 = _target(kind, z, p, h, Lz, 0.0, buf)
                sig = locate(kind, z, hstep, wts, cf, p, h, Lz, 0.0, g0, g1, zt, buf, st)
                if sig <= sig_stop:
                    sig_stop = sig
                    stop_status = SPILLED if kind == SPILL else SLIPPED
                    stop_kind = kind
                    stop_is_event = True
        g1 = zn[Z_P]
        if (g_aps > 0.0 and g1 <= 0.0) or (g_aps < 0.0 and g1 >= 0.0):
            sig = locate(np.int64(PERICENTRE), z, hstep, wts, cf, p, h, Lz, 0.0, z[Z_P], g1, zt,
                         buf, st)  # fmt: skip
            if sig <= sig_stop:
                if n_ev == cap_ev:
                    status = BUFFER_FULL
                    break
                full_state(zt, p, h, Lz, buf)
                ev_t[n_ev] = zt[Z_T]
                ev_kind[n_ev] = APOCENTRE if g_aps > 0.0 else PERICENTRE
                _copy_row(buf, ev_y, n_ev)
                n_ev += 1
                n_aps += 1
                g_aps = -g_aps
                if n_apsides > 0 and n_aps >= n_apsides:
                    sig_stop = sig
                    stop_status = OK
                    stop_is_event = False
        stopping = sig_stop <= hstep
        if stopping:
            # Re-take the step up to the stop.
            _copy(z, zt)
            ttl_step(zt, sig_stop, wts, cf)
            if stop_is_event:
                if n_ev == cap_ev:
                    status = BUFFER_FULL
                    break
                full_state(zt, p, h, Lz, buf)
                ev_t[n_ev] = zt[Z_T]
                ev_kind[n_ev] = stop_kind
                _copy_row(buf, ev_y, n_ev)
                n_ev += 1
            t_lim = zt[Z_T]
        else:
            t_lim = zn[Z_T]
        if record == RECORD_EVERY_DT:
            while next_out <= t_lim and next_out < t_end and n_tr < cap_tr:
                g0 = z[Z_T] - next_out
                g1 = zn[Z_T] - next_out
                locate(np.int64(_TARGET_TIME), z, hstep, wts, cf, p, h, Lz, next_out, g0, g1, zs,
                       buf, st)  # fmt: skip
                tr_t[n_tr] = next_out
                full_state(zs, p, h, Lz, buf)
                _copy_row(buf, tr_y, n_tr)
                n_tr += 1
                next_out = n_tr * dt_out
            if n_tr == cap_tr:
                status = BUFFER_FULL
                break
        if stopping:
            _copy(zt, z)
        else:
            _copy(zn, z)
        if record == RECORD_STEPS or (record == RECORD_EVERY_DT and stopping):
            if n_tr == cap_tr:
                status = BUFFER_FULL
                break
            tr_t[n_tr] = z[Z_T]
            full_state(z, p, h, Lz, buf)
            _copy_row(buf, tr_y, n_tr)
            n_tr += 1
        if stopping:
            status = stop_status
            break
    full_state(z, p, h, Lz, y)
    return status, n_acc, 0, z[Z_T], y, n_ev, n_tr

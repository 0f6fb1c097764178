"""The model: one copy of each formula of docs/physics.md, as numba kernels.

- the radial problem: coefficients A, B, C of V(r) = A/r^2 + B/r + C r, V and its derivatives,
  the radial energy;
- the invariants E, L_z, h and the contact forces (F, N) of a state;
- the scene's right-hand side, with the effects compiled in or out.

A scene's structure is an ``effects`` bit mask (:data:`ROLLING_RESISTANCE`, :data:`RIM`,
:data:`SLIP_CHECK`, :data:`ATTITUDE`) that reaches every kernel as a numba *literal* integer
(the entry points call ``numba.literally(effects)``), so each effect set is its own compiled,
disk-cached specialisation and an effect that is off costs no branch, no state and no time: the
tests ``effects & FLAG`` fold to constants and LLVM drops the dead code. Gravity (g = 0 is free
fall) and the spin coupling (k = 0) are runtime parameters. All physical parameters travel in
one float64 array (layout ``P_*`` below, built by :func:`make_params`), so sweeping a grid never
recompiles.

State y (length :func:`state_size`): r [m], theta [rad], u = rdot [m/s], v = r sin(alpha)
thetadot [m/s], w = a omega_nu [m/s]; with :data:`ATTITUDE` also the unit quaternion
(q0, q1, q2, q3) (scalar first) rotating body axes to the fixed frame (identity at t = 0).

The scalar formulas (:func:`invariants_of`, :func:`contact_forces_of`, :func:`radial_energy`)
use arithmetic only, so their ``.py_func`` also evaluates them on numpy arrays (trajectories).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel

# Effect bits (combine with |). Gravity and spin coupling are parameters, not effects.
ROLLING_RESISTANCE = 1
RIM = 2
SLIP_CHECK = 4
ATTITUDE = 8
ALL_EFFECTS = ROLLING_RESISTANCE | RIM | SLIP_CHECK | ATTITUDE
#: Run option (not a scene effect): stop after ``P_THETA_MAX`` radians of azimuth (fate maps).
REVOLUTIONS = 16
#: Effect name (Scene.effects) -> bit; sliding, spin_friction: kernels.hybrid's, not ALL_EFFECTS.
EFFECT_BITS = {
    "rolling_resistance": ROLLING_RESISTANCE,
    "rim": RIM,
    "slip_check": SLIP_CHECK,
    "attitude": ATTITUDE,
    "sliding": 32,
    "spin_friction": 64,
}

# Parameter array layout.
P_ALPHA = 0  # half-aperture [rad]
P_SIN = 1  # sin(alpha)
P_COS = 2  # cos(alpha)
P_COT = 3  # cot(alpha)
P_M = 4  # mass [kg]
P_G = 5  # gravity [m s-2]
P_K = 6  # inertia factor I/(M a^2)
P_KK = 7  # k / (1 + k)
P_GC = 8  # g cos(alpha) / (1 + k) [m s-2]
P_RADIUS = 9  # sphere radius a [m]
P_RIM = 10  # the rim on the centre's cone: slant length of the centre there [m] (inf: none)
P_MU = 11  # friction coefficient (inf: no slip check)
P_CRR = 12  # rolling-resistance coefficient
P_INV_M1K = 13  # 1 / (M (1 + k)) [kg-1]
P_RIM_SLANT = 14  # the rim as a user measures it: slant length of the real cone [m] (inf: none)
P_R_VERTEX = 15  # the vertex region: r below this [m] ends a run (VERTEX_FRACTION a)
P_V_REST = 16  # speed [m/s] below which rolling resistance has stopped the sphere (per orbit)
P_THETA_MAX = 17  # azimuth [rad] after which a fate run stops (inf: none; REVOLUTIONS runs)
N_PARAMS = 18

#: The vertex region, in units of the sphere's radius a: the centre within this of its lowest
#: point (r = 0, where the sphere touches the cone all around and the single-contact model ends).
VERTEX_FRACTION = 1e-2

N_BASE = 5
N_ATTITUDE = 9


# ------------------------------------------------------------------------ the radial problem
@kernel
def coefficients(alpha, h, Lz, M, g, k):
    """A [J m^2], B [J m], C [J/m] of V(r) = A/r^2 + B/r + C r."""
    return coefficients_sc(math.sin(alpha), math.cos(alpha), h, Lz, M, g, k)


@kernel
def coefficients_sc(s, c, h, Lz, M, g, k):
    """:func:`coefficients` from s = sin(alpha), c = cos(alpha) (arithmetic only)."""
    s2 = s * s
    kk = k / (1.0 + k)
    cot = c / s
    A = Lz * Lz / (2.0 * M * s2) * (1.0 + kk * cot * cot)
    B = kk * h * Lz * c / s2
    C = M * g * c / (1.0 + k)
    return A, B, C


@kernel
def radial_energy(E, h, M, k):
    """Radial energy calE [J] from the total energy E [J] and spin invariant h [m/s]."""
    return E / (1.0 + k) - k / (2.0 * (1.0 + k)) * M * h * h


@kernel
def potential(r, A, B, C):
    """Effective potential V(r) = A/r^2 + B/r + C r [J]."""
    return A / (r * r) + B / r + C * r


@kernel
def potential_d1(r, A, B, C):
    """V'(r) [J/m]."""
    return -2.0 * A / (r * r * r) - B / (r * r) + C


@kernel
def potential_d2(r, A, B, C):
    """V''(r) [J/m^2]."""
    return 6.0 * A / (r * r * r * r) + 2.0 * B / (r * r * r)


# ----------------------------------------------------------------- invariants and forces
@kernel
def invariants_of(r, u, v, w, s, c, M, g, k):
    """(E [J], L_z [kg m^2/s], h [m/s]) of the state (r, u, v, w) on a cone with sin(alpha) = s,
    cos(alpha) = c."""
    Lz = M * r * v * s
    h = w - Lz * c / (M * r * s * s)
    E = 0.5 * (1.0 + k) * M * (u * u + v * v) + 0.5 * k * M * w * w + M * g * r * c
    return E, Lz, h


@kernel
def contact_forces_of(r, v, w, s, c, cot, M, g, kk):
    """(F [N], N [N]): the friction along e1 that rolling needs, and the normal force (> 0 on
    the inside of the cone); cot = cot(alpha), kk = k/(1+k)."""
    kappa = cot / r
    N = M * (g * s + v * v * kappa)
    F = kk * M * (g * c + kappa * v * w)
    return F, N


# ------------------------------------------------------------------------ the scene's params
@kernel
def make_params(alpha, M, g, k, a, rim, mu, c_rr):
    """The float64 parameter array (``P_*`` layout) of a scene on a cone of half-aperture alpha."""
    p = np.empty(N_PARAMS)
    p[P_M] = M
    p[P_G] = g
    p[P_K] = k
    p[P_KK] = k / (1.0 + k)
    p[P_RADIUS] = a
    p[P_RIM_SLANT] = rim
    p[P_MU] = mu
    p[P_CRR] = c_rr
    p[P_INV_M1K] = 1.0 / (M * (1.0 + k))
    p[P_R_VERTEX] = VERTEX_FRACTION * a
    p[P_V_REST] = 0.0
    p[P_THETA_MAX] = math.inf
    set_alpha(p, alpha)
    return p


@kernel
def set_alpha(p, alpha):
    """Update the alpha-dependent entries of ``p`` in place (for batch kernels over alpha)."""
    s = math.sin(alpha)
    c = math.cos(alpha)
    p[P_ALPHA] = alpha
    p[P_SIN] = s
    p[P_COS] = c
    p[P_COT] = c / s
    p[P_GC] = p[P_G] * c / (1.0 + p[P_K])
    p[P_RIM] = rim_on_centre_cone(p[P_RIM_SLANT], p[P_RADIUS], c / s)


@kernel
def rim_on_centre_cone(rim, a, cot):
    """The rim's slant length on the centre's cone [m]: where the centre is when the contact
    point reaches the real cone's edge at slant length ``rim`` from the real vertex. The contact
    point sits a cot(alpha) farther from the real vertex than the centre is from its own
    (docs/physics.md "Geometry and state"). inf stays inf."""
    return rim - a * cot


@kernel
def param_tuple(p):
    """The parameter array as a tuple: the hot loops index it with constants and keep the values
    in registers (an array is re-read after every store that might alias it)."""
    return (p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11], p[12],
            p[13], p[14], p[15], p[16], p[17])  # fmt: skip


def state_size_of(effects: int) -> int:
    """Length of the state vector of an effect set: r, theta, u, v, w; then the attitude
    quaternion (4) with ATTITUDE; then the work done against rolling resistance [J] with
    ROLLING_RESISTANCE (always the last component)."""
    return N_BASE + (4 if effects & ATTITUDE else 0) + (1 if effects & ROLLING_RESISTANCE else 0)


@kernel
def state_size(effects):
    """:func:`state_size_of` inside kernels."""
    n = N_BASE
    if effects & ATTITUDE:
        n += 4
    if effects & ROLLING_RESISTANCE:
        n += 1
    return n


# ------------------------------------------------------------------------ right-hand side
@kernel
def motion_rates(r, u, v, w, p, effects):
    """(rdot, thetadot, udot, vdot, wdot) of the centre (docs/physics.md "Equations of motion";
    rolling resistance from "Effects beyond the ideal cone" when compiled in)."""
    ir = 1.0 / r
    kappa = p[P_COT] * ir
    vir = v * ir
    udot = v * vir + p[P_KK] * kappa * v * w - p[P_GC]
    vdot = -u * vir
    if effects & ROLLING_RESISTANCE:
        # A force c_rr N opposing the CM velocity (u, v); at zero speed, the pull (static).
        speed = math.sqrt(u * u + v * v)
        N = p[P_M] * (p[P_G] * p[P_SIN] + v * vir * p[P_COT])
        f = p[P_CRR] * N * p[P_INV_M1K]
        if speed > 0.0:
            udot -= f * u / speed
            vdot -= f * v / speed
        else:
            pull = math.sqrt(udot * udot + vdot * vdot)
            held = min(f, pull) / pull if pull > 0.0 else 0.0
            udot -= held * udot
            vdot -= held * vdot
    return u, vir / p[P_SIN], udot, vdot, -kappa * u * v


@kernel
def omega_fixed(theta, u, v, w, p):
    """Angular velocity (wx, wy, wz) [rad/s] in the fixed frame: (-v/a) e1 + (u/a) e2 + (w/a) nu."""
    s = p[P_SIN]
    c = p[P_COS]
    cth = math.cos(theta)
    sth = math.sin(theta)
    ia = 1.0 / p[P_RADIUS]
    o1 = -v * ia
    o2 = u * ia
    o3 = w * ia
    # e1 = (s cth, s sth, c), e2 = (-sth, cth, 0), nu = (-c cth, -c sth, s)
    wx = o1 * s * cth - o2 * sth - o3 * c * cth
    wy = o1 * s * sth + o2 * cth - o3 * c * sth
    wz = o1 * c + o3 * s
    return wx, wy, wz


@kernel
def quaternion_rate(theta, u, v, w, q0, q1, q2, q3, p):
    """qdot = 1/2 (0, omega) * q: q maps body axes to the fixed frame, omega in the fixed frame."""
    wx, wy, wz = omega_fixed(theta, u, v, w, p)
    return (
        0.5 * (-wx * q1 - wy * q2 - wz * q3),
        0.5 * (wx * q0 + wy * q3 - wz * q2),
        0.5 * (wy * q0 + wz * q1 - wx * q3),
        0.5 * (wz * q0 + wx * q2 - wy * q1),
    )


@kernel
def resistance_power(r, u, v, p):
    """Power [W] dissipated by rolling resistance, c_rr N |V| (the rate of the work state)."""
    N = p[P_M] * (p[P_G] * p[P_SIN] + v * v * p[P_COT] / r)
    return p[P_CRR] * N * math.sqrt(u * u + v * v)


@kernel
def rates5(y0, y1, y2, y3, y4, p, effects):
    """dy/dt of a 5-component state given as scalars (a tuple)."""
    return motion_rates(y0, y2, y3, y4, p, effects)


@kernel
def rates6(y0, y1, y2, y3, y4, y5, p, effects):
    """dy/dt of the state with the work done against rolling resistance (y5)."""
    a, b, c, d, e = motion_rates(y0, y2, y3, y4, p, effects)
    return a, b, c, d, e, resistance_power(y0, y2, y3, p)


@kernel
def rates9(y0, y1, y2, y3, y4, y5, y6, y7, y8, p, effects):
    """dy/dt of a 9-component state (with the attitude quaternion) given as scalars."""
    a, b, c, d, e = motion_rates(y0, y2, y3, y4, p, effects)
    q0, q1, q2, q3 = quaternion_rate(y1, y2, y3, y4, y5, y6, y7, y8, p)
    return a, b, c, d, e, q0, q1, q2, q3


@kernel
def rates10(y0, y1, y2, y3, y4, y5, y6, y7, y8, y9, p, effects):
    """dy/dt of the state with the attitude quaternion and the work against resistance."""
    a, b, c, d, e = motion_rates(y0, y2, y3, y4, p, effects)
    q0, q1, q2, q3 = quaternion_rate(y1, y2, y3, y4, y5, y6, y7, y8, p)
    return a, b, c, d, e, q0, q1, q2, q3, resistance_power(y0, y2, y3, p)


@kernel
def rhs(y, p, effects, out, row):
    """dy/dt of the scene ``effects`` into the row ``row`` of the 2-D array ``out``."""
    a, b, c, d, e = motion_rates(y[0], y[2], y[3], y[4], p, effects)
    out[row, 0] = a
    out[row, 1] = b
    out[row, 2] = c
    out[row, 3] = d
    out[row, 4] = e
    if effects & ATTITUDE:
        q0, q1, q2, q3 = quaternion_rate(y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8], p)
        out[row, 5] = q0
        out[row, 6] = q1
        out[row, 7] = q2
        out[row, 8] = q3
    if effects & ROLLING_RESISTANCE:
        out[row, state_size(effects) - 1] = resistance_power(y[0], y[2], y[3], p)


# ----------------------------------------------------------- quantities of a state vector
@kernel
def forces(y, p):
    """(F [N], N [N]) of the state y (:func:`contact_forces_of`)."""
    return contact_forces_of(
        y[0], y[3], y[4], p[P_SIN], p[P_COS], p[P_COT], p[P_M], p[P_G], p[P_KK]
    )


@kernel
def slip_margin(y, p, effects):
    """Event function of the slip check: |F| - mu N [N] (> 0: the sphere slips).

    F is the whole friction force at the contact. With rolling resistance (a couple c_rr N a
    opposing the rolling) it adds -c_rr N/(1+k) along the velocity (u, v) to the conservative
    part F e1 (docs/physics.md "Effects beyond the ideal cone"); at zero speed, what holds the
    sphere against the pull down the generatrix, up to c_rr N/(1+k) (:func:`motion_rates`)."""
    F, N = forces(y, p)
    if effects & ROLLING_RESISTANCE:
        u = y[2]
        v = y[3]
        speed = math.sqrt(u * u + v * v)
        if speed > 0.0:
            f = p[P_CRR] * N / ((1.0 + p[P_K]) * speed)
            F1 = F - f * u
            F2 = f * v
            return math.sqrt(F1 * F1 + F2 * F2) - p[P_MU] * N
        held = p[P_M] * min(p[P_GC], p[P_CRR] * N * p[P_INV_M1K])
        return abs(F + held) - p[P_MU] * N
    return abs(F) - p[P_MU] * N


@kernel
def rim_margin(y, p):
    """Event function of the rim: r - rim [m] (>= 0: the sphere has left the cone)."""
    return y[0] - p[P_RIM]


@kernel
def invariants(y, p):
    """(E [J], L_z [kg m^2/s], h [m/s]) of the state y (:func:`invariants_of`)."""
    return invariants_of(y[0], y[2], y[3], y[4], p[P_SIN], p[P_COS], p[P_M], p[P_G], p[P_K])


@kernel
def holds_at_rest(p):
    """Whether rolling resistance can hold a sphere at rest on this cone's slope: the slope's
    pull g cos(alpha) against the most the resistance gives, c_rr N = c_rr M g sin(alpha)."""
    return p[P_COT] <= p[P_CRR]


@kernel
def kinetic_energy(y, p):
    """Kinetic energy [J] of translation and rotation."""
    M = p[P_M]
    k = p[P_K]
    u = y[2]
    v = y[3]
    w = y[4]
    return 0.5 * (1.0 + k) * M * (u * u + v * v) + 0.5 * k * M * w * w


@kernel
def contact_velocity(y, ydot, p):
    """Velocity [m/s] (fixed frame) of the material point of the sphere at the contact.

    R_dot + omega x (-a nu), with R_dot from (rdot, thetadot) = ydot[0:2] and omega recovered from
    the attitude, omega = 2 qdot q* / |q|^2 with qdot = ydot[5:9]: zero for rolling without slip,
    so it checks the frame, the rolling constraint and the quaternion's kinematics together.
    """
    s = p[P_SIN]
    c = p[P_COS]
    a = p[P_RADIUS]
    r = y[0]
    cth = math.cos(y[1])
    sth = math.sin(y[1])
    rd = ydot[0]
    vt = r * s * ydot[1]
    # R_dot = rdot e1 + r s thetadot e2
    Rx = rd * s * cth - vt * sth
    Ry = rd * s * sth + vt * cth
    Rz = rd * c
    q0, q1, q2, q3 = y[5], y[6], y[7], y[8]
    d0, d1, d2, d3 = ydot[5], ydot[6], ydot[7], ydot[8]
    n2 = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
    # vector part of 2 qdot * conj(q)
    wx = 2.0 * (-d0 * q1 + d1 * q0 - d2 * q3 + d3 * q2) / n2
    wy = 2.0 * (-d0 * q2 + d1 * q3 + d2 * q0 - d3 * q1) / n2
    wz = 2.0 * (-d0 * q3 - d1 * q2 + d2 * q1 + d3 * q0) / n2
    # -a nu = a (c cth, c sth, -s)
    px = a * c * cth
    py = a * c * sth
    pz = -a * s
    vx = Rx + wy * pz - wz * py
    vy = Ry + wz * px - wx * pz
    vz = Rz + wx * py - wy * px
    return vx, vy, vz

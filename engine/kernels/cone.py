"""The cone, the first model: one copy of each formula of docs/physics.md for a sphere rolling
inside a right circular cone of half-aperture alpha, as numba kernels.

- its parameters (:data:`SLOTS`, after the shared ones of :mod:`.layouts`): alpha and its sines
  and cosines, the rim on the centre's cone (:func:`set_alpha`);
- the radial problem: coefficients A, B, C of V(r) = A/r^2 + B/r + C r, V and its derivative,
  the radial energy;
- the invariants E, L_z, h and the contact forces (F, N) of a state;
- the rolling equations of motion (:func:`motion_rates`), the effects' forces and couples
  added as every model adds them (:mod:`.forces`), and the angular velocity in the fixed frame;
- its meridian frame for the sliding equations (:func:`contact_frame`, read by
  :mod:`.sliding`), its height energy and a resting spin's rate of decay.

State y: r [m] (the centre's distance from the vertex of its own cone, along the generatrix),
theta [rad], u = rdot [m/s], v = r sin(alpha) thetadot [m/s], w = a omega_nu [m/s]
(:mod:`.model`). The scalar formulas (:func:`invariants_of`, :func:`contact_forces_of`,
:func:`radial_energy`, :func:`coefficients_sc`) use arithmetic only, so their ``.py_func`` also
evaluates them on numpy arrays (trajectories, launches).

The drivers reach these through the model interface (:mod:`.model`); the closed form
(:mod:`.geometry`, :mod:`.batch`, :mod:`.ending`), the symplectic integrator and the cone's
starts (:mod:`.cone_starts`) are the cone's own capabilities and read it directly.
"""

from __future__ import annotations

import math

from .._jit import kernel
from .effects import FORCE_EFFECTS
from .forces import effect_terms, taken_power
from .layouts import (
    P_G,
    P_INV_M1K,
    P_K,
    P_KK,
    P_M,
    P_MU,
    P_RADIUS,
    P_RIM,
    P_RIM_SLANT,
    Y_QUAT,
    Y_R,
    Y_THETA,
    Y_U,
    Y_V,
    Y_W,
    model_slots,
)

#: The cone's own parameter slots (after the shared ones).
SLOTS = ("alpha", "sin", "cos", "cot", "gc")
_SLOT = model_slots(SLOTS)
P_ALPHA = _SLOT["alpha"]  # half-aperture [rad]
P_SIN = _SLOT["sin"]  # sin(alpha)
P_COS = _SLOT["cos"]  # cos(alpha)
P_COT = _SLOT["cot"]  # cot(alpha)
P_GC = _SLOT["gc"]  # g cos(alpha) / (1 + k) [m s-2]


#: The slot of the domain's floor (None: r = 0): :func:`domain_floor`.
DOMAIN_FLOOR_SLOT = None


@kernel
def domain_floor(p):
    """The cone's state needs r > 0."""
    return 0.0


# ------------------------------------------------------------------------ the scene's params
@kernel
def set_alpha(p, alpha):
    """Update the alpha-dependent entries of ``p`` in place (batch kernels over alpha), the rim
    on the centre's cone among them (:func:`rim_on_centre_cone`)."""
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


@kernel
def normal_force(r, v, p):
    """N [N] = M (g sin(alpha) + kappa v^2), kappa = cot(alpha)/r (rolling and sliding)."""
    return p[P_M] * (p[P_G] * p[P_SIN] + v * v * p[P_COT] / r)


@kernel
def contact_frame(r, u, v, p):
    """The cone's meridian at the centre's r as the hybrid model reads any surface of
    revolution (:func:`.contact.contact_frame`): (dtheta/dt [rad/s], N [N], g sin b [m s-2],
    cos(b)/rho, kappa, sin(b)/rho [1/m], dr/ds). The generatrix rises at b = pi/2 - alpha and
    is straight (kappa = 0), rho = r sin(alpha): cos(b)/rho = 1/r, sin(b)/rho = cot(alpha)/r,
    g sin b = g cos(alpha), N is :func:`normal_force`, and r is the arc length (dr/ds = 1)."""
    ir = 1.0 / r
    return (v * ir / p[P_SIN], normal_force(r, v, p), p[P_G] * p[P_COS], ir, 0.0, p[P_COT] * ir,
            1.0)  # fmt: skip


@kernel
def rolling_invariants_of(r, u, v, w, p):
    """(E [J], L_z [kg m^2/s], h [m/s]) of a rolling state given by its parts (a hybrid state's:
    :func:`invariants_of` with the cone of ``p``)."""
    return invariants_of(r, u, v, w, p[P_SIN], p[P_COS], p[P_M], p[P_G], p[P_K])


@kernel
def height_energy(r, p):
    """M g z [J] of the centre at r (z measured from the vertex of the centre's cone)."""
    return p[P_M] * p[P_G] * r * p[P_COS]


@kernel
def rest_spin_rate(c_spin, r, p):
    """|dw/dt| [m s-2] of a sphere at rest (anywhere on the cone: r is not needed) spinning
    against spin friction, c_spin N/(k M) with N = M g sin(alpha)."""
    return c_spin * p[P_G] * p[P_SIN] / p[P_K]


@kernel
def rolling_orbit(r, u, v, w, p):
    """(calE [J], h [m/s], L_z) of the rolling state (r, u, v, w): the orbit a story reports."""
    E, Lz, h = rolling_invariants_of(r, u, v, w, p)
    return radial_energy(E, h, p[P_M], p[P_K]), h, Lz


@kernel
def rolling_energy(r, u, v, w, p):
    """E [J] of the rolling state (r, u, v, w)."""
    return rolling_invariants_of(r, u, v, w, p)[0]


#: Inside a cone N = M (g sin(alpha) + kappa v^2) > 0 (:func:`normal_force`): the sphere never
#: leaves it (the lift-off event is not compiled into its runs).
LEAVES = False


@kernel
def lift_margin(y, p):
    """Event function of lift-off: -N [N] (>= 0: the sphere leaves the surface; never here)."""
    return -normal_force(y[Y_R], y[Y_V], p)


@kernel
def invariants(y, p):
    """(E [J], L_z [kg m^2/s], h [m/s]) of the state y (:func:`invariants_of`)."""
    return invariants_of(y[Y_R], y[Y_U], y[Y_V], y[Y_W], p[P_SIN], p[P_COS], p[P_M], p[P_G], p[P_K])


@kernel
def rolling_friction(y, p, effects):
    """(F1, F2) [N]: the friction at the contact that rolling needs, along (e1, e2): the
    conservative part F e1 (:func:`contact_forces_of`) and the part the effects' forces and
    couples need, ((t2 - k f1), (-t1 - k f2)) / (1 + k) (docs/physics.md "Effects as forces and
    couples")."""
    r, u, v, w = y[Y_R], y[Y_U], y[Y_V], y[Y_W]
    F, N = contact_forces_of(r, v, w, p[P_SIN], p[P_COS], p[P_COT], p[P_M], p[P_G], p[P_KK])
    F1 = F
    F2 = 0.0
    if effects & FORCE_EFFECTS:
        pull_u, pull_v = pull(r, u, v, w, p)
        f1, f2, t1, t2, t3 = effect_terms(effects, p, u, v, -v, u, w, N, pull_u, pull_v)
        k = p[P_K]
        F1 += (t2 - k * f1) / (1.0 + k)
        F2 += (-t1 - k * f2) / (1.0 + k)
    return F1, F2, N


@kernel
def slip_margin(y, p, effects):
    """Event function of the slip check: |F| - mu N [N] (> 0: the sphere slips), F the whole
    friction at the contact (:func:`rolling_friction`)."""
    F1, F2, N = rolling_friction(y, p, effects)
    if effects & FORCE_EFFECTS:
        return math.sqrt(F1 * F1 + F2 * F2) - p[P_MU] * N
    return abs(F1) - p[P_MU] * N


# ------------------------------------------------------------------------ right-hand side
@kernel
def pull(r, u, v, w, p):
    """(udot, vdot) [m/s^2] of the rolling sphere without the effects (docs/physics.md
    "Equations of motion")."""
    ir = 1.0 / r
    kappa = p[P_COT] * ir
    vir = v * ir
    return v * vir + p[P_KK] * kappa * v * w - p[P_GC], -u * vir


@kernel
def motion_rates(r, u, v, w, p, effects):
    """(rdot, thetadot, udot, vdot, wdot) of the centre (docs/physics.md "Equations of motion";
    the effects' forces and couples (:mod:`.forces`) when compiled in)."""
    udot, vdot = pull(r, u, v, w, p)
    wdot = -(p[P_COT] * (1.0 / r)) * u * v
    if effects & FORCE_EFFECTS:
        N = normal_force(r, v, p)
        f1, f2, t1, t2, t3 = effect_terms(effects, p, u, v, -v, u, w, N, udot, vdot)
        udot += (f1 + t2) * p[P_INV_M1K]
        vdot += (f2 - t1) * p[P_INV_M1K]
        if t3 != 0.0:
            wdot += t3 / (p[P_K] * p[P_M])
    return u, v * (1.0 / r) / p[P_SIN], udot, vdot, wdot


@kernel
def dissipated_power(r, u, v, w, p, effects):
    """Power [W] the effects take from the rolling sphere (the rate of the work state)."""
    power = 0.0
    if effects & FORCE_EFFECTS:
        udot, vdot = pull(r, u, v, w, p)
        f1, f2, t1, t2, t3 = effect_terms(effects, p, u, v, -v, u, w, normal_force(r, v, p),
                                          udot, vdot)  # fmt: skip
        power = taken_power(f1, f2, t1, t2, t3, u, v, -v, u, w)
    return power


@kernel
def omega_fixed(r, theta, u, v, w, p):
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
def contact_velocity(y, ydot, p):
    """Velocity [m/s] (fixed frame) of the material point of the sphere at the contact.

    R_dot + omega x (-a nu), with R_dot from (rdot, thetadot) = ydot[0:2] and omega recovered from
    the attitude, omega = 2 qdot q* / |q|^2 with qdot = ydot[5:9]: zero for rolling without slip,
    so it checks the frame, the rolling constraint and the quaternion's kinematics together.
    """
    s = p[P_SIN]
    c = p[P_COS]
    a = p[P_RADIUS]
    r = y[Y_R]
    cth = math.cos(y[Y_THETA])
    sth = math.sin(y[Y_THETA])
    rd = ydot[Y_R]
    vt = r * s * ydot[Y_THETA]
    # R_dot = rdot e1 + r s thetadot e2
    Rx = rd * s * cth - vt * sth
    Ry = rd * s * sth + vt * cth
    Rz = rd * c
    q0, q1, q2, q3 = y[Y_QUAT], y[Y_QUAT + 1], y[Y_QUAT + 2], y[Y_QUAT + 3]
    d0, d1, d2, d3 = ydot[Y_QUAT], ydot[Y_QUAT + 1], ydot[Y_QUAT + 2], ydot[Y_QUAT + 3]
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

"""Any surface of revolution, the second model: a sphere rolling on the inside of a surface
whose meridian :mod:`.meridian` describes (docs/physics.md "Any surface of revolution").

State y (the model interface's, :mod:`.model`): q, the meridian parameter of the contact point
(its kind's: :mod:`.meridian`), theta [rad], u = ds/dt [m/s] along the centre's meridian, v =
rho dtheta/dt [m/s] along the parallel, w = a omega_nu [m/s] the spin about the normal nu (from
the contact to the centre). With the centre's meridian at q (rho, z, slope b, curvature kappa,
sigma = ds/dq) and k' = k/(1+k), the rolling equations are

    dq/dt = u / sigma,   dtheta/dt = v / rho
    du/dt = v^2 cos(b)/rho + k' sin(b)/rho v w - g sin(b)/(1+k)
    dv/dt = -u v cos(b)/rho - k' kappa u w
    dw/dt = -u v (sin(b)/rho - kappa)

plus the effects' forces and couples (:mod:`.forces`) as every model adds them. The normal
force is N = M (g cos b + sin(b)/rho v^2 + kappa u^2), the friction rolling needs
(F1, F2) = k' M (g sin b + sin(b)/rho v w, -kappa u w). On a cone (kappa = 0, b = pi/2 - alpha,
s = r) these are the cone's equations (:mod:`.cone`).
"""

from __future__ import annotations

import math

from .._jit import kernel
from .effects import FORCE_EFFECTS
from .forces import effect_terms, taken_power
from .layouts import P_G, P_INV_M1K, P_K, P_KK, P_M, P_MU, P_RADIUS, Y_R, Y_U, Y_V, Y_W
from .meridian import P_Q_FLOOR, centre
from .meridian import SLOTS as SLOTS

#: The slot of the domain's floor: where the sphere stops fitting or touching.
DOMAIN_FLOOR_SLOT = P_Q_FLOOR


@kernel
def domain_floor(p):
    """A surface's state needs q above Q_FLOOR (where the sphere stops fitting, else the axis;
    -inf on the cylinder): the inner end's event (the hole, the fit limit's margin, the axis
    region) lies above it."""
    return p[P_Q_FLOOR]


@kernel
def geometry(q, p):
    """(1/rho, cos b, sin b, kappa, sigma) of the centre's meridian at q."""
    rho, z, cb, sb, kappa, sigma, fit = centre(p, q)
    return 1.0 / rho, cb, sb, kappa, sigma


@kernel
def pull(q, u, v, w, p):
    """(du/dt, dv/dt, dw/dt) of the rolling sphere without the effects, and (N, sigma, 1/rho)."""
    irho, cb, sb, kappa, sigma = geometry(q, p)
    kk = p[P_KK]
    sbr = sb * irho
    udot = v * v * cb * irho + kk * sbr * v * w - p[P_G] * sb / (1.0 + p[P_K])
    vdot = -u * v * cb * irho - kk * kappa * u * w
    wdot = -u * v * (sbr - kappa)
    N = p[P_M] * (p[P_G] * cb + sbr * v * v + kappa * u * u)
    return udot, vdot, wdot, N, sigma, irho


#: The normal force can fall to zero where the meridian curves away from the ball (a funnel, a
#: profile's convex stretch: kappa u^2 < 0) or over the bowl's equator (cos b < 0): the
#: sphere leaves the surface there, an event that ends the run (``lifted_off``).
LEAVES = True


@kernel
def normal_force(q, u, v, p):
    """N [N] = M (g cos b + sin(b)/rho v^2 + kappa u^2) (module docstring)."""
    rho, z, cb, sb, kappa, sigma, fit = centre(p, q)
    return p[P_M] * (p[P_G] * cb + sb / rho * v * v + kappa * u * u)


@kernel
def contact_frame(q, u, v, p):
    """The meridian frame at the centre's q for the hybrid model (:func:`.contact.contact_frame`):
    (dtheta/dt [rad/s], N [N], g sin b [m s-2], cos(b)/rho, kappa, sin(b)/rho [1/m],
    dq/ds = 1/sigma)."""
    rho, z, cb, sb, kappa, sigma, fit = centre(p, q)
    irho = 1.0 / rho
    sbr = sb * irho
    N = p[P_M] * (p[P_G] * cb + sbr * v * v + kappa * u * u)
    return v * irho, N, p[P_G] * sb, cb * irho, kappa, sbr, 1.0 / sigma


@kernel
def height_energy(q, p):
    """M g z [J] of the centre at q (z of the centre's meridian, :func:`.meridian.centre`)."""
    return p[P_M] * p[P_G] * centre(p, q)[1]


@kernel
def rolling_energy(q, u, v, w, p):
    """E [J] of the rolling state (q, u, v, w)."""
    M = p[P_M]
    k = p[P_K]
    z = centre(p, q)[1]
    return 0.5 * (1.0 + k) * M * (u * u + v * v) + 0.5 * k * M * w * w + M * p[P_G] * z


@kernel
def rolling_orbit(q, u, v, w, p):
    """(E [J], NaN, NaN): what a story reports for a rolling state; the orbit's two linear
    integrals need the surface's table (``engine.routh``), which the kernels do not hold."""
    return rolling_energy(q, u, v, w, p), math.nan, math.nan


@kernel
def rest_spin_rate(c_spin, q, p):
    """|dw/dt| [m s-2] of a sphere at rest at q spinning against spin friction, c_spin N/(k M)
    with N = M g cos(b) (at rest the normal force is the weight's part)."""
    return c_spin * p[P_G] * centre(p, q)[2] / p[P_K]


@kernel
def lift_margin(y, p):
    """Event function of lift-off: -N [N] (>= 0: the sphere leaves the surface)."""
    return -normal_force(y[Y_R], y[Y_U], y[Y_V], p)


@kernel
def motion_rates(q, u, v, w, p, effects):
    """(dq/dt, dtheta/dt, du/dt, dv/dt, dw/dt) (module docstring)."""
    udot, vdot, wdot, N, sigma, irho = pull(q, u, v, w, p)
    if effects & FORCE_EFFECTS:
        f1, f2, t1, t2, t3 = effect_terms(effects, p, u, v, -v, u, w, N, udot, vdot)
        udot += (f1 + t2) * p[P_INV_M1K]
        vdot += (f2 - t1) * p[P_INV_M1K]
        if t3 != 0.0:
            wdot += t3 / (p[P_K] * p[P_M])
    return u / sigma, v * irho, udot, vdot, wdot


@kernel
def dissipated_power(q, u, v, w, p, effects):
    """Power [W] the effects take from the rolling sphere."""
    power = 0.0
    if effects & FORCE_EFFECTS:
        udot, vdot, wdot, N, sigma, irho = pull(q, u, v, w, p)
        f1, f2, t1, t2, t3 = effect_terms(effects, p, u, v, -v, u, w, N, udot, vdot)
        power = taken_power(f1, f2, t1, t2, t3, u, v, -v, u, w)
    return power


@kernel
def omega_fixed(q, theta, u, v, w, p):
    """Angular velocity (wx, wy, wz) [rad/s] in the fixed frame: (-v/a) e1 + (u/a) e2 + (w/a) nu,
    e1 = (cos b cos th, cos b sin th, sin b), e2 = (-sin th, cos th, 0),
    nu = (-sin b cos th, -sin b sin th, cos b)."""
    irho, cb, sb, kappa, sigma = geometry(q, p)
    cth = math.cos(theta)
    sth = math.sin(theta)
    ia = 1.0 / p[P_RADIUS]
    o1 = -v * ia
    o2 = u * ia
    o3 = w * ia
    wx = o1 * cb * cth - o2 * sth - o3 * sb * cth
    wy = o1 * cb * sth + o2 * cth - o3 * sb * sth
    wz = o1 * sb + o3 * cb
    return wx, wy, wz


@kernel
def invariants(y, p):
    """(E [J], M rho v [kg m^2/s], w [m/s]) of the state y: the energy, conserved, and the
    quantities Routh's two linear integrals are made of (``engine.surfaces``), which on a
    curved meridian are not conserved themselves."""
    rho, z, cb, sb, kappa, sigma, fit = centre(p, y[Y_R])
    M = p[P_M]
    k = p[P_K]
    u, v, w = y[Y_U], y[Y_V], y[Y_W]
    E = 0.5 * (1.0 + k) * M * (u * u + v * v) + 0.5 * k * M * w * w + M * p[P_G] * z
    return E, M * rho * v, w


@kernel
def rolling_friction(y, p, effects):
    """(F1, F2, N) [N]: the friction at the contact that rolling needs, along (e1, e2), with the
    part the effects' forces and couples need, and the normal force."""
    q, u, v, w = y[Y_R], y[Y_U], y[Y_V], y[Y_W]
    udot, vdot, wdot, N, sigma, irho = pull(q, u, v, w, p)
    rho, z, cb, sb, kappa, sigma, fit = centre(p, q)
    kM = p[P_KK] * p[P_M]
    F1 = kM * (p[P_G] * sb + sb * irho * v * w)
    F2 = -kM * kappa * u * w
    if effects & FORCE_EFFECTS:
        f1, f2, t1, t2, t3 = effect_terms(effects, p, u, v, -v, u, w, N, udot, vdot)
        k = p[P_K]
        F1 += (t2 - k * f1) / (1.0 + k)
        F2 += (-t1 - k * f2) / (1.0 + k)
    return F1, F2, N


@kernel
def slip_margin(y, p, effects):
    """Event function of the slip check: |F| - mu N [N] (> 0: the sphere slips)."""
    F1, F2, N = rolling_friction(y, p, effects)
    return math.sqrt(F1 * F1 + F2 * F2) - p[P_MU] * N

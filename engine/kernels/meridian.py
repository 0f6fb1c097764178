"""The meridians of the surfaces of revolution: where the sphere touches, and where its centre
moves (docs/physics.md "Any surface of revolution").

A surface is the touching surface's meridian (rho_c(q), z_c(q)) in a parameter q of its own
(its kind's, below), in the parameter array's surface slots (:data:`SLOTS`, set by
``engine.surfaces``). The sphere's centre moves on the offset surface, a (the sphere's radius)
from the touching one along the normal nu that points from the contact into the surface's
inside. With the tangent (cos b, sin b) = (rho_c', z_c') / l, l = |(rho_c', z_c')|, and the
touching meridian's curvature kc = (rho_c' z_c'' - z_c' rho_c'') / l^3:

    rho = rho_c - a sin b,   z = z_c + a cos b              (nu = (-sin b, cos b))
    ds/dq = sigma = l (1 - a kc),   kappa = db/ds = kc / (1 - a kc)

s the centre's arc length along its meridian, b its slope from the horizontal (the same for
both meridians: they are parallel curves), kappa its curvature. The sphere fits where
1 - a kc > 0 (a concave radius of curvature 1/kc above a). Kinds and their parameter q:

====================  =====================================================  =============
kind                  touching meridian                                      q
====================  =====================================================  =============
CONE (alpha)          rho_c = q sin(alpha), z_c = q cos(alpha)               slant length
BOWL (R)              rho_c = R sin q, z_c = R (1 - cos q)                   polar angle
PARABOLOID (R)        z_c = rho_c^2 / (2 R)                                  rho_c
FUNNEL (c, hole)      z_c = -c / rho_c, rho_c >= hole                        rho_c
POWER_LAW (c, n)      z_c = c rho_c^n                                        rho_c
CYLINDER (R)          rho_c = R                                              z_c
PROFILE               z_c = sum_j a_j T_j(x), x = (2 rho_c - lo - hi)/(hi-lo)  rho_c
====================  =====================================================  =============

Everything here is arithmetic on the slots: a run of a surface compiles once for every kind
(the kind is a runtime value; one branch per evaluation).
"""

from __future__ import annotations

import math

from .._jit import kernel
from .layouts import P_RADIUS, model_slots

CONE = 0
BOWL = 1
PARABOLOID = 2
FUNNEL = 3
POWER_LAW = 4
CYLINDER = 5
PROFILE = 6
KIND_NAMES = ("cone", "bowl", "paraboloid", "funnel", "power_law", "cylinder", "profile")
#: Chebyshev coefficients a profile may have (its degree + 1).
PROFILE_TERMS = 24
#: The surface slots: the kind, two shape parameters (CONE: alpha; BOWL, PARABOLOID, CYLINDER:
#: R; FUNNEL: c, hole; POWER_LAW: c, n; PROFILE: lo, hi), the meridian parameter's range where
#: the sphere fits and touches (Q_LO, Q_HI: the hole or the fit limit, the rim), the floor of
#: the integrators' domain (Q_FLOOR: below Q_LO, so that the inner end is an event that can
#: fire), then a profile's coefficients.
SLOTS = ("kind", "shape1", "shape2", "q_lo", "q_hi", "q_floor") + tuple(
    f"cheb{j}" for j in range(PROFILE_TERMS)
)
_SLOT = model_slots(SLOTS)
P_KIND = _SLOT["kind"]
P_SHAPE1 = _SLOT["shape1"]
P_SHAPE2 = _SLOT["shape2"]
P_Q_LO = _SLOT["q_lo"]
P_Q_HI = _SLOT["q_hi"]
P_Q_FLOOR = _SLOT["q_floor"]  # below it the geometry means nothing (a step there is rejected)
P_CHEB = _SLOT["cheb0"]


@kernel
def _chebyshev(p, x):
    """(f, f', f'') at x in [-1, 1] of the profile's series sum_j a_j T_j(x), by the recurrences
    of T_j and its derivatives."""
    t0, t1 = 1.0, x
    d0, d1 = 0.0, 1.0
    e0, e1 = 0.0, 0.0
    f = p[P_CHEB] + p[P_CHEB + 1] * x
    f1 = p[P_CHEB + 1]
    f2 = 0.0
    for j in range(2, PROFILE_TERMS):
        t2 = 2.0 * x * t1 - t0
        d2 = 2.0 * t1 + 2.0 * x * d1 - d0
        e2 = 4.0 * d1 + 2.0 * x * e1 - e0
        c = p[P_CHEB + j]
        f += c * t2
        f1 += c * d2
        f2 += c * e2
        t0, t1 = t1, t2
        d0, d1 = d1, d2
        e0, e1 = e1, e2
    return f, f1, f2


@kernel
def touching(p, q):
    """(rho_c, z_c, rho_c', z_c', rho_c'', z_c'') of the touching meridian at q (derivatives in
    q)."""
    kind = p[P_KIND]
    s1 = p[P_SHAPE1]
    s2 = p[P_SHAPE2]
    if kind == CONE:
        sa = math.sin(s1)
        ca = math.cos(s1)
        return q * sa, q * ca, sa, ca, 0.0, 0.0
    if kind == BOWL:
        sq = math.sin(q)
        cq = math.cos(q)
        sh = math.sin(0.5 * q)  # R (1 - cos q) = 2 R sin^2(q/2), without the cancellation
        return s1 * sq, 2.0 * s1 * sh * sh, s1 * cq, s1 * sq, -s1 * sq, s1 * cq
    if kind == PARABOLOID:
        return q, 0.5 * q * q / s1, 1.0, q / s1, 0.0, 1.0 / s1
    if kind == FUNNEL:
        iq = 1.0 / q
        return q, -s1 * iq, 1.0, s1 * iq * iq, 0.0, -2.0 * s1 * iq * iq * iq
    if kind == POWER_LAW:
        z = s1 * q**s2
        return q, z, 1.0, s2 * z / q, 0.0, s2 * (s2 - 1.0) * z / (q * q)
    if kind == CYLINDER:
        return s1, q, 0.0, 1.0, 0.0, 0.0
    # PROFILE: z(rho) as a Chebyshev series on [lo, hi] = [s1, s2]
    half = 0.5 * (s2 - s1)
    f, f1, f2 = _chebyshev(p, (q - 0.5 * (s1 + s2)) / half)
    return q, f, 1.0, f1 / half, 0.0, f2 / (half * half)


@kernel
def centre(p, q):
    """(rho [m], z [m], cos b, sin b, kappa [1/m], sigma = ds/dq, fit = 1 - a kc) of the centre's
    meridian at q (module docstring). fit <= 0: the sphere does not fit there."""
    rc, zc, r1, z1, r2, z2 = touching(p, q)
    a = p[P_RADIUS]
    ell = math.sqrt(r1 * r1 + z1 * z1)
    cb = r1 / ell
    sb = z1 / ell
    kc = (r1 * z2 - z1 * r2) / (ell * ell * ell)
    fit = 1.0 - a * kc
    return rc - a * sb, zc + a * cb, cb, sb, kc / fit, ell * fit, fit

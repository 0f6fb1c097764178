"""Classification and closed-form orbit geometry for one point, and the parallel batch kernel.

For g > 0 the radial integrals are complete elliptic integrals (docs/physics.md).
With energy - V = C (r - r1)(r2 - r)(r - r3) / r^2, r3 = -A / (C r1 r2) < 0, and
r = r1 cos^2 t + r2 sin^2 t,

    T_r = 4 sqrt(M/(2C)) cel(kc, 1, r1, r2) / sqrt(r1 - r3),
    psi = 2 K sqrt(M/(2C)) cel(kc, r2/r1, 1, 1) / (r1 sqrt(r1 - r3)),

with kc^2 = (r2 - r3)/(r1 - r3) and K = |L_z| / (M sin^2 alpha). In Carlson's form (used by the
tests as a second evaluation) T_r = 2 sqrt(M/(2C)) [r1 I0 + 2/3 (r2 - r1)(r1 - r3)
R_D(0, r2 - r3, r1 - r3)], I0 = 2 R_F(0, r1 - r3, r2 - r3), and psi = 2 K sqrt(M/(2C))
[R_F(0, 1-m, 1) + n/3 R_J(0, 1-m, 1, 1-n)] / (r2 sqrt(r2 - r3)), m = (r2-r1)/(r2-r3),
n = (r2-r1)/r2. Every term is positive, so no digits cancel. In free fall (g = 0):
T_r = pi (r1 + r2) sqrt(M / (2 |energy|)), psi = pi / Omega, and an escape sweeps
2 atan2(2 sqrt(A energy), B) / Omega in azimuth (= 2 arccos(sign(B)/e) / Omega, without
the e -> 1 and B -> 0 singularities).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .carlson import cel_pair
from .cone import coefficients, coefficients_sc, rim_on_centre_cone, set_alpha
from .ending import (
    critical_cube,
    critical_ratio,
    first_slip,
    friction_terms,
    mu_required_of,
    time_and_azimuth,
)
from .layouts import P_G, P_K, P_M, P_MU, P_RADIUS, P_RIM_SLANT, SLOTS
from .model import make_params
from .roots import circular_radius, free_fall_r_min, turning_points, turning_points_in, well

#: Orbit classes, stored as int8 ``orbit_class`` (CF flag_values, names CLASS_NAMES).
FORBIDDEN = 0
BOUNDED = 1
CIRCULAR = 2
HYPERBOLIC = 3
RADIAL = 4
SPILLS = 5
SLIPS = 6
OFF_CONE = 7
OUT_OF_RANGE = 8
CLASS_NAMES = (
    "forbidden",
    "bounded",
    "circular",
    "hyperbolic",
    "radial",
    "spills",
    "slips",
    "off_cone",
    "out_of_range",
)
#: :func:`family` kind of L_z = 0 (orbits through the axis).
AXIS = 1
#: Smallest A [J m^2] kept: below it (A underflows towards subnormals) the class is OUT_OF_RANGE.
A_MIN = 2.2250738585072014e-308 / 2.220446049250313e-16

#: Default tolerance of the circular class: |energy - V_min| <= CIRCULAR_TOL times the size of
#: the terms of V_min, |A|/r_c^2 + |B|/r_c + C r_c (>= |V_min|; not |V_min|, which cancels to
#: 0 where B < 0 balances the others while calE still carries their rounding).
CIRCULAR_TOL = 1e-12
NAN = math.nan


#: What :func:`family` returns: everything of (alpha, h, L_z) that does not depend on the
#: energy, a plain tuple, field i named ``FAMILY_FIELDS[i]`` and read by the ``FM_*`` places
#: (numba's own type: a class of this package in a cached kernel's signature would stop another
#: version from reading that cache, docs/architecture.md's kernel contract). The batch kernels
#: keep it in the rows of a table (row i: field i).
FAMILY_FIELDS = (
    "kind",  # AXIS (L_z = 0), OUT_OF_RANGE or 0
    "s",  # sin(alpha)
    "c",  # cos(alpha)
    "A",  # coefficients of V(r) = A/r^2 + B/r + C r
    "B",
    "C",
    "K",  # |L_z| / (M sin^2 alpha): thetadot = K / r^2
    "r_c",  # circular radius (NaN: none)
    "a",  # the well (.roots.well): its a, V_min, c3, igam, noise
    "V_min",
    "c3",
    "igam",
    "noise",
    "kk",  # the friction terms (.ending.friction_terms): kk, p0, p2, p3, q0, q3
    "p0",
    "p2",
    "p3",
    "q0",
    "q3",
    "rs3",  # .ending.critical_cube
    "fstar",  # .ending.critical_ratio (eager families only; NaN otherwise)
)
(FM_KIND, FM_S, FM_COS, FM_A, FM_B, FM_C, FM_K, FM_RC, FM_WELL, FM_VMIN, FM_C3, FM_IGAM,
 FM_NOISE, FM_KK, FM_P0, FM_P2, FM_P3, FM_Q0, FM_Q3, FM_RS3, FM_FSTAR) = range(
    len(FAMILY_FIELDS))  # fmt: skip
#: What :func:`family_head` returns: the family's fields but r_c and the well (a plain tuple;
#: its first :data:`FM_RC` places are the family's).
HEAD_FIELDS = FAMILY_FIELDS[:FM_RC] + FAMILY_FIELDS[FM_KK:]


def scene_params(M: float, g: float, k: float, a: float = 0.0, rim: float = math.inf,
                 mu: float = math.inf) -> np.ndarray:  # fmt: skip
    """The parameter array (``.layouts`` layout, as ``engine.Scene.params`` builds it) of a
    scene given by the closed form's numbers: the sphere's M, g, k, a, the rim (the real cone's
    slant length; +inf: none) and the friction limit mu (+inf: no slip check). The closed-form
    kernels read these six from it; alpha is per point (its slots are not read)."""
    slots = np.array([SLOTS["rim"], SLOTS["mu"]], np.int64)
    p = make_params(float(M), float(g), float(k), float(a), slots, np.array([rim, mu], np.float64))
    set_alpha(p, math.pi / 4)
    return p


def ideal_cone(p: np.ndarray) -> np.ndarray:
    """A copy of the parameter array ``p`` without the scene's rules (no rim, no slip check):
    the closed form of the orbit on the ideal cone."""
    q = p.copy()
    q[P_RIM_SLANT] = math.inf
    q[P_MU] = math.inf
    return q


@kernel
def family_head(alpha, h, Lz, p, eager):
    """:func:`family` but r_c and the well: a tuple of :data:`HEAD_FIELDS`."""
    M, g, k = p[P_M], p[P_G], p[P_K]
    s = math.sin(alpha)
    c = math.cos(alpha)
    A, B, C = coefficients_sc(s, c, h, Lz, M, g, k)
    Kang = abs(Lz) / (M * s * s)  # K: thetadot = K / r^2
    kk, p0, p2, p3, q0, q3 = friction_terms(s, c, h, Lz, M, g, k)
    rs3 = critical_cube(p0, p2, p3, q0, q3)
    fstar = critical_ratio(p0, p2, p3, q0, q3) if eager and not math.isnan(rs3) else NAN
    kind = 0
    if Lz == 0.0:
        kind = AXIS
    elif not (A >= A_MIN and A < math.inf and abs(B) < math.inf and C < math.inf):
        kind = OUT_OF_RANGE  # r_c and V_min are still reported (minimum_energy)
    return kind, s, c, A, B, C, Kang, kk, p0, p2, p3, q0, q3, rs3, fstar


@kernel
def well_or_nan(A, B, C, rc):
    """:func:`.roots.well`, NaN when there is no r_c."""
    if math.isnan(rc):
        return NAN, NAN, NAN, NAN, NAN
    return well(A, B, C, rc)


@kernel
def family_from(head, rc):
    """:func:`family` from :func:`family_head` and r_c (NaN: none)."""
    kind, s, c, A, B, C, Kang, kk, p0, p2, p3, q0, q3, rs3, fstar = head
    a, vmin, c3, igam, noise = well_or_nan(A, B, C, rc)
    return (kind, s, c, A, B, C, Kang, rc, a, vmin, c3, igam, noise, kk, p0, p2, p3, q0, q3, rs3,
            fstar)  # fmt: skip


@kernel
def family(alpha, h, Lz, p, eager):
    """Everything of the points (alpha, energy, h, L_z) that does not depend on the energy:
    sin and cos of alpha, A, B, C, K = |L_z|/(M sin^2 alpha), r_c, the potential's
    :func:`roots.well` (V_min among it) and the friction terms (:mod:`.ending`). A survey grid
    computes it once per (alpha, h, L_z) for all its energies (``eager``: with |F|/N at the
    interior critical point too); :func:`orbit_in` takes it.

    Returns a tuple of :data:`FAMILY_FIELDS`; kind is AXIS (L_z = 0), OUT_OF_RANGE or 0; NaN
    where undefined.
    """
    head = family_head(alpha, h, Lz, p, eager)
    rc = NAN if Lz == 0.0 else circular_radius(head[FM_A], head[FM_B], head[FM_C])
    return family_from(head, rc)


@kernel
def _mu(fam, r1, r2):
    """mu_required on [r1, r2] from the family's friction terms."""
    return mu_required_of(r1, r2, fam[FM_KK], fam[FM_P0], fam[FM_P2], fam[FM_P3], fam[FM_Q0],
                          fam[FM_Q3], fam[FM_RS3], fam[FM_FSTAR])  # fmt: skip


@kernel
def _turning(fam, energy):
    """Turning points from the family's well (the closed form when C = 0)."""
    A, B, C, rc = fam[FM_A], fam[FM_B], fam[FM_C], fam[FM_RC]
    if C == 0.0:
        return turning_points(energy, A, B, C, rc)
    return turning_points_in(energy, A, B, C, rc, fam[FM_WELL], fam[FM_VMIN], fam[FM_C3],
                             fam[FM_IGAM], fam[FM_NOISE])  # fmt: skip


@kernel
def orbit_in(fam, energy, p, circ_tol):
    """:func:`ideal_orbit` at one energy of a :func:`family`."""
    M, g, k = p[P_M], p[P_G], p[P_K]
    kind, s, A, B, C = fam[FM_KIND], fam[FM_S], fam[FM_A], fam[FM_B], fam[FM_C]
    Kang, rc = fam[FM_K], fam[FM_RC]
    cls = FORBIDDEN
    r1 = r2 = T = psi = prec = mu = NAN
    if kind == AXIS:
        if g > 0.0 and energy > 0.0:
            cls = RADIAL
            r1 = 0.0
            r2 = energy / C
            T = 2.0 * math.sqrt(2.0 * M * r2 / C)
            mu = _mu(fam, 0.0, r2)
        return cls, r1, r2, NAN, T, psi, prec, mu
    if kind == OUT_OF_RANGE:
        return OUT_OF_RANGE, r1, r2, NAN, T, psi, prec, mu
    has_min = not math.isnan(rc)
    if has_min:
        Vmin = fam[FM_VMIN]
        if abs(energy - Vmin) <= circ_tol * fam[FM_NOISE]:  # scaled by the size of V's terms
            omega_r = math.sqrt(2.0 * (A + C * rc * rc * rc) / (M * rc * rc * rc * rc))
            T = 2.0 * math.pi / omega_r
            psi = math.pi * Kang / (rc * rc * omega_r)
            mu = _mu(fam, rc, rc)
            return CIRCULAR, rc, rc, rc, T, psi, precession(psi, T), mu
        if energy < Vmin:
            return FORBIDDEN, r1, r2, rc, T, psi, prec, mu
    if g == 0.0:
        Om = math.sqrt((s * s + k) / (1.0 + k))  # Omega^2 = 1 - cos^2(a)/(1+k)
        if energy >= 0.0 and (B < 0.0 or energy > 0.0):
            cls = HYPERBOLIC
            r1 = free_fall_r_min(energy, A, B)
            r2 = math.inf
            psi = math.atan2(2.0 * math.sqrt(A) * math.sqrt(energy), B) / Om
        elif has_min:
            cls = BOUNDED
            r1, r2 = _turning(fam, energy)
            T = math.pi * (r1 + r2) * math.sqrt(M / (-2.0 * energy))
            psi = math.pi / Om
    else:
        cls = BOUNDED
        r1, r2 = _turning(fam, energy)
        kc, sc = cel_args(A, C, M, r1, r2)
        c1, c2 = cel_pair(kc, 1.0, r1, r2, r2 / r1, 1.0, 1.0)
        T, psi = period_and_angle(sc, c1, c2, Kang, r1)
    if cls != FORBIDDEN:
        mu = _mu(fam, r1, r2)
    if cls == BOUNDED:
        prec = precession(psi, T)
    return cls, r1, r2, rc, T, psi, prec, mu


@kernel
def cel_args(A, C, M, r1, r2):
    """(kc, sqrt(M/(2C)) / sqrt(r1 - r3)) of a bounded orbit under gravity (module docstring)."""
    r3 = -A / (C * r1 * r2)
    d13 = r1 - r3
    return math.sqrt((r2 - r3) / d13), math.sqrt(M / (2.0 * C)) / math.sqrt(d13)


@kernel
def period_and_angle(sc, c1, c2, Kang, r1):
    """(T_r, psi) from :func:`cel_args`'s sc and cel(kc, 1, r1, r2), cel(kc, r2/r1, 1, 1)."""
    return 4.0 * sc * c1, 2.0 * Kang * sc * c2 / r1


@kernel
def precession(psi, T):
    """Apsidal precession rate [rad/s] (2 psi - 2 pi) / T."""
    return (2.0 * psi - 2.0 * math.pi) / T


@kernel
def ideal_orbit(alpha, energy, h, Lz, p, circ_tol):
    """Class and geometry of one orbit on the ideal (infinite, lossless) cone of the scene's
    parameter array ``p`` (:func:`scene_params`; M, g and k are read).

    Returns (orbit_class, r_min [m], r_max [m], r_circ [m], period [s], apsidal_angle [rad],
    precession_rate [rad/s], mu_required [1]); NaN where a quantity is undefined.
    """
    return orbit_in(family(alpha, h, Lz, p, False), energy, p, circ_tol)


@kernel
def representable(cls, r1, r2, T, psi, prec):
    """Whether the numbers the class promises (README class table) came out finite: otherwise
    an intermediate under- or overflowed and the point is OUT_OF_RANGE, never a class with NaN."""
    if cls == BOUNDED or cls == CIRCULAR:
        return (r1 > 0.0 and r2 < math.inf and math.isfinite(T) and math.isfinite(psi)
                and math.isfinite(prec))  # fmt: skip
    if cls == HYPERBOLIC:
        return r1 > 0.0 and r1 < math.inf and math.isfinite(psi)
    if cls == RADIAL:
        return r2 < math.inf and math.isfinite(T)
    return True


@kernel
def scene_end(cls, r1, r2, alpha, energy, h, Lz, p):
    """The scene's rules on an ideal orbit started at r_min: its class on this cone and where
    rolling on it ends (r [m], t [s] and theta [rad] from r_min; NaN if it never ends).

    The rim (``p[P_RIM_SLANT]``) is the real cone's slant length (docs/physics.md "Effects
    beyond the ideal cone"); an orbit that starts beyond it is OFF_CONE, one that reaches it
    SPILLS (every escape does); one where |F|/N first exceeds mu (``p[P_MU]``) before that SLIPS.
    """
    M, g, k, a, rim, mu = p[P_M], p[P_G], p[P_K], p[P_RADIUS], p[P_RIM_SLANT], p[P_MU]
    nan = math.nan
    if not (cls == BOUNDED or cls == CIRCULAR or cls == HYPERBOLIC or cls == RADIAL):
        return cls, nan, nan, nan
    s = math.sin(alpha)
    r_rim = rim_on_centre_cone(rim, a, math.cos(alpha) / s)
    if r1 > r_rim:
        return OFF_CONE, nan, nan, nan
    r_slip = first_slip(r1, r2, alpha, h, Lz, M, g, k, mu)
    if r_slip <= r_rim:
        cls = SLIPS
        r_end = r_slip
    elif r2 > r_rim:
        cls = SPILLS
        r_end = r_rim
    else:
        return cls, nan, nan, nan
    A, B, C = coefficients(alpha, h, Lz, M, g, k)
    t, th = time_and_azimuth(r_end, r1, r2, energy, A, C, M, abs(Lz) / (M * s * s))
    return cls, r_end, t, th


@kernel
def orbit_point(alpha, energy, h, Lz, p, circ_tol):
    """Class and geometry of one orbit on the cone of the scene's parameter array ``p``
    (:func:`scene_params`, ``engine.Scene.params``: M, g, k, a, the rim and mu are read).

    Returns (orbit_class, r_min [m], r_max [m], r_circ [m], period [s], apsidal_angle [rad],
    precession_rate [rad/s], mu_required [1], end_r [m], end_time [s], end_theta [rad]): the
    geometry is the orbit's on the ideal cone; the class and the end apply the scene's rim and
    friction limit (:func:`scene_end`). NaN where a quantity is undefined.
    """
    cls, r1, r2, rc, T, psi, prec, mur = ideal_orbit(alpha, energy, h, Lz, p, circ_tol)
    return scene_point(cls, r1, r2, rc, T, psi, prec, mur, alpha, energy, h, Lz, p)


@kernel
def scene_point(cls, r1, r2, rc, T, psi, prec, mur, alpha, energy, h, Lz, p):
    """:func:`orbit_point` from the ideal orbit: OUT_OF_RANGE where its numbers did not come
    out finite, then the scene's rules (:func:`scene_end`) when a rim or mu is given."""
    if not representable(cls, r1, r2, T, psi, prec):
        nan = math.nan
        return OUT_OF_RANGE, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan
    end_r = math.nan
    end_t = math.nan
    end_th = math.nan
    if p[P_RIM_SLANT] < math.inf or p[P_MU] < math.inf:
        cls, end_r, end_t, end_th = scene_end(cls, r1, r2, alpha, energy, h, Lz, p)
    return cls, r1, r2, rc, T, psi, prec, mur, end_r, end_t, end_th

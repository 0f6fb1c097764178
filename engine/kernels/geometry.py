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
from numba import prange

from .._jit import kernel, parallel_kernel
from .carlson import cel
from .ending import _ratio, first_slip, time_and_azimuth
from .model import coefficients, rim_on_centre_cone
from .roots import circular_radius, free_fall_r_min, turning_points

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
#: Smallest A [J m^2] kept: below it (A underflows towards subnormals) the class is OUT_OF_RANGE.
A_MIN = 2.2250738585072014e-308 / 2.220446049250313e-16

#: Default |energy - V_min| <= CIRCULAR_TOL |V_min| tolerance of the circular class.
CIRCULAR_TOL = 1e-12
NAN = math.nan


@kernel
def mu_required(r1, r2, alpha, h, Lz, M, g, k):
    """Smallest friction coefficient that keeps rolling on [r1, r2] (r2 may be +inf): max |F|/N.

    With x = 1/r and q = L_z/(M sin a):
    |F|/N = k/(1+k) |g cos a + cot a q h x^2 + cot^2 a q^2 x^3| / (g sin a + cot a q^2 x^3),
    whose only interior critical point is x^3 = 2 g sin a / (cot a q^2).
    """
    s = math.sin(alpha)
    c = math.cos(alpha)
    cot = c / s
    q = Lz / (M * s)
    p0 = g * c
    p2 = cot * q * h
    p3 = cot * cot * q * q
    q0 = g * s
    q3 = cot * q * q
    kk = k / (1.0 + k)
    if kk == 0.0:
        return 0.0  # a point particle needs no friction (and 0 * inf would be NaN)
    best = 0.0
    # Endpoints, then the interior critical point.
    for i in range(3):
        if i == 0:
            if math.isinf(r2):
                if q0 > 0.0:
                    val = abs(p0) / q0
                elif p2 == 0.0:
                    val = abs(p3) / q3
                else:
                    val = math.inf
                best = max(best, val)
                continue
            x = 1.0 / r2
        elif i == 1:
            x = 1.0 / r1 if r1 > 0.0 else math.inf
            if math.isinf(x):
                # Through the axis (L_z = 0): q = 0, the ratio is constant.
                best = max(best, abs(p0) / q0)
                continue
        else:
            if q3 <= 0.0 or q0 <= 0.0:
                continue
            x = (2.0 * q0 / q3) ** (1.0 / 3.0)
            xlo = 1.0 / r2 if not math.isinf(r2) else 0.0
            xhi = 1.0 / r1
            if not (xlo < x < xhi):
                continue
        best = max(best, abs(_ratio(x, p0, p2, p3, q0, q3)))
    return kk * best


@kernel
def ideal_orbit(alpha, energy, h, Lz, M, g, k, circ_tol):
    """Class and geometry of one orbit on the ideal (infinite, lossless) cone.

    Returns (orbit_class, r_min [m], r_max [m], r_circ [m], period [s], apsidal_angle [rad],
    precession_rate [rad/s], mu_required [1]); NaN where a quantity is undefined.
    """
    A, B, C = coefficients(alpha, h, Lz, M, g, k)
    cls = FORBIDDEN
    r1 = NAN
    r2 = NAN
    rc = NAN
    T = NAN
    psi = NAN
    prec = NAN
    mu = NAN
    s = math.sin(alpha)
    Kang = abs(Lz) / (M * s * s)  # K: thetadot = K / r^2
    if Lz == 0.0:
        if g > 0.0 and energy > 0.0:
            cls = RADIAL
            r1 = 0.0
            r2 = energy / C
            T = 2.0 * math.sqrt(2.0 * M * r2 / C)
            mu = mu_required(0.0, r2, alpha, h, Lz, M, g, k)
        return cls, r1, r2, rc, T, psi, prec, mu
    if not (A >= A_MIN and A < math.inf and abs(B) < math.inf and C < math.inf):
        return OUT_OF_RANGE, r1, r2, rc, T, psi, prec, mu
    rc = circular_radius(A, B, C)
    has_min = not math.isnan(rc)
    if has_min:
        Vmin = A / (rc * rc) + B / rc + C * rc
        if abs(energy - Vmin) <= circ_tol * abs(Vmin):
            omega_r = math.sqrt(2.0 * (A + C * rc * rc * rc) / (M * rc * rc * rc * rc))
            T = 2.0 * math.pi / omega_r
            psi = math.pi * Kang / (rc * rc * omega_r)
            mu = mu_required(rc, rc, alpha, h, Lz, M, g, k)
            return CIRCULAR, rc, rc, rc, T, psi, (2.0 * psi - 2.0 * math.pi) / T, mu
        if energy < Vmin:
            return FORBIDDEN, r1, r2, rc, T, psi, prec, mu
    Om = math.sqrt((s * s + k) / (1.0 + k))  # Omega^2 = 1 - cos^2(a)/(1+k)
    if g == 0.0:
        if energy >= 0.0 and (B < 0.0 or energy > 0.0):
            cls = HYPERBOLIC
            r1 = free_fall_r_min(energy, A, B)
            r2 = math.inf
            psi = math.atan2(2.0 * math.sqrt(A) * math.sqrt(energy), B) / Om
        elif has_min:
            cls = BOUNDED
            r1, r2 = turning_points(energy, A, B, C, rc)
            T = math.pi * (r1 + r2) * math.sqrt(M / (-2.0 * energy))
            psi = math.pi / Om
    else:
        cls = BOUNDED
        r1, r2 = turning_points(energy, A, B, C, rc)
        r3 = -A / (C * r1 * r2)
        d13 = r1 - r3
        kc = math.sqrt((r2 - r3) / d13)
        sc = math.sqrt(M / (2.0 * C)) / math.sqrt(d13)
        T = 4.0 * sc * cel(kc, 1.0, r1, r2)
        psi = 2.0 * Kang * sc * cel(kc, r2 / r1, 1.0, 1.0) / r1
    if cls != FORBIDDEN:
        mu = mu_required(r1, r2, alpha, h, Lz, M, g, k)
    if cls == BOUNDED:
        prec = (2.0 * psi - 2.0 * math.pi) / T
    return cls, r1, r2, rc, T, psi, prec, mu


@kernel
def _representable(cls, r1, r2, T, psi, prec):
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
def scene_end(cls, r1, r2, alpha, energy, h, Lz, M, g, k, a, rim, mu):
    """The scene's rules on an ideal orbit started at r_min: its class on this cone and where
    rolling on it ends (r [m], t [s] and theta [rad] from r_min; NaN if it never ends).

    ``rim`` is the real cone's slant length (docs/physics.md "Effects beyond the ideal cone");
    an orbit that starts beyond it is OFF_CONE, one that reaches it SPILLS (every escape does);
    one where |F|/N first exceeds ``mu`` before that SLIPS.
    """
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
def orbit_point(alpha, energy, h, Lz, M, g, k, a, rim, mu, circ_tol):
    """Class and geometry of one orbit on the scene's cone.

    Returns (orbit_class, r_min [m], r_max [m], r_circ [m], period [s], apsidal_angle [rad],
    precession_rate [rad/s], mu_required [1], end_r [m], end_time [s], end_theta [rad]): the
    geometry is the orbit's on the ideal cone; the class and the end apply the scene's rim and
    friction limit (:func:`scene_end`). NaN where a quantity is undefined.
    """
    cls, r1, r2, rc, T, psi, prec, mur = ideal_orbit(alpha, energy, h, Lz, M, g, k, circ_tol)
    if not _representable(cls, r1, r2, T, psi, prec):
        nan = math.nan
        return OUT_OF_RANGE, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan
    end_r = math.nan
    end_t = math.nan
    end_th = math.nan
    if rim < math.inf or mu < math.inf:
        cls, end_r, end_t, end_th = scene_end(cls, r1, r2, alpha, energy, h, Lz, M, g, k, a, rim,
                                              mu)  # fmt: skip
    return cls, r1, r2, rc, T, psi, prec, mur, end_r, end_t, end_th


#: Rows of the float output of :func:`orbit_batch`.
BATCH_ROWS = (
    "r_min",
    "r_max",
    "r_circ",
    "period",
    "apsidal_angle",
    "precession_rate",
    "mu_required",
    "end_r",
    "end_time",
    "end_theta",
)


@parallel_kernel
def orbit_batch(alpha, energy, h, Lz, M, g, k, a, rim, mu, circ_tol, out_cls, out_f):
    """:func:`orbit_point` over 1-D arrays in parallel: ``out_cls`` int8[n], ``out_f``
    float64[10, n] (rows :data:`BATCH_ROWS`)."""
    n = alpha.shape[0]
    for i in prange(n):
        c, r1, r2, rc, T, psi, prec, mur, er, et, eth = orbit_point(
            alpha[i], energy[i], h[i], Lz[i], M, g, k, a, rim, mu, circ_tol
        )
        out_cls[i] = c
        out_f[0, i] = r1
        out_f[1, i] = r2
        out_f[2, i] = rc
        out_f[3, i] = T
        out_f[4, i] = psi
        out_f[5, i] = prec
        out_f[6, i] = mur
        out_f[7, i] = er
        out_f[8, i] = et
        out_f[9, i] = eth


@parallel_kernel
def minimum_energy_batch(alpha, h, Lz, M, g, k, out):
    """V_min [J] for each (alpha, h, Lz); NaN where V has no minimum."""
    n = alpha.shape[0]
    for i in prange(n):
        A, B, C = coefficients(alpha[i], h[i], Lz[i], M, g, k)
        if Lz[i] == 0.0:
            out[i] = NAN
            continue
        rc = circular_radius(A, B, C)
        out[i] = A / (rc * rc) + B / rc + C * rc


def empty_outputs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Output buffers for :func:`orbit_batch`."""
    return np.empty(n, np.int8), np.empty((len(BATCH_ROWS), n), np.float64)

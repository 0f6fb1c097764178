"""Where and when a conservative orbit stops rolling on the scene's cone, in closed form.

An orbit of the ideal cone (started at r_min, moving outward) ends where rolling first fails
(the smallest r with |F|/N > mu) or where it reaches the rim. :func:`first_slip` finds that
radius from the shape of |F|/N in x = 1/r (a ratio of cubics with one interior critical point,
docs/physics.md "Contact forces"); :func:`time_and_azimuth` integrates dt and dtheta from r_min
to a radius by adaptive Gauss-Kronrod (G7-K15) quadrature on a substitution that removes the
turning point's square-root singularity:

- orbits with two turning points: r = r1 + (r2 - r1) sin^2(x), dt = 2 r dx / sqrt((2/M) Q(r)),
  Q = C (r - r3) under gravity, |calE| in free fall;
- escapes (free fall): r = r1 + x^2, the same dt with Q = calE r + A / r1;

and dtheta = K dt / r^2 with K = |L_z| / (M sin^2 alpha). Every Q is positive: no cancellation.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel

# Gauss-Kronrod 15-point nodes and weights (QUADPACK qk15) on [-1, 1].
_XGK = np.array(
    [
        0.991455371120812639206854697526329,
        0.949107912342758524526189684047851,
        0.864864423359769072789712788640926,
        0.741531185599394439863864773280788,
        0.586087235467691130294144845693013,
        0.405845151377397166906606412076961,
        0.207784955007898467600689403773245,
        0.0,
    ]
)
_WGK = np.array(
    [
        0.022935322010529224963732008058970,
        0.063092092629978553290700663189204,
        0.104790010322250183839876322541518,
        0.140653259715525918745189590510238,
        0.169004726639267902826583426598550,
        0.190350578064785409913256402421014,
        0.204432940075298892414161999234649,
        0.209482141084727828012999174891714,
    ]
)
_WG = np.array(
    [
        0.129484966168869693270611432679082,
        0.279705391489276667901467771423780,
        0.381830050505118944950369775488975,
        0.417959183673469387755102040816327,
    ]
)
#: Relative accuracy asked of the quadrature, and its budget of subintervals.
QUAD_RTOL = 1e-14
QUAD_INTERVALS = 200

# Substitutions.
SUB_SINE = 0  # r = r1 + d sin^2 x
SUB_SQUARE = 1  # r = r1 + x^2


@kernel
def _integrands(x, sub, r1, d, q0, q1, M, K):
    """(dt/dx, dtheta/dx) at x, with Q(r) = q0 + q1 r."""
    if sub == SUB_SINE:
        s = math.sin(x)
        r = r1 + d * s * s
    else:
        r = r1 + x * x
    dt = 2.0 * r / math.sqrt((2.0 / M) * (q0 + q1 * r))
    return dt, K * dt / (r * r)


@kernel
def _gk15(a, b, sub, r1, d, q0, q1, M, K):
    """Kronrod estimates of both integrals on [a, b] and their error estimates."""
    c = 0.5 * (a + b)
    hl = 0.5 * (b - a)
    ft, fth = _integrands(c, sub, r1, d, q0, q1, M, K)
    kt = _WGK[7] * ft
    kth = _WGK[7] * fth
    gt = _WG[3] * ft
    gth = _WG[3] * fth
    for j in range(7):
        dx = hl * _XGK[j]
        f1t, f1th = _integrands(c - dx, sub, r1, d, q0, q1, M, K)
        f2t, f2th = _integrands(c + dx, sub, r1, d, q0, q1, M, K)
        kt += _WGK[j] * (f1t + f2t)
        kth += _WGK[j] * (f1th + f2th)
        if j % 2 == 1:
            gt += _WG[j // 2] * (f1t + f2t)
            gth += _WG[j // 2] * (f1th + f2th)
    return kt * hl, kth * hl, abs((kt - gt) * hl), abs((kth - gth) * hl)


@kernel
def integrate_to(x_end, sub, r1, d, q0, q1, M, K):
    """(t, theta) = the integrals over [0, x_end], globally adaptive (bisect the interval with
    the largest error until both errors are below QUAD_RTOL relative)."""
    lo = np.empty(QUAD_INTERVALS)
    hi = np.empty(QUAD_INTERVALS)
    vt = np.empty(QUAD_INTERVALS)
    vth = np.empty(QUAD_INTERVALS)
    et = np.empty(QUAD_INTERVALS)
    eth = np.empty(QUAD_INTERVALS)
    lo[0] = 0.0
    hi[0] = x_end
    vt[0], vth[0], et[0], eth[0] = _gk15(0.0, x_end, sub, r1, d, q0, q1, M, K)
    m = 1
    while m < QUAD_INTERVALS:
        tot_t = 0.0
        tot_th = 0.0
        err_t = 0.0
        err_th = 0.0
        worst = 0
        worst_e = -1.0
        for i in range(m):
            tot_t += vt[i]
            tot_th += vth[i]
            err_t += et[i]
            err_th += eth[i]
            e = et[i] / max(abs(vt[i]), 1e-300) + eth[i] / max(abs(vth[i]), 1e-300)
            if e > worst_e:
                worst_e = e
                worst = i
        if err_t <= QUAD_RTOL * abs(tot_t) and err_th <= QUAD_RTOL * abs(tot_th):
            return tot_t, tot_th
        a = lo[worst]
        b = hi[worst]
        mid = 0.5 * (a + b)
        hi[worst] = mid
        vt[worst], vth[worst], et[worst], eth[worst] = _gk15(a, mid, sub, r1, d, q0, q1, M, K)
        lo[m] = mid
        hi[m] = b
        vt[m], vth[m], et[m], eth[m] = _gk15(mid, b, sub, r1, d, q0, q1, M, K)
        m += 1
    return vt[:m].sum(), vth[:m].sum()


@kernel
def time_and_azimuth(r_end, r1, r2, energy, A, C, M, K):
    """(t [s], theta [rad]) from r1 (r_min) outward to r_end on the orbit (module docstring).
    r2 = inf for an escape; r1 = 0 for a radial orbit (theta stays 0)."""
    if r_end <= r1:
        return 0.0, 0.0
    if r1 == 0.0:  # radial: calE - V = calE - C r
        t = math.sqrt(2.0 * M) / C * (math.sqrt(energy) - math.sqrt(max(energy - C * r_end, 0.0)))
        return t, 0.0
    if math.isinf(r2):
        return integrate_to(math.sqrt(r_end - r1), SUB_SQUARE, r1, 0.0, A / r1, energy, M, K)
    d = r2 - r1
    x_end = math.asin(math.sqrt(min((r_end - r1) / d, 1.0)))
    if C > 0.0:
        r3 = -A / (C * r1 * r2)
        return integrate_to(x_end, SUB_SINE, r1, d, -C * r3, C, M, K)
    return integrate_to(x_end, SUB_SINE, r1, d, abs(energy), 0.0, M, K)


# ------------------------------------------------------------------------------ the slip radius
@kernel
def _ratio(x, p0, p2, p3, q0, q3):
    """(p0 + p2 x^2 + p3 x^3) / (q0 + q3 x^3), scaled for large x (no overflow of x^3); its
    limit at x = 0 in free fall (q0 = 0)."""
    if x == 0.0 and q0 == 0.0:
        return math.copysign(math.inf, p2 * q3) if p2 != 0.0 else p3 / q3
    if p0 == 0.0 and q0 == 0.0:  # free fall: divide x^3 out (it underflows for r > 1e103)
        return (p2 / x + p3) / q3
    if x <= 1.0:
        x2 = x * x
        return (p0 + p2 * x2 + p3 * x2 * x) / (q0 + q3 * x2 * x)
    y = 1.0 / x
    y3 = y * y * y
    return (p0 * y3 + p2 * y + p3) / (q0 * y3 + q3)


@kernel
def _level_crossing(a, b, level, p0, p2, p3, q0, q3):
    """x in [a, b] where the monotone ratio equals ``level`` (bisection with secant steps in
    log x when the bracket spans decades)."""
    fa = _ratio(a, p0, p2, p3, q0, q3) - level
    for _ in range(200):
        if a > 0.0 and b > 4.0 * a:
            x = math.sqrt(a * b)
        else:
            x = 0.5 * (a + b)
        if not (a < x < b):
            break
        fx = _ratio(x, p0, p2, p3, q0, q3) - level
        if (fx > 0.0) == (fa > 0.0):
            a = x
            fa = fx
        else:
            b = x
    return 0.5 * (a + b)


@kernel
def first_slip(r1, r2, alpha, h, Lz, M, g, k, mu):
    """The smallest radius in [r1, r2] (r2 may be inf) where |F|/N > mu, or NaN if rolling
    never fails. |F|/N = k/(1+k) |f(x)|, f = (p0 + p2 x^2 + p3 x^3)/(q0 + q3 x^3), x = 1/r, is
    monotone on either side of x* = (2 q0/q3)^(1/3) (constant = cot(alpha) when p2 = 0)."""
    kk = k / (1.0 + k)
    if kk == 0.0 or not mu < math.inf:
        return math.nan
    s = math.sin(alpha)
    c = math.cos(alpha)
    cot = c / s
    q = Lz / (M * s)
    p0 = g * c
    p2 = cot * q * h
    p3 = cot * cot * q * q
    q0 = g * s
    q3 = cot * q * q
    m = mu / kk
    if r1 == 0.0 or q3 == 0.0:  # through the axis, or free of the x terms: a constant ratio
        return r1 if abs(p0 / q0) > m else math.nan
    xhi = 1.0 / r1
    xlo = 0.0 if math.isinf(r2) else 1.0 / r2
    if abs(_ratio(xhi, p0, p2, p3, q0, q3)) > m:
        return r1
    xs = (2.0 * q0 / q3) ** (1.0 / 3.0) if q0 > 0.0 else math.inf
    b = xhi
    for piece in range(2):
        a = max(xs, xlo) if (piece == 0 and xlo < xs < xhi) else xlo
        if a >= b:
            continue
        fa = _ratio(a, p0, p2, p3, q0, q3)
        if fa > m:
            return 1.0 / _level_crossing(a, b, m, p0, p2, p3, q0, q3)
        if fa < -m:
            return 1.0 / _level_crossing(a, b, -m, p0, p2, p3, q0, q3)
        b = a
    return math.nan

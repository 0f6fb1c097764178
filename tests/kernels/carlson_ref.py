"""Carlson's symmetric elliptic integrals R_C, R_F, R_D, R_J (real arguments), in numba: the
tests' second evaluation of the closed form (the package computes it with Bulirsch's cel,
:mod:`engine.kernels.carlson`).

Duplication algorithms of B. C. Carlson, "Numerical computation of real or complex elliptic
integrals", Numer. Algorithms 10 (1995) 13-26, with the fifth-order series at the end. With
``TOL`` = 2^-53 the truncation error is below ~2e-16 relative, so the result carries the
rounding error of a few operations (measured against mpmath in test_carlson.py).
Arguments: x, y, z >= 0, at most one of them zero; p > 0.
"""

from __future__ import annotations

import math

import numba

kernel = numba.njit(cache=True, error_model="numpy")

#: Relative tolerance r of Carlson (1995); the series error is O(r).
TOL = 2.0**-53
_QF = (3.0 * TOL) ** (-1.0 / 6.0)  # R_F
_QDJ = (TOL / 4.0) ** (-1.0 / 6.0)  # R_D, R_J
_MAX_ITER = 60


@kernel
def rc_one(e, onepe):
    """R_C(1, 1 + e) for e > -1, given e and onepe = 1 + e (both accurate).

    atan(sqrt e)/sqrt e for e > 0; atanh(s)/s = log((1 + s)/sqrt(1 + e))/s, s = sqrt(-e),
    for e < 0 (the log form keeps its digits as e -> -1).
    """
    if e > 0.0:
        s = math.sqrt(e)
        return math.atan(s) / s
    if e < 0.0:
        s = math.sqrt(-e)
        if s < 0.5:
            return math.atanh(s) / s
        return math.log((1.0 + s) / math.sqrt(onepe)) / s
    return 1.0


@kernel
def rc(x, y):
    """Degenerate integral R_C(x, y) = R_F(x, y, y), x >= 0, y > 0."""
    if x > 0.0:
        return rc_one((y - x) / x, y / x) / math.sqrt(x)
    return math.pi / (2.0 * math.sqrt(y))


@kernel
def rf(x, y, z):
    """R_F(x, y, z) = 1/2 int_0^inf dt / sqrt((t+x)(t+y)(t+z))."""
    a0 = (x + y + z) / 3.0
    q = _QF * max(abs(a0 - x), abs(a0 - y), abs(a0 - z))
    a = a0
    f = 1.0
    for _ in range(_MAX_ITER):
        if q * f < abs(a):
            break
        sx = math.sqrt(x)
        sy = math.sqrt(y)
        sz = math.sqrt(z)
        lam = sx * sy + sx * sz + sy * sz
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        a = 0.25 * (a + lam)
        f *= 0.25
    # (a0 - x0) 4^-m = a_m - x_m in exact arithmetic; the iterates avoid the rescaling.
    X = (a - x) / a
    Y = (a - y) / a
    Z = -X - Y
    e2 = X * Y - Z * Z
    e3 = X * Y * Z
    return (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0) / math.sqrt(a)


@kernel
def rd(x, y, z):
    """R_D(x, y, z) = 3/2 int_0^inf dt / ((t+z) sqrt((t+x)(t+y)(t+z))), z > 0."""
    a0 = (x + y + 3.0 * z) / 5.0
    q = _QDJ * max(abs(a0 - x), abs(a0 - y), abs(a0 - z))
    a = a0
    f = 1.0
    s = 0.0
    for _ in range(_MAX_ITER):
        if q * f < abs(a):
            break
        sx = math.sqrt(x)
        sy = math.sqrt(y)
        sz = math.sqrt(z)
        lam = sx * sy + sx * sz + sy * sz
        s += f / (sz * (z + lam))
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        a = 0.25 * (a + lam)
        f *= 0.25
    X = (a - x) / a
    Y = (a - y) / a
    Z = -(X + Y) / 3.0
    xy = X * Y
    zz = Z * Z
    e2 = xy - 6.0 * zz
    e3 = (3.0 * xy - 8.0 * zz) * Z
    e4 = 3.0 * (xy - zz) * zz
    e5 = xy * zz * Z
    series = (
        1.0
        - 3.0 * e2 / 14.0
        + e3 / 6.0
        + 9.0 * e2 * e2 / 88.0
        - 3.0 * e4 / 22.0
        - 9.0 * e2 * e3 / 52.0
        + 3.0 * e5 / 26.0
    )
    return f * series / (a * math.sqrt(a)) + 3.0 * s


@kernel
def rj(x, y, z, p):
    """R_J(x, y, z, p) = 3/2 int_0^inf dt / ((t+p) sqrt((t+x)(t+y)(t+z))), p > 0."""
    a0 = (x + y + z + 2.0 * p) / 5.0
    delta = (p - x) * (p - y) * (p - z)
    q = _QDJ * max(abs(a0 - x), abs(a0 - y), abs(a0 - z), abs(a0 - p))
    a = a0
    f = 1.0
    f3 = 1.0  # 4^-3m
    s = 0.0
    for _ in range(_MAX_ITER):
        if q * f < abs(a):
            break
        sx = math.sqrt(x)
        sy = math.sqrt(y)
        sz = math.sqrt(z)
        sp = math.sqrt(p)
        lam = sx * sy + sx * sz + sy * sz
        d = (sp + sx) * (sp + sy) * (sp + sz)
        e = f3 * delta / (d * d)
        # 1 + e = 2 sqrt(p) (p + lam) / d exactly: no cancellation as e -> -1.
        s += f * rc_one(e, 2.0 * sp * (p + lam) / d) / d
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        p = 0.25 * (p + lam)
        a = 0.25 * (a + lam)
        f *= 0.25
        f3 *= 0.015625
    X = (a - x) / a
    Y = (a - y) / a
    Z = (a - z) / a
    P = -(X + Y + Z) / 2.0
    pp = P * P
    e2 = X * Y + X * Z + Y * Z - 3.0 * pp
    e3 = X * Y * Z + 2.0 * e2 * P + 4.0 * pp * P
    e4 = (2.0 * X * Y * Z + e2 * P + 3.0 * pp * P) * P
    e5 = X * Y * Z * pp
    series = (
        1.0
        - 3.0 * e2 / 14.0
        + e3 / 6.0
        + 9.0 * e2 * e2 / 88.0
        - 3.0 * e4 / 22.0
        - 9.0 * e2 * e3 / 52.0
        + 3.0 * e5 / 26.0
    )
    return f * series / (a * math.sqrt(a)) + 6.0 * s

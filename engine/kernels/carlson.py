"""Carlson's symmetric elliptic integrals R_C, R_F, R_D, R_J (real arguments), in numba.

Duplication algorithms of B. C. Carlson, "Numerical computation of real or complex elliptic
integrals", Numer. Algorithms 10 (1995) 13-26, with the fifth-order series at the end. With
``TOL`` = 2^-53 the truncation error is below ~2e-16 relative, so the result carries the
rounding error of a few operations (measured against mpmath in tests/test_carlson.py).
Arguments: x, y, z >= 0, at most one of them zero; p > 0.

Also Bulirsch's general complete integral :func:`cel`, which gives the complete integrals of
the hot path in one quadratically convergent loop (~50 ns, 4x fewer than R_F + R_D + R_J).
"""

from __future__ import annotations

import math

from .._jit import kernel

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


#: cel stops when the AGM-like sequence agrees to CEL_TOL; its error is then ~CEL_TOL^2.
CEL_TOL = 2.0**-26


@kernel
def cel(kc, p, a, b):
    """Bulirsch's complete elliptic integral, p > 0, kc != 0:

    cel(kc, p, a, b) = int_0^{pi/2} (a cos^2 t + b sin^2 t) dt
                       / ((cos^2 t + p sin^2 t) sqrt(cos^2 t + kc^2 sin^2 t)).

    R. Bulirsch, Numer. Math. 13 (1969) 305-315. K(m) = cel(sqrt(1-m), 1, 1, 1),
    Pi(n|m) = cel(sqrt(1-m), 1-n, 1, 1).
    """
    qc = abs(kc)
    e = qc
    em = 1.0
    p = math.sqrt(p)
    b /= p
    for _ in range(_MAX_ITER):
        f = a
        a += b / p
        g = e / p
        b += f * g
        b += b
        p = g + p
        g = em
        em += qc
        if abs(g - qc) <= g * CEL_TOL:
            break
        qc = math.sqrt(e)
        qc += qc
        e = qc * em
    return 0.5 * math.pi * (b + a * em) / (em * (em + p))


@kernel
def cel_pair(kc, p1, a1, b1, p2, a2, b2):
    """(cel(kc, p1, a1, b1), cel(kc, p2, a2, b2)) in one loop: the AGM-like sequence of kc is
    shared, the two recurrences in p, a, b run side by side (bit-identical to two calls of
    :func:`cel`, at about the cost of one)."""
    qc = abs(kc)
    e = qc
    em = 1.0
    p1 = math.sqrt(p1)
    b1 /= p1
    p2 = math.sqrt(p2)
    b2 /= p2
    for _ in range(_MAX_ITER):
        f1 = a1
        f2 = a2
        a1 += b1 / p1
        a2 += b2 / p2
        g1 = e / p1
        g2 = e / p2
        b1 += f1 * g1
        b2 += f2 * g2
        b1 += b1
        b2 += b2
        p1 = g1 + p1
        p2 = g2 + p2
        g = em
        em += qc
        if abs(g - qc) <= g * CEL_TOL:
            break
        qc = math.sqrt(e)
        qc += qc
        e = qc * em
    h = 0.5 * math.pi
    return h * (b1 + a1 * em) / (em * (em + p1)), h * (b2 + a2 * em) / (em * (em + p2))


@kernel
def cel_pair_lanes(m, kc, p1, a1, b1, p2, a2, b2, st, out1, out2):
    """:func:`cel_pair` for lanes 0..m-1 of the arrays, in lock-step: each step runs over all
    lanes, a lane that has converged keeps its values (selects, no branch on which has), so
    the lanes' chains overlap. Bit-identical to :func:`cel_pair` per lane. ``p*``, ``a*``,
    ``b*`` are overwritten; ``st`` is float64[4, >= m] scratch."""
    qc, e, em, act = st[0], st[1], st[2], st[3]
    for j in range(m):
        qc[j] = abs(kc[j])
        e[j] = qc[j]
        em[j] = 1.0
        act[j] = 1.0
        p1[j] = math.sqrt(p1[j])
        b1[j] /= p1[j]
        p2[j] = math.sqrt(p2[j])
        b2[j] /= p2[j]
    for _ in range(_MAX_ITER):
        left = 0.0
        for j in range(m):
            on = act[j] != 0.0
            f1 = a1[j]
            f2 = a2[j]
            na1 = f1 + b1[j] / p1[j]
            na2 = f2 + b2[j] / p2[j]
            g1 = e[j] / p1[j]
            g2 = e[j] / p2[j]
            nb1 = b1[j] + f1 * g1
            nb2 = b2[j] + f2 * g2
            nb1 += nb1
            nb2 += nb2
            g = em[j]
            nem = g + qc[j]
            a1[j] = na1 if on else f1
            a2[j] = na2 if on else f2
            b1[j] = nb1 if on else b1[j]
            b2[j] = nb2 if on else b2[j]
            p1[j] = g1 + p1[j] if on else p1[j]
            p2[j] = g2 + p2[j] if on else p2[j]
            em[j] = nem if on else g
            going = on and not abs(g - qc[j]) <= g * CEL_TOL
            nqc = math.sqrt(e[j])
            nqc += nqc
            qc[j] = nqc if going else qc[j]
            e[j] = nqc * nem if going else e[j]
            act[j] = 1.0 if going else 0.0
            left += act[j]
        if left == 0.0:
            break
    h = 0.5 * math.pi
    for j in range(m):
        out1[j] = h * (b1[j] + a1[j] * em[j]) / (em[j] * (em[j] + p1[j]))
        out2[j] = h * (b2[j] + a2[j] * em[j]) / (em[j] * (em[j] + p2[j]))

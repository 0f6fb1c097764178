"""Bulirsch's general complete elliptic integral :func:`cel`, which gives the complete integrals
of the hot path in one quadratically convergent loop (~50 ns, 4x fewer than Carlson's
R_F + R_D + R_J), two at once (:func:`cel_pair`) and over lanes (:func:`cel_pair_lanes`).

Carlson's R_C, R_F, R_D, R_J, the tests' second evaluation of the closed form, are in
``tests/kernels/carlson_ref.py``.
"""

from __future__ import annotations

import math

from .._jit import kernel

_MAX_ITER = 60


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

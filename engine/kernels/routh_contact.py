"""The contact along an exact orbit: whether the ball stays on the surface (Routh's reduction,
:mod:`.routh`).

Rolling on the inside of a surface of revolution needs the normal force

    N / M = g cos(b) + sin(b) v^2 / rho + kappa u^2     (v = L / rho, u^2 = F(q) = e - U(q))

(:mod:`.surface`) to stay positive. Where the meridian curves away from the ball (kappa < 0: a
funnel, a convex stretch of a profile) a fast enough ball along the meridian leaves the surface,
and its orbit of the reduction, which assumes the contact, is not what happens: the exact map
calls it ``lifts_off``, as the integrators end such a run ``lifted_off``. Only a table whose
meridian can lose the contact (``MAY_LIFT``) is scanned: elsewhere N >= M g cos(b) > 0.

A bounded orbit's quadrature (:mod:`.routh_quad`) has N/M at its nodes already (dense where F
is resolved to 1e-7, and N is made of the same smooth functions): only where the smallest of
them is within :data:`NEAR` of the size of its terms (they nearly cancel) is the orbit scanned
(:func:`lifts_at_nodes`); a narrow orbit is looked at in the middle of its well and at its turning
points first (:func:`lifts_in_well`). The scan (:func:`lifts_between`, also every orbit that
escapes) samples N/M over the q the orbit visits, at :data:`SAMPLES` Chebyshev-Lobatto points
(clustered at the ends: the turning points, where F = 0 and the curvature term vanishes), then
narrows the smallest sample by golden section between its neighbours: N along an orbit is
smooth, its minimum where the two terms balance.
"""

from __future__ import annotations

import math

from .._jit import kernel
from .layouts import P_RADIUS
from .routh import MAY_LIFT, radial_f

#: Where the smallest N/M seen is within this share of its terms' size, the orbit is scanned.
NEAR = 0.1
#: Samples of N over the orbit's range of q.
SAMPLES = 33
#: Golden-section steps that narrow the smallest sample (0.618^24 of two sample spacings).
NARROWING = 24
_GOLD = 0.6180339887498949


@kernel
def normal_per_mass(p, edges, coef, meta, c1, c2, e0, q):
    """N / M [m/s^2] of the orbit (constants c1, c2, energy e0) at q (module docstring)."""
    return radial_f(p, edges, coef, meta, c1, c2, e0, q)[6]


@kernel
def _at(qa, qb, scale, x):
    """q of x in [0, 1] on [qa, qb] (Chebyshev-Lobatto spacing); on [qa, inf) the map
    qa + scale x/(1-x), x < 1."""
    if math.isfinite(qb):
        return qa + (qb - qa) * 0.5 * (1.0 - math.cos(math.pi * x))
    return qa + scale * x / (1.0 - x)


@kernel
def lifts_between(p, edges, coef, meta, c1, c2, e0, qa, qb):
    """Whether the normal force of the orbit falls below zero anywhere on [qa, qb] (qb
    may be inf: the far field, where N -> M g cos(b), is not sampled). False at once where the
    table's surface cannot lose the contact."""
    if meta[MAY_LIFT] == 0.0 or not (qa <= qb) or not math.isfinite(qa):
        return False
    scale = max(abs(qa), p[P_RADIUS])
    last = SAMPLES - 1 if math.isfinite(qb) else SAMPLES - 2
    j_min = 0
    n_min = math.inf
    for j in range(last + 1):
        n = normal_per_mass(p, edges, coef, meta, c1, c2, e0, _at(qa, qb, scale, j / (SAMPLES - 1)))
        if n < 0.0:
            return True
        if n < n_min:
            n_min = n
            j_min = j
    lo = max(j_min - 1, 0) / (SAMPLES - 1)
    hi = min(j_min + 1, last) / (SAMPLES - 1)
    x1 = hi - _GOLD * (hi - lo)
    x2 = lo + _GOLD * (hi - lo)
    f1 = normal_per_mass(p, edges, coef, meta, c1, c2, e0, _at(qa, qb, scale, x1))
    f2 = normal_per_mass(p, edges, coef, meta, c1, c2, e0, _at(qa, qb, scale, x2))
    for _ in range(NARROWING):
        if min(f1, f2) < 0.0:
            return True
        if f1 < f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - _GOLD * (hi - lo)
            f1 = normal_per_mass(p, edges, coef, meta, c1, c2, e0, _at(qa, qb, scale, x1))
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + _GOLD * (hi - lo)
            f2 = normal_per_mass(p, edges, coef, meta, c1, c2, e0, _at(qa, qb, scale, x2))
    return min(f1, f2) < 0.0


@kernel
def lifts_at_nodes(p, edges, coef, meta, c1, c2, e0, q1, q2, n_min, n_size):
    """Whether the bounded orbit between q1 and q2 loses its contact, from the smallest N/M at
    its quadrature's nodes (``n_min``, its terms' size ``n_size``): at once where it is < 0,
    by :func:`lifts_between` where it is within :data:`NEAR` of its terms' size."""
    if meta[MAY_LIFT] == 0.0:
        return False
    if n_min < 0.0:
        return True
    return n_min <= NEAR * n_size and lifts_between(p, edges, coef, meta, c1, c2, e0, q1, q2)


@kernel
def lifts_in_well(p, edges, coef, meta, c1, c2, e0, q1, qc, q2):
    """Whether a narrow orbit (turning points q1, q2, the well's centre qc) loses its contact:
    N/M at the three, and :func:`lifts_between` where the smallest is near zero (:data:`NEAR`)."""
    if meta[MAY_LIFT] == 0.0:
        return False
    n_min, n_size = math.inf, 0.0
    for q in (q1, qc, q2):
        r = radial_f(p, edges, coef, meta, c1, c2, e0, q)
        if r[6] < n_min:
            n_min, n_size = r[6], r[7]
    if n_min < 0.0:
        return True
    return n_min <= NEAR * n_size and lifts_between(p, edges, coef, meta, c1, c2, e0, q1, q2)

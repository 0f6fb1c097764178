"""The integrals of Routh's radial problem (:mod:`.routh`) between an orbit's turning points
q1 < q2: the radial period T = 2 int sigma dq/sqrt(F) (pericentre to pericentre) and the
apsidal angle psi = |int (L/rho^2) sigma dq/sqrt(F)| (pericentre to apocentre; L may change
sign along a curved meridian).

With q = m - h cos t (or, for an eccentric orbit, log(q - q_axis) = m - h cos t) F = O(t^2) at
the ends: the integrands are smooth, even and 2 pi-periodic in t, and the trapezoidal rule
converges geometrically, each doubling of the nodes squaring its error; n doubles from 4 until
two rules agree to :data:`QUAD_TOL` (the finer one then to about its square, 1e-14). At the ends the
integrand is its limit sigma sqrt(2 J / |dF/dq|) (dq/dt = J sin t). A narrow orbit is
integrated in its well's variable (:mod:`.routh_well`). A radial orbit (through the axis,
where the potential may have a kink: the cone's vertex) by Gauss-Legendre in v, q = q2 -
(q2 - q_axis) v^2.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .routh import Q_AXIS, radial_f
from .routh_well import value

#: Two trapezoidal rules agree to this (relative) when the quadrature stops.
QUAD_TOL = 1e-7
#: Most nodes of the quadrature (then it stops, at its best estimate).
N_MAX = 8192
#: Gauss-Legendre rules of 2 N_GL, 4 N_GL, 8 N_GL points on [-1, 1]: their positive halves,
#: rows padded with points of weight 0.
N_GL = 16
_GL_X = np.full((3, 4 * N_GL), 0.5)
_GL_W = np.zeros((3, 4 * N_GL))
for _m in range(3):
    _x, _w = np.polynomial.legendre.leggauss(2 * N_GL * 2**_m)
    _GL_X[_m, : N_GL * 2**_m], _GL_W[_m, : N_GL * 2**_m] = _x[_x > 0], _w[_x > 0]


@kernel
def _at(p, edges, coef, meta, c1, c2, e0, q, wm):
    """(F, dF/dq, ds/dq, L/rho^2, N/M, its terms' size) at q; where ``wm`` holds a well
    (:mod:`.routh_well`) q is its variable x = (q - q_c)/hw (the orbit's nodes keep every digit
    of its width, which q itself, rounded to eps q, would not) and F comes from the well's
    series (N/M not computed: inf)."""
    H, g, S, R, qc, hw, delta = wm
    if H.shape[0] > 0:
        sig = hw * value(S, q)
        return delta - value(H, q), -sig * value(g, q), sig, value(R, q), math.inf, 0.0
    F, Fq, sig, lr2, rho, z, nm, ns = radial_f(p, edges, coef, meta, c1, c2, e0, q)
    return F, Fq, sig, lr2, nm, ns


@kernel
def _node(p, edges, coef, meta, c1, c2, e0, q, jac, fa, fb, q1, q2, wm):
    """(sigma J/sqrt(F), its L/rho^2 multiple, N/M, its terms' size) at q; where rounding makes
    F <= 0 beside an end, F's linear growth from the nearer end (slopes fa, fb) stands in."""
    F, Fq, sig, lr2, nm, ns = _at(p, edges, coef, meta, c1, c2, e0, q, wm)
    if not F > 0.0:
        F = min(abs(fa) * (q - q1), abs(fb) * (q2 - q))
        if not F > 0.0:
            return 0.0, 0.0, nm, ns
    f = sig * jac / math.sqrt(F)
    return f, f * lr2, nm, ns


@kernel
def quadrature(p, edges, coef, meta, c1, c2, e0, q1, q2, sub, wm):
    """(T, psi, nodes, the smallest N/M at the nodes and its terms' size there) of the orbit
    between its turning points q1 < q2 (module docstring); sub: 0 q = m - h cos t, 1
    log(q - q_axis) = m - h cos t; ``wm`` the well (:func:`_at`: then q1, q2 are in its
    variable x, and N/M is not computed: inf)."""
    F1, fq1, s1, l1, n1, z1 = _at(p, edges, coef, meta, c1, c2, e0, q1, wm)
    F2, fq2, s2, l2, n2, z2 = _at(p, edges, coef, meta, c1, c2, e0, q2, wm)
    n_min, n_size = (n1, z1) if n1 <= n2 else (n2, z2)
    m = 0.5 * (q1 + q2)
    h = 0.5 * (q2 - q1)
    qx = meta[Q_AXIS]
    ym = yh = 0.0
    if sub == 1:
        y1 = math.log(q1 - qx)
        y2 = math.log(q2 - qx)
        ym = 0.5 * (y1 + y2)
        yh = 0.5 * (y2 - y1)
    j1 = h if sub == 0 else (q1 - qx) * yh
    j2 = h if sub == 0 else (q2 - qx) * yh
    fa = s1 * math.sqrt(2.0 * j1 / abs(fq1))
    fb = s2 * math.sqrt(2.0 * j2 / abs(fq2))
    pa, pb = fa * l1, fb * l2
    sT = 0.5 * (fa + fb)
    sP = 0.5 * (pa + pb)
    sA = 0.5 * (abs(pa) + abs(pb))
    n = 1
    IT = IP = math.nan
    while n < N_MAX:
        n *= 2
        dc, ds = math.cos(2.0 * math.pi / n), math.sin(2.0 * math.pi / n)
        ct, st = math.cos(math.pi / n), math.sin(math.pi / n)
        for j in range(1, n, 2):  # the new nodes t = j pi/n (cos, sin by rotations)
            if j > 1:
                ct, st = ct * dc - st * ds, st * dc + ct * ds
            if sub == 0:
                q, jac = m - h * ct, h
            else:
                e = math.exp(ym - yh * ct)
                q, jac = qx + e, e * yh
            f, g, nm, ns = _node(p, edges, coef, meta, c1, c2, e0, q, jac, fq1, fq2, q1, q2, wm)
            if nm < n_min:
                n_min, n_size = nm, ns
            sT += f * st
            sP += g * st
            sA += abs(g) * st
        IT2 = sT * math.pi / n
        IP2 = sP * math.pi / n
        if n >= 8 and abs(IT2 - IT) <= QUAD_TOL * IT2:
            if abs(IP2 - IP) <= QUAD_TOL * sA * math.pi / n:
                return 2.0 * IT2, abs(IP2), n + 1, n_min, n_size
        IT, IP = IT2, IP2
    return 2.0 * IT, abs(IP), n + 1, n_min, n_size


@kernel
def radial_period(p, edges, coef, meta, c2, e0, qa, q2):
    """T = 2 int_{qa}^{q2} sigma dq/sqrt(F) of a radial orbit (qa the axis, where the
    potential may have a kink: the cone's vertex): q = q2 - (q2 - qa) v^2 makes the integrand
    smooth and even in v on [-1, 1]; Gauss-Legendre on 2 N_GL and 4 N_GL points, then 8 N_GL
    where they differ by more than QUAD_TOL."""
    D = q2 - qa
    last = math.nan
    for m in range(3):
        s = 0.0
        for i in range(N_GL * 2**m):
            v = _GL_X[m, i]
            F, Fq, sig, lr2, rho, z, nm, ns = radial_f(p, edges, coef, meta, 0.0, c2, e0,
                                                       q2 - D * v * v)  # fmt: skip
            s += _GL_W[m, i] * sig * 2.0 * D * v / math.sqrt(F)
        if abs(s - last) <= QUAD_TOL * s:
            break
        last = s
    return 2.0 * s

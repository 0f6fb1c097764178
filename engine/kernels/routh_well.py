"""The well of a narrow orbit of Routh's radial problem (:mod:`.routh`), to full relative
precision.

Near a circular orbit F = e - U(q) is the small difference of large terms: evaluated directly
it carries an absolute error eps |U|, a relative error eps |U| / (e - U_min) that grows as the
orbit narrows (the cone's closed form meets the same with its exact factorisation,
docs/physics.md "The radial problem"). Here, on [q_c - hw, q_c + hw] around the circular
orbit q_c (dU/ds = 0, Newton's method), the potential is rebuilt from its second derivative,
which has no such cancellation (:func:`.routh.potential_ss`):

    U(q) - U(q_c) = H(q) = int_{q_c}^q sigma(q') g(q') dq',   g(q') = int_{q_c}^{q'} sigma U'' dq''

(g = dU/ds), each integral a Chebyshev series on :data:`NL` points of the first kind
(:data:`NL_NARROW` for the narrowest), integrated exactly. With delta = u0^2 + H(q0),
F = delta - H(q) holds to the rounding of delta and H themselves: turning points, period and
apsidal angle keep every digit however narrow the orbit. sigma and L/rho^2 come as series on
the same points. :func:`well` reports the size of the series' trailing coefficients; the orbit
uses the model only where they are negligible.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .routh import along, potential, potential_ss

#: Points of the well's Chebyshev series (:data:`NL_NARROW` for a well narrower than
#: :data:`NARROWER` of its distance from the axis).
NL = 16
NL_NARROW = 8
NARROWER = 0.02


def _points(n: int) -> tuple[np.ndarray, np.ndarray]:
    theta = np.pi * (np.arange(n) + 0.5) / n
    v2c = np.cos(np.outer(np.arange(n), theta)) * (2.0 / n)
    v2c[0] *= 0.5
    return np.cos(theta), v2c


XI, _V2C = _points(NL)
_XI8, _V2C8 = _points(NL_NARROW)


@kernel
def _fit(v, v2c):
    """Chebyshev coefficients of the values v at the points of ``v2c`` (values -> coefficients)."""
    n = v.shape[0]
    c = np.zeros(n)
    for k in range(n):
        s = 0.0
        for j in range(n):
            s += v2c[k, j] * v[j]
        c[k] = s
    return c


@kernel
def value(c, x):
    """The Chebyshev series c at x in [-1, 1] (Clenshaw)."""
    b0 = b1 = 0.0
    for k in range(c.shape[0] - 1, 0, -1):
        b0, b1 = 2.0 * x * b0 - b1 + c[k], b0
    return x * b0 - b1 + c[0]


@kernel
def _integral(c, scale):
    """The antiderivative of the series c times ``scale``, zero at x = 0."""
    n = c.shape[0]
    out = np.zeros(n + 1)
    for k in range(1, n + 1):
        lo = c[k - 1] * (2.0 if k == 1 else 1.0)
        hi = c[k + 1] if k + 1 < n else 0.0
        out[k] = scale * (lo - hi) / (2.0 * k)
    out[0] = -value(out, 0.0)
    return out


@kernel
def _tail(c):
    big = 0.0
    for k in range(c.shape[0]):
        big = max(big, abs(c[k]))
    return (abs(c[-1]) + abs(c[-2])) / big if big > 0.0 else 0.0


@kernel
def circular_q(p, edges, coef, meta, c1, c2, q1, q2):
    """The circular orbit q_c in (q1, q2) of the orbit with constants (c1, c2): dU/ds = 0 by
    Newton's method from the middle, kept in the bracket (bisection where it leaves it)."""
    lo, hi = q1, q2
    q = 0.5 * (q1 + q2)
    for _ in range(60):
        rho, z, sb, cb, kap, sig, L, dw = along(p, edges, coef, meta, c1, c2, q)
        Us = potential(p, rho, z, sb, cb, L, dw, c2)[1]
        if Us == 0.0:
            return q
        if Us < 0.0:
            lo = q
        else:
            hi = q
        qn = q - Us / (sig * potential_ss(p, rho, sb, cb, kap, L, c2 + dw))
        if not (lo < qn < hi):
            qn = 0.5 * (lo + hi)
        if abs(qn - q) <= 4e-16 * abs(q) or hi - lo <= 4e-16 * max(abs(lo), abs(hi)):
            return qn
        q = qn
    return q


@kernel
def well(p, edges, coef, meta, c1, c2, qc, hw, narrow):
    """(H, g, sigma, L/rho^2, tail): Chebyshev series in x = (q - q_c)/hw of the well (module
    docstring; on NL_NARROW points where ``narrow``, else NL) and the largest relative size of
    their trailing coefficients."""
    xi, v2c = (_XI8, _V2C8) if narrow else (XI, _V2C)
    n = xi.shape[0]
    f = np.empty(n)
    sg = np.empty(n)
    lr = np.empty(n)
    for j in range(n):
        rho, z, sb, cb, kap, sig, L, dw = along(p, edges, coef, meta, c1, c2, qc + hw * xi[j])
        f[j] = sig * potential_ss(p, rho, sb, cb, kap, L, c2 + dw)
        sg[j] = sig
        lr[j] = L / (rho * rho)
    a1 = _fit(f, v2c)
    g = _integral(a1, hw)
    for j in range(n):
        f[j] = sg[j] * value(g, xi[j])
    a2 = _fit(f, v2c)
    H = _integral(a2, hw)
    S = _fit(sg, v2c)
    R = _fit(lr, v2c)
    tail = max(max(_tail(a1), _tail(a2)), max(_tail(S), _tail(R)))
    return H, g, S, R, tail


@kernel
def well_root(H, g, S, hw, delta, x):
    """The root of delta - H near x (Newton's method; dH/dx = hw sigma g), in [-1, 1]."""
    for _ in range(50):
        d = (value(H, x) - delta) / (hw * value(S, x) * value(g, x))
        x -= d
        if not (-1.0 <= x <= 1.0) or not math.isfinite(x):
            return math.nan
        if abs(d) <= 4e-16 * max(abs(x), 1e-3):
            return x
    return x

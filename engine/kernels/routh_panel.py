"""One panel of a surface's fundamental solution (:mod:`.routh`; the panels are chosen by
``engine.routh``): Chebyshev collocation of the linear meridian system in integral form.

On the panel [lo, hi] (in q, or in x = 1/q on an infinite tail) mapped to xi in [-1, 1], the
propagator Psi from the panel's start (Psi = I there) solves

    Psi(xi_i) = I + sum_j S_ij B(xi_j) Psi(xi_j),     B = (dq/dxi) A(q),

on the NC Chebyshev points of the first kind xi_j (inside the panel: the axis and q = inf are
never evaluated), S the spectral integration matrix from the start (:data:`INT`, from the left
end; minus the whole integral :data:`W` from the right end): one linear system of 2 NC
equations for each of Psi's two columns, solved by Gaussian elimination with partial pivoting.
The integral form is well conditioned (no differentiation matrix). The panel's quality is the
size of the last two Chebyshev coefficients of Psi with L scaled by the panel's mean rho (so L
and w weigh alike).
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev as cheb

from .._jit import kernel
from .routh import NC, ode_coefficients

#: The Chebyshev points of the first kind (descending) and values -> coefficients.
NODES = np.cos(np.pi * (np.arange(NC) + 0.5) / NC)
V2C = np.cos(np.outer(np.arange(NC), np.pi * (np.arange(NC) + 0.5) / NC)) * (2.0 / NC)
V2C[0] *= 0.5
_ANTI = [cheb.chebint(np.eye(NC)[k], lbnd=-1) for k in range(NC)]
#: int_{-1}^{xi_i} f from the values f(xi_j), and int_{-1}^{1} f.
INT = np.stack([cheb.chebval(NODES, a) for a in _ANTI], axis=1) @ V2C
W = np.array([cheb.chebval(1.0, a) for a in _ANTI]) @ V2C


@kernel
def _solve(M, rhs):
    """Solve M X = rhs in place (Gaussian elimination, partial pivoting); returns X (rhs)."""
    n = M.shape[0]
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(M[r, c]) > abs(M[piv, c]):
                piv = r
        if piv != c:
            for j in range(n):
                M[c, j], M[piv, j] = M[piv, j], M[c, j]
            for j in range(rhs.shape[1]):
                rhs[c, j], rhs[piv, j] = rhs[piv, j], rhs[c, j]
        inv = 1.0 / M[c, c]
        for r in range(c + 1, n):
            f = M[r, c] * inv
            if f != 0.0:
                for j in range(c + 1, n):
                    M[r, j] -= f * M[c, j]
                for j in range(rhs.shape[1]):
                    rhs[r, j] -= f * rhs[c, j]
    for r in range(n - 1, -1, -1):
        for j in range(rhs.shape[1]):
            s = rhs[r, j]
            for k in range(r + 1, n):
                s -= M[r, k] * rhs[k, j]
            rhs[r, j] = s / M[r, r]
    return rhs


@kernel
def _mul2(A, B):
    """The 2 x 2 product A B (without BLAS)."""
    C = np.empty((2, 2))
    for r in range(2):
        for c in range(2):
            C[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c]
    return C


@kernel
def panel(p, mode, lo, hi, in_x, from_left, start):
    """(coef [NC, 4], Phi at the panel's far end [2, 2], tail): the Chebyshev coefficients of
    Phi - I on the panel (Phi = Psi start; a constant exactly), and the size of Psi's
    trailing coefficients (module docstring)."""
    n = NC
    qs = np.empty(n)
    jac = np.empty(n)
    for j in range(n):
        if in_x:
            xa, xb = 1.0 / lo, 1.0 / hi
            qs[j] = 1.0 / (0.5 * (xa + xb) + 0.5 * (xb - xa) * NODES[j])
            jac[j] = qs[j] * qs[j] * 0.5 * (xa - xb)
        else:
            qs[j] = 0.5 * (lo + hi) + 0.5 * (hi - lo) * NODES[j]
            jac[j] = 0.5 * (hi - lo)
    A = np.empty((5, n))
    ode_coefficients(p, mode, qs, A)
    ell = 0.0
    zero = True
    for j in range(n):
        ell += abs(A[4, j]) / n
        for m in range(4):
            A[m, j] *= jac[j]
            zero = zero and A[m, j] == 0.0
    ell = max(ell, 1e-300)
    psi = np.zeros((n, 2, 2))
    end = np.eye(2)
    tail = 0.0
    if zero:
        for j in range(n):
            psi[j, 0, 0] = psi[j, 1, 1] = 1.0
    else:
        M = np.eye(2 * n)
        for i in range(n):
            for j in range(n):
                s = INT[i, j] if from_left else INT[i, j] - W[j]
                M[i, j] -= s * A[0, j]
                M[i, n + j] -= s * A[1, j]
                M[n + i, j] -= s * A[2, j]
                M[n + i, n + j] -= s * A[3, j]
        Y = np.zeros((2 * n, 2))
        for i in range(n):
            Y[i, 0] = Y[n + i, 1] = 1.0
        _solve(M, Y)
        sign = 1.0 if from_left else -1.0
        for j in range(n):
            for c in range(2):
                psi[j, 0, c] = Y[j, c]
                psi[j, 1, c] = Y[n + j, c]
                end[0, c] += sign * W[j] * (A[0, j] * Y[j, c] + A[1, j] * Y[n + j, c])
                end[1, c] += sign * W[j] * (A[2, j] * Y[j, c] + A[3, j] * Y[n + j, c])
        scale = np.array([[1.0, 1.0 / ell], [ell, 1.0]])
        big = 1.0
        for j in range(n):
            for r in range(2):
                for c in range(2):
                    big = max(big, abs(psi[j, r, c] * scale[r, c]))
        for k in range(n - 2, n):
            for r in range(2):
                for c in range(2):
                    s = 0.0
                    for j in range(n):
                        s += V2C[k, j] * psi[j, r, c] * scale[r, c]
                    tail = max(tail, abs(s) / big)
    coef = np.zeros((n, 4))
    vals = np.empty((n, 4))
    for j in range(n):
        P = _mul2(psi[j], start)
        vals[j, 0], vals[j, 1] = P[0, 0] - 1.0, P[0, 1]
        vals[j, 2], vals[j, 3] = P[1, 0], P[1, 1] - 1.0
    for m in range(4):
        const = True
        for j in range(1, n):
            const = const and vals[j, m] == vals[0, m]
        if const:
            coef[0, m] = vals[0, m]
        else:
            for k in range(n):
                s = 0.0
                for j in range(n):
                    s += V2C[k, j] * vals[j, m]
                coef[k, m] = s
    return coef, _mul2(end, start), tail

"""Routh's reduction: exact orbit maps of a sphere rolling on any surface of revolution
(docs/physics.md "Any surface of revolution"; the surfaces' meridians: :mod:`.meridian`).

Along the centre's meridian (arc length s, slope b, curvature kappa, distance rho from the axis)
the rolling equations (:mod:`.surface`) give, with k' = k/(1+k), for L = rho v = rho^2 dtheta/dt
and the spin w = a omega . nu

    dL/ds = -k' kappa rho w,      dw/ds = -(sin(b)/rho - kappa) L / rho,

a linear system whose coefficients depend on the surface only (Routh). Its fundamental matrix
Phi (Phi(q_ref) = I, det Phi = 1) is built once per surface (``engine.routh``) as Chebyshev
panels in the meridian parameter q (and in x = 1/q on an infinite tail) and reaches the
kernels as three arrays, a *table*: ``edges`` (the panels' ends in q, ascending; the last may be
inf), ``coef`` [panel, NC, 4] (the Chebyshev coefficients of Phi - I: Phi11 - 1, Phi12, Phi21,
Phi22 - 1, in the panel's variable mapped to [-1, 1]; Phi - I keeps its digits where Phi ~ I)
and ``meta`` (:data:`META`). The table's variables (its *mode*): (L, W) with W = w - L
tan(b)/rho, which are the cone's constants L_z/M and h (there kappa = 0: Phi = I exactly, no
coefficient), or (L, w) on the bowl (regular up to its equator, where tan b diverges), or the
cylinder's closed form (L constant, w linear in the height: no panels). In (L, W)

    dL/ds = -k' kappa (tan(b) L + rho W),   dW/ds = kappa tan(b) (k' W - L tan(b)/((1+k) rho)),

every coefficient a multiple of kappa, regular at a smooth axis (tan(b)/rho -> kappa there).

An orbit's two linear integrals are the constants c = Phi(q0)^-1 (L0, W0) of its launch. What
is left is the radial problem of one degree of freedom, u = ds/dt:

    u^2 = F(q) = e - U(q),  U = [k w^2 + 2 g z] / (1+k) + L^2/rho^2,  e = u0^2 + U(q0),

(the energy; du/dt = -U'(s)/2 is the rolling equations' meridian acceleration), solved by
:mod:`.routh_orbit` (turning points, classes), :mod:`.routh_quad` (period, apsidal angle) and
:mod:`.routh_well` (narrow orbits).

**The integrals' normalisation** (``routh_L`` [kg m^2/s], ``routh_w`` [m/s]): M L and
w - L tan(b)/rho of the orbit's solution at the surface's reference point q_ref: the inner end
(the axis, the fit limit or the profile's inner edge; at an axis tan(b)/rho is its limit, the
curvature there), on the funnel q = inf (the flat far field: M L and w at infinity). On the
cone these are L_z and h exactly, for any q_ref. The cylinder (tan b infinite): M L and the
spin w at height 0 (the centre's, w + L z/rho^2).
"""

from __future__ import annotations

import math

from .._jit import kernel
from .layouts import P_G, P_INV_M1K, P_K, P_KK, P_M
from .meridian import centre

#: Orbit classes (int8); bounded .. spills have the cone's codes (``.geometry``).
NO_ORBIT, BOUNDED, CIRCULAR, HYPERBOLIC, RADIAL, SPILLS, HOLE, UNFIT, UNSTABLE, LIFTS = range(10)
CLASS_NAMES = ("no_orbit", "bounded", "circular", "hyperbolic", "radial", "spills", "hole",
               "unfit", "unstable_circular", "lifts_off")  # fmt: skip
#: Not a class: the orbit leaves a table built to a finite q (``engine.routh`` extends it).
EXTEND = -1
#: Rows of the float output of :func:`.routh_orbit.orbit_points`.
ROWS = ("rho_min", "rho_max", "period", "apsidal_angle", "precession_rate", "routh_L", "routh_w")
#: Chebyshev coefficients per panel.
NC = 16
#: The table's modes (its variables).
MODE_HAT, MODE_LW, MODE_CYLINDER = 0, 1, 2
#: Kinds of the meridian's ends: inner (the axis, a hole, the fit limit, none: the cylinder's
#: -inf), outer (a rim, infinity, the end of a table built to a finite q).
END_AXIS, END_HOLE, END_UNFIT, END_OPEN, END_RIM, END_INFINITY, END_TABLE = range(7)
#: The table's meta slots: mode, panels (all, in q), the ends (q, kind), the log substitution's
#: origin (NaN: none), the limit of tan(b)/rho at q_ref (mode (L, w)), the cylinder's rho,
#: 1 where kappa = 0 everywhere (Phi = I), the build's error estimate, q_ref, 1 where the
#: normal force can fall to zero somewhere (kappa < 0 or cos b <= 0 on the meridian's range).
META = ("mode", "n_panels", "n_q", "q_a", "q_b", "inner", "outer", "q_axis", "t_ref", "rho_cyl",
        "flat", "error", "q_ref", "may_lift")  # fmt: skip
(MODE, N_PANELS, N_Q, Q_A, Q_B, INNER, OUTER, Q_AXIS, T_REF, RHO_CYL, FLAT, ERROR,
 Q_REF, MAY_LIFT) = range(len(META))  # fmt: skip
#: Where the geometry of q = inf is evaluated (the infinite tail's end).
Q_FAR = 1e150
#: A launch with u0 = 0 whose meridian force vanishes to this fraction of its terms is circular.
CIRCULAR_TOL = 1e-12


@kernel
def ode_coefficients(p, mode, qs, out):
    """The linear system in q, d(L, X)/dq = A(q) (L, X): out[0:4, i] = A11, A12, A21, A22 at
    qs[i] (X = W in mode (L, W), w in mode (L, w)), out[4, i] = rho."""
    kk = p[P_KK]
    k1 = 1.0 + p[P_K]
    for i in range(qs.shape[0]):
        rho, z, cb, sb, kap, sig, fit = centre(p, qs[i])
        sk = sig * kap
        if mode == MODE_HAT:
            tb = sb / cb
            out[0, i] = -kk * sk * tb
            out[1, i] = -kk * sk * rho
            out[2, i] = -sk * tb * tb / (k1 * rho)
            out[3, i] = kk * sk * tb
        else:
            out[0, i] = 0.0
            out[1, i] = -kk * sk * rho
            out[2, i] = -(sig * sb / rho - sk) / rho
            out[3, i] = 0.0
        out[4, i] = rho


@kernel
def phi(edges, coef, meta, q):
    """(Phi11 - 1, Phi12, Phi21, Phi22 - 1) at q (module docstring: the table holds Phi - I,
    exactly 0 on the cone)."""
    if meta[MODE] == MODE_CYLINDER:
        r = meta[RHO_CYL]
        return 0.0, 0.0, -q / (r * r), 0.0
    lo, hi = 0, int(meta[N_PANELS])
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if edges[mid] <= q:
            lo = mid
        else:
            hi = mid
    a = edges[lo]
    b = edges[lo + 1]
    if lo < int(meta[N_Q]):
        xi = (2.0 * q - a - b) / (b - a)
    else:  # the tail, in x = 1/q (1/inf = 0)
        xa = 1.0 / a
        xb = 1.0 / b
        xi = (2.0 / q - xa - xb) / (xb - xa)
    xi = min(1.0, max(-1.0, xi))
    x2 = 2.0 * xi
    b0 = b1 = b2 = b3 = 0.0
    d0 = d1 = d2 = d3 = 0.0
    for j in range(NC - 1, 0, -1):
        t0 = x2 * b0 - d0 + coef[lo, j, 0]
        t1 = x2 * b1 - d1 + coef[lo, j, 1]
        t2 = x2 * b2 - d2 + coef[lo, j, 2]
        t3 = x2 * b3 - d3 + coef[lo, j, 3]
        d0, d1, d2, d3 = b0, b1, b2, b3
        b0, b1, b2, b3 = t0, t1, t2, t3
    return (xi * b0 - d0 + coef[lo, 0, 0], xi * b1 - d1 + coef[lo, 0, 1],
            xi * b2 - d2 + coef[lo, 0, 2], xi * b3 - d3 + coef[lo, 0, 3])  # fmt: skip


@kernel
def along(p, edges, coef, meta, c1, c2, q):
    """(rho, z, sin b, cos b, kappa, sigma, L, w - c2) of the orbit with constants (c1, c2) at
    q (w - c2 without the rounding of c2: exactly L tan(b)/rho on the cone)."""
    rho, z, cb, sb, kap, sig, fit = centre(p, min(q, Q_FAR))
    D11, D12, D21, D22 = phi(edges, coef, meta, q)
    L = c1 + (D11 * c1 + D12 * c2)
    dw = D21 * c1 + D22 * c2
    if meta[MODE] == MODE_HAT and L != 0.0:
        dw += L * sb / (cb * rho)
    return rho, z, sb, cb, kap, sig, L, dw


@kernel
def potential(p, rho, z, sb, cb, L, dw, c2):
    """(U - k c2^2/(1+k) [m^2/s^2], dU/ds [m/s^2], the size of dU/ds's terms) of the orbit with
    L and w = c2 + dw at q (module docstring; the constant k c2^2/(1+k) taken out, so that F's
    differences do not carry its rounding: on a funnel the binding energy at infinity)."""
    k1 = p[P_INV_M1K] * p[P_M]  # 1/(1+k)
    w = c2 + dw
    ir = 1.0 / rho
    v = L * ir if L != 0.0 else 0.0
    t1 = p[P_G] * sb * k1
    t2 = p[P_KK] * w * v * sb * ir
    t3 = v * v * cb * ir
    U = (p[P_K] * dw * (dw + 2.0 * c2) + 2.0 * p[P_G] * z) * k1 + v * v
    return U, 2.0 * (t1 - t2 - t3), 2.0 * (abs(t1) + abs(t2) + abs(t3))


@kernel
def potential_ss(p, rho, sb, cb, kap, L, w):
    """d^2U/ds^2 [1/s^2] (dU/ds differentiated along the meridian, the linear system for L', w')."""
    kk = p[P_KK]
    r2 = rho * rho
    r3 = r2 * rho
    wpL = -(sb / rho - kap) * L * L / rho  # w' L
    wLp = -kk * kap * rho * w * w  # w L'
    LLp2 = -2.0 * kk * kap * rho * L * w  # 2 L L'
    d1 = p[P_G] / (1.0 + p[P_K]) * kap * cb
    d2 = kk * ((wpL + wLp) * sb / r2 + w * L * kap * cb / r2 - 2.0 * w * L * sb * cb / r3)
    d3 = LLp2 * cb / r3 - L * L * kap * sb / r3 - 3.0 * L * L * cb * cb / (r2 * r2)
    return 2.0 * (d1 - d2 - d3)


@kernel
def integrals(p, edges, coef, meta, q0, v0, w0):
    """(ok, c1, c2, routh_L, routh_w) of the launch at q0 (module docstring); ok False where the
    launch is not where the centre can be (outside the meridian's range, on the axis)."""
    rho, z, cb, sb, kap, sig, fit = centre(p, q0)
    if not (meta[Q_A] <= q0 <= meta[Q_B]) or not (rho > 0.0 and fit > 0.0):
        return False, math.nan, math.nan, math.nan, math.nan
    L0 = rho * v0
    X0 = w0 - L0 * sb / (cb * rho) if meta[MODE] == MODE_HAT else w0
    D11, D12, D21, D22 = phi(edges, coef, meta, q0)
    c1 = (1.0 + D22) * L0 - D12 * X0
    c2 = -D21 * L0 + (1.0 + D11) * X0
    cw = c2 - c1 * meta[T_REF] if meta[MODE] == MODE_LW else c2
    return True, c1, c2, p[P_M] * c1, cw


@kernel
def radial_f(p, edges, coef, meta, c1, c2, e0, q):
    """(F = u^2, dF/dq, sigma, L/rho^2, rho, z, N/M, the size of N/M's terms) of the orbit at q:
    the normal force per mass N/M = g cos b + sin(b) v^2/rho + kappa u^2 [m/s^2] (:mod:`.surface`)
    with v = L/rho, u^2 = F (0 where rounding makes F < 0), and |g cos b| + |sin(b) v^2/rho| +
    |kappa u^2| (:mod:`.routh_contact`)."""
    rho, z, sb, cb, kap, sig, L, dw = along(p, edges, coef, meta, c1, c2, q)
    U, Us, sc = potential(p, rho, z, sb, cb, L, dw, c2)
    lr2 = L / (rho * rho) if L != 0.0 else 0.0
    F = e0 - U
    t1 = p[P_G] * cb
    t2 = sb * lr2 * L / rho if L != 0.0 else 0.0
    t3 = kap * max(F, 0.0)
    return F, -sig * Us, sig, lr2, rho, z, t1 + t2 + t3, abs(t1) + abs(t2) + abs(t3)

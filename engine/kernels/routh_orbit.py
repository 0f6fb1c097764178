"""One orbit of Routh's radial problem (:mod:`.routh`): its class, turning points, radial
period and apsidal angle (:mod:`.routh_quad`); the parallel batch over points.

- **Turning points**: from the launch (F = u0^2 >= 0) towards each end of the meridian, F is
  sampled at steps that grow from 1/64 of the way and then close in geometrically on the end
  (the axis, where a centrifugal barrier can sit arbitrarily close), or double towards an
  infinite end; the first sign change is refined by Newton's method kept inside the bracket
  (bisection where it leaves it) to full precision. A launch with u0 = 0 is itself a turning
  point, the pericentre where the meridian force -dU/ds/2 points outward. An end reached with
  F >= 0 gives the class: a rim (spills), a hole, the fit limit (unfit), infinity where F(inf)
  >= 0 after 2^20 times the launch's q with no root (hyperbolic: a barrier farther out is not
  looked for), the cylinder's open bottom (hyperbolic: it falls).
- **Narrow orbits** (narrower in arc length than :data:`NARROW` of their distance from the
  axis) are solved in their well (:mod:`.routh_well`): from a launch at a turning point whose
  harmonic estimate of the width is narrow, directly (no search); otherwise after the search.
- **Circular** launches (u0 = 0, dU/ds = 0 to the rounding of its terms): T = 2 pi/omega,
  omega^2 = U''(s)/2, psi = pi |L/rho^2|/omega (the small-oscillation limit, as for the cone);
  U'' < 0: an unstable circular orbit.
- **Radial** orbits (L = 0 along the whole meridian: on the cone L = 0; elsewhere also w = 0)
  pass through the axis: T from the axis to the apocentre and back (pericentre to pericentre,
  the cone's convention: half the swing from one side to the other and back), psi NaN.
- **Lift-off**: an orbit (of any class) whose normal force falls to zero where it goes, on a
  meridian that can lose the contact, is ``lifts_off`` instead (:mod:`.routh_contact`): the
  reduction's orbit assumes the contact it would lose.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from .._jit import kernel, parallel_kernel
from .lanes_step import piece_starts, take_point
from .meridian import centre
from .routh import (
    BOUNDED,
    CIRCULAR,
    CIRCULAR_TOL,
    END_AXIS,
    END_HOLE,
    END_INFINITY,
    END_OPEN,
    END_RIM,
    END_UNFIT,
    EXTEND,
    FLAT,
    HOLE,
    HYPERBOLIC,
    INNER,
    LIFTS,
    MODE,
    MODE_CYLINDER,
    NO_ORBIT,
    OUTER,
    Q_A,
    Q_AXIS,
    Q_B,
    Q_FAR,
    RADIAL,
    RHO_CYL,
    SPILLS,
    UNFIT,
    UNSTABLE,
    along,
    integrals,
    potential,
    potential_ss,
    radial_f,
)
from .routh_contact import lifts_at_nodes, lifts_between, lifts_in_well, normal_per_mass
from .routh_quad import quadrature, radial_period
from .routh_well import NARROWER, circular_q, value, well, well_root
from .surface_starts import X_POS, X_U, X_V, X_W, launch_q

#: Doublings towards infinity before F(inf) decides.
SCAN = 20
#: Closer and closer steps towards a finite end.
HALVINGS = 200
#: An orbit narrower (in arc length) than this fraction of its distance from the axis uses
#: its well (:mod:`.routh_well`) where the well's series converge to WELL_TOL.
NARROW = 0.3
WELL_TOL = 1e-14
#: Log substitution where the apocentre's distance from the axis is this many pericentres.
ECCENTRIC = 4.0


@kernel
def _root(p, edges, coef, meta, c1, c2, e0, qa, fa, qb, fb, guess):
    """The root of F between qa (F = fa >= 0) and qb (F = fb < 0): Newton kept in the bracket,
    from ``guess`` where it lies inside, else from the secant point, or the middle where qa
    is a root itself (the launch: F = 0 there; the secant would return it)."""
    q = guess
    if not (min(qa, qb) < q < max(qa, qb)):
        q = qb - fb * (qb - qa) / (fb - fa)
        if not (fa > 0.0 and min(qa, qb) < q < max(qa, qb)):
            q = 0.5 * (qa + qb)
    for _ in range(100):
        F, Fq, sig, lr2, rho, z, nm, ns = radial_f(p, edges, coef, meta, c1, c2, e0, q)
        if F == 0.0:
            return q
        if F > 0.0:
            qa = q
        else:
            qb = q
        qn = q - F / Fq
        if not (min(qa, qb) < qn < max(qa, qb)):
            qn = 0.5 * (qa + qb)
        if abs(qn - q) <= 4e-16 * abs(q) or abs(qb - qa) <= 4e-16 * max(abs(qa), abs(qb)):
            return qn
        q = qn
    return q


@kernel
def _turn(p, edges, coef, meta, c1, c2, e0, q0, f0, q_end, axis_end, hint):
    """(found, q): the first root of F from q0 (F = f0 >= 0) towards the end q_end, or (False,
    q_end) where F stays >= 0 to the end (module docstring). ``hint``: from a launch at a
    turning point, 2.5 times the way to the harmonic well's centre: a first sample beyond the
    other root, used where it is on the way to the end and F < 0 there (Newton then starts at
    the harmonic estimate, 0.8 hint)."""
    qp, fp = q0, f0
    nan = math.nan
    if hint != 0.0 and (q0 + hint - q_end) * hint < 0.0:
        f = radial_f(p, edges, coef, meta, c1, c2, e0, q0 + hint)[0]
        if f < 0.0:
            return True, _root(p, edges, coef, meta, c1, c2, e0, q0, fp, q0 + hint, f,
                               q0 + 0.8 * hint)  # fmt: skip
    if math.isfinite(q_end):
        span = q_end - q0
        frac = 1.0 / 128.0
        for k in range(HALVINGS + 6):
            frac = 2.0 * frac if k < 6 else 1.0 - 0.5 * (1.0 - frac)
            q = q0 + frac * span
            if (q - q_end) * span >= 0.0:
                break
            f = radial_f(p, edges, coef, meta, c1, c2, e0, q)[0]
            if f < 0.0:
                return True, _root(p, edges, coef, meta, c1, c2, e0, qp, fp, q, f, nan)
            qp, fp = q, f
        if axis_end:  # the barrier at the axis is closer than 2^-200 of the way: none
            return False, q_end
        f = radial_f(p, edges, coef, meta, c1, c2, e0, q_end)[0]
        if f < 0.0:
            return True, _root(p, edges, coef, meta, c1, c2, e0, qp, fp, q_end, f, nan)
        return False, q_end
    up = q_end > 0.0
    d = max(abs(q0), meta[RHO_CYL] if meta[MODE] == MODE_CYLINDER else 1e-300) / 16.0
    step = d if up else -d
    f_inf = radial_f(p, edges, coef, meta, c1, c2, e0, q_end)[0] if up else math.inf
    for k in range(1100):
        q = qp + step
        step *= 2.0
        if up and (q >= Q_FAR or (k > SCAN and f_inf >= 0.0)):
            if f_inf >= 0.0:
                return False, q_end
            q = Q_FAR
        if not up and q < -1e300:
            return False, q_end
        f = radial_f(p, edges, coef, meta, c1, c2, e0, q)[0]
        if f < 0.0:
            return True, _root(p, edges, coef, meta, c1, c2, e0, qp, fp, q, f, nan)
        qp, fp = q, f
    return False, q_end


@kernel
def _position(p, meta, q):
    """Where the centre is at q: its distance from the axis (the cylinder: its height)."""
    rho, z, cb, sb, kap, sig, fit = centre(p, min(q, Q_FAR))
    return z if meta[MODE] == MODE_CYLINDER else max(rho, 0.0)


@kernel
def _in_well(p, edges, coef, meta, c1, c2, e0, q0, u0, qc, hw, x1, x2):
    """(ok, rho_min, rho_max, T, psi, q1, q2) of the orbit in its well around q_c (half-width hw;
    its turning points near x1, x2 in x = (q - q_c)/hw, found at q1, q2); ok False where the
    well's series do not converge or its turning points are not inside it."""
    nan = math.nan
    rho, z, cb, sb, kap, sig, fit = centre(p, qc)
    narrow = hw * sig <= NARROWER * rho
    H, g, S, R, tail = well(p, edges, coef, meta, c1, c2, qc, hw, narrow)
    if narrow and not tail <= WELL_TOL:  # the wider rule
        H, g, S, R, tail = well(p, edges, coef, meta, c1, c2, qc, hw, False)
    if not tail <= WELL_TOL:
        return False, nan, nan, nan, nan, nan, nan
    delta = u0 * u0 + value(H, (q0 - qc) / hw)
    x1 = well_root(H, g, S, hw, delta, x1)
    x2 = well_root(H, g, S, hw, delta, x2)
    if not (-0.98 < x1 < x2 < 0.98):
        return False, nan, nan, nan, nan, nan, nan
    T, psi, nodes, n_min, n_size = quadrature(p, edges, coef, meta, c1, c2, e0, x1, x2, 0,
                               (H, g, S, R, qc, hw, delta))  # fmt: skip
    q1 = qc + hw * x1
    q2 = qc + hw * x2
    return True, _position(p, meta, q1), _position(p, meta, q2), T, psi, q1, q2


@kernel
def orbit(p, edges, coef, meta, q0, u0, v0, w0):
    """(class, rho_min, rho_max, period, apsidal angle, precession rate, routh_L, routh_w) of
    the launch at the meridian parameter q0 with speeds (u0, v0, w0) (module docstring)."""
    nan = math.nan
    ok, c1, c2, IL, Iw = integrals(p, edges, coef, meta, q0, v0, w0)
    if not (ok and math.isfinite(u0) and math.isfinite(v0) and math.isfinite(w0)):
        return NO_ORBIT, nan, nan, nan, nan, nan, nan, nan
    cyl = meta[MODE] == MODE_CYLINDER
    radial = c1 == 0.0 and (c2 == 0.0 or meta[FLAT] != 0.0) and not cyl
    rho0, z0, sb0, cb0, kap0, sig0, L0, dw0 = along(p, edges, coef, meta, c1, c2, q0)
    U0, Us0, sc0 = potential(p, rho0, z0, sb0, cb0, L0, dw0, c2)
    e0 = u0 * u0 + U0
    pos0 = z0 if cyl else rho0
    if u0 == 0.0 and abs(Us0) <= CIRCULAR_TOL * sc0 and not radial:
        Uss = potential_ss(p, rho0, sb0, cb0, kap0, L0, c2 + dw0)
        if normal_per_mass(p, edges, coef, meta, c1, c2, e0, q0) < 0.0:
            return LIFTS, pos0, pos0, nan, nan, nan, IL, Iw
        if not Uss > 0.0:
            return UNSTABLE, pos0, pos0, nan, nan, nan, IL, Iw
        om = math.sqrt(0.5 * Uss)
        T = 2.0 * math.pi / om
        psi = math.pi * abs(L0 / (rho0 * rho0)) / om
        return CIRCULAR, pos0, pos0, T, psi, (2.0 * psi - 2.0 * math.pi) / T, IL, Iw
    hint = 0.0
    if u0 == 0.0 and not radial:  # at a turning point: narrow by its harmonic estimate?
        Uss = potential_ss(p, rho0, sb0, cb0, kap0, L0, c2 + dw0)
        dq = -Us0 / (Uss * sig0)  # to the centre of the harmonic well
        hint = 2.5 * dq if Uss > 0.0 else 0.0
        if Uss > 0.0 and 2.6 * abs(dq) * sig0 <= NARROW * rho0:
            qc = circular_q(p, edges, coef, meta, c1, c2, min(q0, q0 + 2.0 * dq),
                            max(q0, q0 + 2.0 * dq))  # fmt: skip
            hw = 1.3 * abs(q0 - qc)
            x0 = (q0 - qc) / hw
            w = _in_well(p, edges, coef, meta, c1, c2, e0, q0, 0.0, qc, hw, min(x0, -x0),
                         max(x0, -x0))  # fmt: skip
            ok, rmin, rmax, T, psi, qw1, qw2 = w
            if ok:
                if lifts_in_well(p, edges, coef, meta, c1, c2, e0, qw1, qc, qw2):
                    return LIFTS, rmin, rmax, nan, nan, nan, IL, Iw
                return BOUNDED, rmin, rmax, T, psi, (2.0 * psi - 2.0 * math.pi) / T, IL, Iw
    inner = meta[INNER]
    lo_end = -math.inf if inner == END_OPEN else meta[Q_A]
    axis = inner == END_AXIS
    if radial and axis:
        found1, q1 = False, lo_end
    elif u0 == 0.0 and Us0 < 0.0:
        found1, q1 = True, q0
    else:
        found1, q1 = _turn(p, edges, coef, meta, c1, c2, e0, q0, u0 * u0, lo_end, axis, hint)
    if u0 == 0.0 and Us0 > 0.0:
        found2, q2 = True, q0
    else:
        found2, q2 = _turn(p, edges, coef, meta, c1, c2, e0, q0, u0 * u0, meta[Q_B], False,
                           hint)  # fmt: skip
    rmin = _position(p, meta, q1) if found1 or not axis else 0.0
    outer = meta[OUTER]
    rmax = _position(p, meta, q2) if found2 or outer == END_RIM else math.inf
    cls_out = SPILLS if outer == END_RIM else HYPERBOLIC if outer == END_INFINITY else EXTEND
    cls_in = (RADIAL if axis else HOLE if inner == END_HOLE else UNFIT if inner == END_UNFIT
              else HYPERBOLIC)  # fmt: skip
    if not found2 and (found1 or u0 > 0.0):  # out: from the launch or its inner turning point
        qa = q0 if u0 > 0.0 else q1
        if lifts_between(p, edges, coef, meta, c1, c2, e0, qa, meta[Q_B]):
            return LIFTS, rmin, rmax, nan, nan, nan, IL, Iw
        return cls_out, rmin, rmax, nan, nan, nan, IL, Iw
    if not found1 and not (radial and axis):  # in: from the launch or its outer turning point
        qb = q2 if found2 and u0 >= 0.0 else q0
        if lifts_between(p, edges, coef, meta, c1, c2, e0, lo_end, qb):
            return LIFTS, rmin, rmax, nan, nan, nan, IL, Iw
        return cls_in, rmin, rmax, nan, nan, nan, IL, Iw
    if not found2:  # through the axis and out
        if lifts_between(p, edges, coef, meta, c1, c2, e0, lo_end, meta[Q_B]):
            return LIFTS, rmin, rmax, nan, nan, nan, IL, Iw
        return cls_out, rmin, rmax, nan, nan, nan, IL, Iw
    none = np.empty(0)
    wm = (none, none, none, none, 0.0, 1.0, 0.0)
    if radial and axis:
        if lifts_between(p, edges, coef, meta, c1, c2, e0, q1, q2):
            return LIFTS, 0.0, rmax, nan, nan, nan, IL, Iw
        T = radial_period(p, edges, coef, meta, c2, e0, q1, q2)
        return RADIAL, 0.0, rmax, T, nan, nan, IL, Iw
    if (q2 - q1) * sig0 <= NARROW * rho0:  # a narrow orbit: its well (.routh_well)
        qc = circular_q(p, edges, coef, meta, c1, c2, q1, q2)
        hw = 0.6 * (q2 - q1) + abs(0.5 * (q1 + q2) - qc)
        w = _in_well(p, edges, coef, meta, c1, c2, e0, q0, u0, qc, hw, (q1 - qc) / hw,
                     (q2 - qc) / hw)  # fmt: skip
        ok, rmin2, rmax2, T, psi, qw1, qw2 = w
        if ok:
            if lifts_in_well(p, edges, coef, meta, c1, c2, e0, qw1, qc, qw2):
                return LIFTS, rmin2, rmax2, nan, nan, nan, IL, Iw
            return BOUNDED, rmin2, rmax2, T, psi, (2.0 * psi - 2.0 * math.pi) / T, IL, Iw
    qx = meta[Q_AXIS]
    sub = 1 if (q1 > qx and q2 - qx > ECCENTRIC * (q1 - qx)) else 0  # NaN q_axis: 0
    T, psi, nodes, n_min, n_size = quadrature(p, edges, coef, meta, c1, c2, e0, q1, q2, sub, wm)
    if lifts_at_nodes(p, edges, coef, meta, c1, c2, e0, q1, q2, n_min, n_size):
        return LIFTS, rmin, rmax, nan, nan, nan, IL, Iw
    return BOUNDED, rmin, rmax, T, psi, (2.0 * psi - 2.0 * math.pi) / T, IL, Iw


@parallel_kernel
def orbit_points(X, P, sid, edges, coef, meta, out_cls, out_f, n_workers):
    """:func:`orbit` of every point (the columns of the points array X, rows
    :mod:`.surface_starts`'s: shape1, shape2, rho0 (the cylinder: z0), v0, w0[, u0]); point i
    lies on surface ``sid[i]``: its parameter array ``P[s]`` (after ``set_point``) and table
    ``edges[s]``, ``coef[s]``, ``meta[s]``. Writes ``out_cls`` int8[n] and ``out_f``
    float64[7, n] (rows :data:`.routh.ROWS`), in parallel: ``n_workers`` threads take guided
    pieces of the points from one queue (:func:`.lanes_step.piece_starts`), so orbits of
    unequal cost (a root search, a quadrature doubled to convergence) keep every thread busy
    to the end, as a static split of the points did not."""
    n = X.shape[1]
    has_u = X.shape[0] > X_U
    workers = max(1, min(n_workers, n))
    queue = np.zeros(1, np.int64)
    starts = piece_starts(n, workers)
    for _ in prange(workers):
        nxt, end = 0, 0
        while True:
            i, nxt, end = take_point(queue, starts, nxt, end)
            if i < 0:
                break
            s = sid[i]
            p = P[s]
            q0 = launch_q(p, X[X_POS, i])
            u0 = X[X_U, i] if has_u else 0.0
            res = orbit(p, edges[s], coef[s], meta[s], q0, u0, X[X_V, i], X[X_W, i])
            out_cls[i] = res[0]
            out_f[0, i] = res[1]
            out_f[1, i] = res[2]
            out_f[2, i] = res[3]
            out_f[3, i] = res[4]
            out_f[4, i] = res[5]
            out_f[5, i] = res[6]
            out_f[6, i] = res[7]

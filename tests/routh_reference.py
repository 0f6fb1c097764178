"""Routh's reduction of a sphere rolling on a surface of revolution, at 40 digits (mpmath), for
the tests: an independent second method beside the Cartesian model of tests/surface_oracle.py
(which supplies only the surfaces' meridian functions; nothing from engine/).

**Derivation.** The centre moves on the offset surface, meridian (rho(s), z(s)) in its arc length
s, slope angle b (rho' = cos b, z' = sin b), frame e1 = (cos b) e_rho + (sin b) e_z, e2 = e_phi,
nu = e1 x e2 = -(sin b) e_rho + (cos b) e_z (from the contact point to the centre); curvatures
k1 = db/ds (meridian) and k2 = sin(b)/rho (parallel). Write V = u e1 + v e2 and
Omega = O1 e1 + O2 e2 + (w/a) nu; rolling (V = a Omega x nu) gives O1 = -v/a, O2 = u/a, and w =
a Omega . nu is the spin. With de1/dt = k1 u nu + (cos(b) v/rho) e2, de2/dt = -(v/rho) e_rho,
dnu/dt = -k1 u e1 - (sin(b) v/rho) e2, and the contact force N nu + F1 e1 + F2 e2 whose torque
-a nu x F = a F2 e1 - a F1 e2 has no nu part:
  Euler along nu:   dw/dt = a Omega . dnu/dt = (k1 - k2) u v;
  e2 (Newton):      M (dv/dt + cos(b) u v/rho) = F2,
  e1 (Euler):       k M a (dO1/dt - Omega . de1/dt) = a F2,
                    so F2 = -k M (dv/dt + cos(b) u v/rho + k1 u w) and
                    d(rho v)/dt = -k/(1+k) k1 u w rho.
Dividing by u = ds/dt leaves a linear ODE along the meridian for (L_z, w), L_z = M rho v (the
centre's angular momentum about z; on the cone the engine's L_z and h = w - v cot(alpha)):
  dL_z/ds = -k/(1+k) M k1 rho w,      dw/ds = (k1 - k2) L_z/(M rho).
Its solution through the launch gives L_z(s) and w(s); with |Omega|^2 = (u^2 + v^2 + w^2)/a^2 the
energy E = M (1+k)(u^2 + v^2)/2 + k M w^2/2 + M g z is conserved, so
  u^2(s) = 2 (E - k M w(s)^2/2 - M g z(s))/(M (1+k)) - (L_z(s)/(M rho(s)))^2,
a one-dimensional radial problem: turning points u^2 = 0, radial period T = 2 int ds/u, apsidal
angle psi = int (L_z/(M rho^2)) ds/u from the pericentre to the apocentre. (On a sphere k1 = k2:
w is conserved, Routh's result.) The tests check all of it against the Cartesian model.

**Numerics.** The touching meridian's parameter q is the variable: with P(q) = (R, Z),
|P'| ds_touch = dq, db/dq = (R'Z'' - Z'R'')/|P'|^2, the centre at (R - a sin b, Z + a cos b) and
ds/dq = |P'| - a db/dq (k1 ds = db, k2 ds = sin(b) ds/rho). mpmath.odefun (its Taylor series from
finite differences at (degree+1) times the precision) took 8-12 s per launch at 40 digits, so the
linear ODE is integrated by Gauss-Legendre collocation (s = 12 stages, order 24, exact linear
stage solves; 1-3 s per launch), step doubling for the step size, from the launch to the turning
points (safeguarded Newton on u^2, d(u^2)/dq from the ODE, within the step that brackets them).
T and psi are quadratures along q = c - d cos(theta) (c, d the turning points' mean and
half-difference; log q instead of q where the turning points are > 0, for wide orbits): the
integrand (ds/dq)(dq/dtheta)/|u| is then even and 2 pi-periodic in theta, free of the endpoint
singularities (u^2 ~ sin^2 theta there), so the trapezoidal rule converges geometrically;
(L_z, w) is carried from node to node by collocation steps. (Stage values of one collocation
step over the whole integral converged only like h^13 there: the integrand's dependence on
(L_z, w) blows up like 1/theta^3 at the ends.) A leg from a turning point q_t to
any q_e (the time to a rim, a hole, a slip) is the same integral along
q = q_t + (q_e - q_t)(1 - cos theta), theta in [0, pi/2], by Gauss-Legendre quadrature (n
doubled until two agree to the tolerance's square root).
Each result carries `err`, the largest of the step-doubling estimates, the quadrature's
convergence and the mismatch of (L_z, w) at the apocentre between the two passes.

**Contact forces** (for the fates' references), from the same equations: the normal force
N = M (g cos b + k1 u^2 + k2 v^2) and the friction F1 = k M (g sin b + k2 v w)/(1+k) along e1,
F2 = -k M k1 u w/(1+k) along e2 (on the cone the engine's F).
"""

from __future__ import annotations

import functools

import mpmath as mp

DPS = 40
WORK = DPS
STAGES = 12


@functools.cache
def _nodes(s: int, dps: int):
    """Gauss-Legendre nodes and weights on [0, 1] (Newton on P_s from Tricomi's guesses, P_s
    and P_s' by the three-term recurrence)."""
    with mp.workdps(dps + 10):
        c, b = [], []
        for i in range(s):
            x = mp.cos(mp.pi * (i + mp.mpf(0.75)) / (s + mp.mpf(0.5)))
            for _ in range(100):
                p0, p1 = mp.mpf(1), x
                for n in range(2, s + 1):
                    p0, p1 = p1, ((2 * n - 1) * x * p1 - (n - 1) * p0) / n
                dp = s * (x * p1 - p0) / (x * x - 1)
                dx = p1 / dp
                x -= dx
                if abs(dx) < mp.eps * 4:
                    break
            c.append((1 + x) / 2)
            b.append(1 / ((1 - x * x) * dp * dp))
        order = sorted(range(s), key=lambda i: c[i])
        return [+c[i] for i in order], [+b[i] for i in order]


@functools.cache
def _gauss(s: int, dps: int):
    """Nodes c, weights b and matrix a of the s-stage Gauss-Legendre collocation on [0, 1]
    (a_ij = int_0^c_i l_j, from the moments: sum_j a_ij c_j^m = c_i^(m+1)/(m+1))."""
    c, b = _nodes(s, dps)
    with mp.workdps(dps + 10):
        V = mp.matrix([[cj**m for cj in c] for m in range(s)])
        a = [mp.lu_solve(V, mp.matrix([ci ** (m + 1) / (m + 1) for m in range(s)])) for ci in c]
        return c, b, [[+x for x in row] for row in a]


def _linsolve(A, y):
    """Gaussian elimination with partial pivoting (lists of mpf; A and y are overwritten)."""
    n = len(y)
    for col in range(n):
        p = max(range(col, n), key=lambda r: abs(A[r][col]))
        A[col], A[p] = A[p], A[col]
        y[col], y[p] = y[p], y[col]
        inv = 1 / A[col][col]
        for r in range(col + 1, n):
            f = A[r][col] * inv
            if f:
                Ar, Ac = A[r], A[col]
                for j in range(col + 1, n):
                    Ar[j] -= f * Ac[j]
                y[r] -= f * y[col]
    x = [0] * n
    for r in range(n - 1, -1, -1):
        x[r] = (y[r] - sum(A[r][j] * x[j] for j in range(r + 1, n))) / A[r][r]
    return x


def gl_step(B, x, y, h):
    """One collocation step of dy/dx = B(x) y from x to x + h. B(x) = ((0, p), (r, 0)) (the
    meridian ODE's shape), so the stage values solve an s x s system:
    Y0 = y0 + h a P Y1, Y1 = y1 + h a R Y0 -> (I - h^2 a P a R) Y0 = y0 + h a P y1."""
    c, bw, a = _gauss(STAGES, WORK)
    s = len(c)
    Bs = [B(x + ci * h) for ci in c]
    P = [Bj[0][1] for Bj in Bs]
    R = [Bj[1][0] for Bj in Bs]
    haP = [[h * a[i][j] * P[j] for j in range(s)] for i in range(s)]
    haR = [[h * a[i][j] * R[j] for j in range(s)] for i in range(s)]
    A = [[(1 if i == j else 0) - mp.fsum(haP[i][m] * haR[m][j] for m in range(s))
          for j in range(s)] for i in range(s)]  # fmt: skip
    Y0 = _linsolve(A, [y[0] + y[1] * mp.fsum(haP[i]) for i in range(s)])
    Y1 = [y[1] + mp.fsum(haR[i][j] * Y0[j] for j in range(s)) for i in range(s)]
    return (y[0] + h * mp.fsum(bw[j] * P[j] * Y1[j] for j in range(s)),
            y[1] + h * mp.fsum(bw[j] * R[j] * Y0[j] for j in range(s)))  # fmt: skip


class Reduction:
    """Routh's reduction for one launch (the launch convention of tests/surface_oracle.py):
    `solve()` for the turning points, period and apsidal angle; `leg`, `first` and `forces`
    for the fates."""

    def __init__(self, surface, M, g, a, k, rho0=None, v0=0, w0=0, u0=0, q0=None):
        self.S = surface
        with mp.workdps(WORK):
            self.M, self.g, self.a, self.k = (mp.mpf(x) for x in (M, g, a, k))
            self.K = self.k / (1 + self.k)
            if q0 is None:
                rho0 = mp.mpf(rho0)
                hi = min(rho0 + self.a, self.S.q_hi * (1 - mp.mpf(10) ** -12))
                q0 = mp.findroot(lambda q: self.geo(q)[0] - rho0, (rho0, hi), solver="anderson")
            self.q0 = mp.mpf(q0)
            rc, zc, sb, cb, bp, ds = self.geo(self.q0)
            self.rho0, v0, w0, u0 = rc, mp.mpf(v0), mp.mpf(w0), mp.mpf(u0)
            self.y0 = (self.M * rc * v0, w0)
            self.E = (self.M * (1 + self.k) * (u0**2 + v0**2) / 2 + self.k * self.M * w0**2 / 2
                      + self.M * self.g * zc)  # fmt: skip
            self.u0 = u0
            self.vs = max(abs(v0), abs(w0), abs(u0), mp.sqrt(self.g * max(abs(rc), self.a)))
            self.err = mp.mpf(0)
            self.marks = {1: [(self.q0, self.y0)], -1: [(self.q0, self.y0)]}
            self.ends = {}

    # ------------------------------------------------------------- the surface
    def geo(self, q):
        """(rho, z, sin b, cos b, db/dq, ds/dq) of the centre's meridian at q."""
        R, Z, R1, Z1, R2, Z2 = self.S.at(q)
        m = mp.sqrt(R1 * R1 + Z1 * Z1)
        sb, cb = Z1 / m, R1 / m
        bp = (R1 * Z2 - Z1 * R2) / m**2
        return R - self.a * sb, Z + self.a * cb, sb, cb, bp, m - self.a * bp

    def B(self, q):
        """The meridian ODE's matrix: d(L_z, w)/dq = B(q) (L_z, w)."""
        rc, zc, sb, cb, bp, ds = self.geo(q)
        return ((0, -self.K * self.M * rc * bp), ((bp - sb * ds / rc) / (self.M * rc), 0))

    def u2(self, q, y):
        rc, zc = self.geo(q)[:2]
        M, k = self.M, self.k
        return (2 * (self.E - k * M * y[1] ** 2 / 2 - M * self.g * zc) / (M * (1 + k))
                - (y[0] / (M * rc)) ** 2)  # fmt: skip

    def du2(self, q, y):
        """d(u^2)/dq along the solution."""
        rc, zc, sb, cb, bp, ds = self.geo(q)
        Bq = self.B(q)
        dL, dw = Bq[0][1] * y[1], Bq[1][0] * y[0]
        v = y[0] / (self.M * rc)
        dv = dL / (self.M * rc) - v * cb * ds / rc
        M, k = self.M, self.k
        return 2 * (-k * M * y[1] * dw - M * self.g * sb * ds) / (M * (1 + k)) - 2 * v * dv

    def forces(self, q, y):
        """(N, F1, |F2|) of the rolling ball at q (module docstring; F2's sign is u's)."""
        with mp.workdps(WORK):
            rc, zc, sb, cb, bp, ds = self.geo(q)
            k1, k2 = bp / ds, sb / rc
            v, w, uu = y[0] / (self.M * rc), y[1], max(self.u2(q, y), 0)
            N = self.M * (self.g * cb + k1 * uu + k2 * v * v)
            F1 = self.k * self.M * (self.g * sb + k2 * v * w) / (1 + self.k)
            return N, F1, abs(self.k * self.M * k1 * mp.sqrt(uu) * w / (1 + self.k))

    # ------------------------------------------------------------- marching
    def _tol(self):
        return mp.mpf(10) ** (-WORK + 8)

    def _norm(self, y1, y2):
        return max(abs(y1[0] - y2[0]) / (self.M * self.rho0 * self.vs),
                   abs(y1[1] - y2[1]) / self.vs)  # fmt: skip

    def _step(self, B, x, y, h):
        """An accepted step from x of at most h (step doubling): (h used, y, next h)."""
        tol = self._tol()
        while True:
            y1 = gl_step(B, x, y, h)
            y2 = gl_step(B, x + h / 2, gl_step(B, x, y, h / 2), h / 2)
            err = self._norm(y1, y2)
            fac = min(2, max(mp.mpf(0.2), mp.mpf(0.8) * (tol / (err + tol * 1e-9)) ** (1 / 25)))
            if err <= tol:
                self.err = max(self.err, err / 1000)
                return h, y2, h * fac
            h *= fac

    def advance(self, B, x, y, x_to, h=None):
        """(L_z, w) at x_to from (x, y), adaptive steps."""
        h = (x_to - x) if h is None else h
        while True:
            last = abs(h) >= abs(x_to - x)
            if last:
                h = x_to - x
            hu, y, h = self._step(B, x, y, h)
            x += hu
            if last and hu == x_to - (x - hu):
                return y

    def march(self, direction, end=None):
        """March from the launch in q's `direction` (+1 or -1) to the first root of u^2 or to
        `end` (default the meridian's domain), keeping the steps as checkpoints: (q, (L_z, w))
        of the turning point, or None."""
        if direction in self.ends:
            return self.ends[direction]
        with mp.workdps(WORK):
            x, y = self.q0, self.y0
            lim = self.S.q_hi if direction > 0 else self.S.q_lo
            end = lim if end is None else mp.mpf(end)
            span = 10**6 * (abs(self.q0) + self.a)
            h = direction * (abs(self.q0) + self.a) / 64
            if self.u0 == 0 and self.du2(x, y) * direction < 0:
                raise ValueError("the launch is a turning point on this side")
            f_old = self.u2(x, y) if self.u0 != 0 else mp.mpf(1)
            out = None
            while abs(x - self.q0) < span:
                last = (x + h - end) * direction >= 0
                if last:
                    h = (end - x) * (mp.mpf("0.999") if end == lim else 1)
                    if abs(h) < mp.mpf(10) ** (-WORK // 2) * (abs(x) + self.a):
                        break
                hu, yn, h = self._step(self.B, x, y, h)
                xn = x + hu
                f_new = self.u2(xn, yn)
                if self.geo(xn)[5] <= 0:  # the ball no longer fits (the ODE goes on: kept)
                    self.marks[direction].append((xn, yn))
                    break
                if f_old > 0 >= f_new:
                    out = self._root(x, y, xn, f_old, f_new)
                    break
                x, y, f_old = xn, yn, f_new
                self.marks[direction].append((x, y))
                if last and end != lim:
                    break
            self.ends[direction] = out
            return out

    def state(self, q):
        """(L_z, w) at q, within the range marched, from the nearest checkpoint before it."""
        with mp.workdps(WORK):
            q = mp.mpf(q)
            side = 1 if q >= self.q0 else -1
            x, y = max(((x, y) for x, y in self.marks[side] if (q - x) * side >= 0),
                       key=lambda m: m[0] * side)  # fmt: skip
            return gl_step(self.B, x, y, q - x)

    def _root(self, x, y, xn, fa, fb):
        """The root of u^2 in the step (x, xn], where u^2 goes from fa > 0 to fb <= 0: Newton
        from the secant's point, kept inside the bracket (bisection where it leaves it)."""
        a, b = x, xn
        r = xn if fb == 0 else x + (xn - x) * fa / (fa - fb)
        for _ in range(200):
            yr = gl_step(self.B, x, y, r - x)
            fr = self.u2(r, yr)
            if fr == 0:
                return r, yr
            if (fr > 0) == (fa > 0):
                a = r
            else:
                b = r
            dr = fr / self.du2(r, yr)
            rn = r - dr
            if not min(a, b) < rn < max(a, b):
                rn = (a + b) / 2
            if abs(rn - r) <= mp.eps * 16 * (abs(r) + self.a):
                return rn, gl_step(self.B, x, y, rn - x)
            r = rn
        raise RuntimeError("the turning point did not converge")

    def first(self, fn, direction):
        """The first q from the launch in `direction`, within the range marched, where
        fn(q, (L_z, w)) turns from > 0 to <= 0; None if it does not."""
        with mp.workdps(WORK):
            pts = sorted(self.marks[direction], key=lambda m: m[0] * direction)
            if self.ends.get(direction):
                pts.append(self.ends[direction])
            f_old = fn(*pts[0])
            for (x, y), (xn, yn) in zip(pts, pts[1:], strict=False):
                f_new = fn(xn, yn)
                if f_old > 0 >= f_new:
                    return mp.findroot(lambda q, x=x, y=y: fn(q, gl_step(self.B, x, y, q - x)),
                                       (x, xn), solver="anderson")  # fmt: skip
                f_old = f_new
            return None

    # ------------------------------------------------------------- quadratures
    def solve(self):
        """Turning points, radial period and apsidal angle (mpf in a dict; `cls` "bounded", or
        "unbounded" where a side has no turning point in the meridian's domain)."""
        with mp.workdps(WORK):
            if self.u0 == 0:
                up = self.du2(self.q0, self.y0) > 0
                lo = (self.q0, self.y0) if up else self.march(-1)
                hi = self.march(+1) if up else (self.q0, self.y0)
            else:
                lo, hi = self.march(-1), self.march(+1)
            if lo is None or hi is None:
                return {"cls": "unbounded", "lower": lo, "upper": hi}
            (q1, y1), (q2, y2) = lo, hi
            # q = c - d cos(theta), or log q = c - d cos(theta) where q1 > 0 (a wide orbit's
            # q ~ 0 singularities then lie far from the real theta axis)
            logmap = q1 > 0
            e1, e2 = (mp.log(q1), mp.log(q2)) if logmap else (q1, q2)
            c, d = (e1 + e2) / 2, (e2 - e1) / 2

            def qmap(th):
                """(q, dq/dtheta)."""
                x = c - d * mp.cos(th)
                return (mp.exp(x), mp.exp(x) * d * mp.sin(th)) if logmap else (x, d * mp.sin(th))

            def Bt(th):
                q, dq = qmap(th)
                Bq = self.B(q)
                return ((0, Bq[0][1] * dq), (Bq[1][0] * dq, 0))

            def f(th, y):
                """(dT, dpsi)/dtheta = (2, L_z/(M rho^2)) (ds/dq)(dq/dtheta)/|u|; at the ends,
                where q - q_t ~ J theta^2/2, the limit (ds/dq) sqrt(2 J/|d(u^2)/dq|)."""
                q, dq = qmap(th)
                rc, _, _, _, _, ds = self.geo(q)
                if th == 0:
                    w = ds * mp.sqrt(2 * d * (q1 if logmap else 1) / self.du2(q1, y))
                elif th == mp.pi:
                    w = ds * mp.sqrt(2 * d * (q2 if logmap else 1) / -self.du2(q2, y))
                else:
                    w = ds * dq / mp.sqrt(self.u2(q, y))
                return (2 * w, y[0] / (self.M * rc**2) * w)

            # The integrand in theta is even and 2 pi-periodic, so the trapezoidal rule converges
            # geometrically: each doubling of n squares its error. (L_z, w) is carried from node
            # to node by one collocation step each, from the pericentre; n doubles until the
            # carried values meet the apocentre's within the tolerance and two rules agree to
            # its square root (the finer one is then good to the tolerance).
            tol, n, Q = self._tol(), 4, None
            while True:
                n *= 2
                h = mp.pi / n
                ys = [y1]
                for i in range(n):
                    ys.append(gl_step(Bt, i * h, ys[-1], h))
                miss = self._norm(ys[-1], y2)
                ys[-1] = y2
                fs = [f(i * h, y) for i, y in enumerate(ys)]
                Qn = [h * (fs[0][m] / 2 + fs[-1][m] / 2 + mp.fsum(x[m] for x in fs[1:-1]))
                      for m in (0, 1)]  # fmt: skip
                if Q is not None:
                    e = max(abs(Qn[m] - Q[m]) / abs(Qn[m]) for m in (0, 1))
                    if miss <= tol and e <= mp.sqrt(tol):
                        break
                if n >= 2048:
                    raise RuntimeError("the quadrature in theta did not converge")
                Q = Qn
            self.err = max(self.err, miss, e**2)
            g1, g2 = self.geo(q1), self.geo(q2)
            return {"cls": "bounded", "q1": q1, "q2": q2, "rho_min": g1[0], "rho_max": g2[0],
                    "z_min": g1[1], "z_max": g2[1], "period": Qn[0], "apsidal_angle": Qn[1],
                    "E": self.E, "Lz_peri": y1[0], "w_peri": y1[1], "Lz_apo": y2[0],
                    "w_apo": y2[1], "err": self.err}  # fmt: skip

    def leg(self, qt, yt, qe):
        """(time, azimuth swept) from the turning point (qt, yt) to qe, along
        q = qt + (qe - qt)(1 - cos theta), theta in [0, pi/2], by Gauss-Legendre quadrature."""
        with mp.workdps(WORK):
            qt, qe = mp.mpf(qt), mp.mpf(qe)
            D = qe - qt

            def Bt(th):
                Bq = self.B(qt + D * (1 - mp.cos(th)))
                f = D * mp.sin(th)
                return ((0, Bq[0][1] * f), (Bq[1][0] * f, 0))

            def f(th, y):
                q = qt + D * (1 - mp.cos(th))
                rc, _, _, _, _, ds = self.geo(q)
                w = ds * abs(D) * mp.sin(th) / mp.sqrt(self.u2(q, y))
                return (w, y[0] / (self.M * rc**2) * w)

            old, n = None, 8
            while True:  # n Gauss-Legendre nodes in theta, n doubled (the error squares)
                n *= 2
                c, b = _nodes(n, WORK)
                H = mp.pi / 2
                x, y, Q = mp.mpf(0), yt, [mp.mpf(0), mp.mpf(0)]
                for ci, bi in zip(c, b, strict=True):
                    y = gl_step(Bt, x, y, ci * H - x)
                    x = ci * H
                    fv = f(x, y)
                    Q = [Q[m] + H * bi * fv[m] for m in (0, 1)]
                if old is not None:
                    e = max(abs(Q[m] - old[m]) / abs(Q[m]) for m in (0, 1) if Q[m] != 0)
                    if e <= mp.sqrt(self._tol()):
                        break
                if n >= 512:
                    raise RuntimeError("the leg's quadrature did not converge")
                old = Q
            self.err = max(self.err, e**2)
            return Q[0], Q[1]


def transport(surface, M, a, k, q_from, q_to, Lz, w):
    """(L_z, w) at q_to of the solution of the meridian ODE through (L_z, w) at q_from."""
    with mp.workdps(WORK):
        r = Reduction(surface, M, 0, a, k, q0=q_from, v0=0, w0=w)
        r.y0 = (mp.mpf(Lz), mp.mpf(w))
        r.vs = max(abs(r.y0[0]) / (r.M * r.rho0), abs(r.y0[1]), mp.mpf(10) ** -WORK)
        return r.advance(r.B, r.q0, r.y0, mp.mpf(q_to), (mp.mpf(q_to) - r.q0) / 8)

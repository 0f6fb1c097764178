"""An independent rigid-body model of a sphere rolling on the inside of a surface of revolution,
for the tests (nothing from engine/).

**Surfaces.** Each is the surface the ball touches, given by its meridian (R(q), Z(q)) in a
parameter q that increases up the wall: `Graph(f, df, d2f)` for z = f(rho) (q = rho, the
touching point's distance from the axis), `Parametric(...)` for any (rho(q), z(q)), and the named
ones: `Cone(alpha)` z = rho cot(alpha), `Bowl(R)` the sphere of radius R with its bottom at z = 0,
`Paraboloid(R)` z = rho^2/(2R), `Funnel(scale, hole)` z = -scale/rho for rho >= hole,
`PowerLaw(scale, n)` z = scale rho^n, `Cylinder(R)` the wall rho = R (q = z). Their functions
take a float or an mpmath number (tests/routh_reference.py evaluates them at 40 digits); user
callables must too. The ball is on the side the normal (-Z', R')/|P'| points to: up for a
graph, towards the axis for the cylinder. `mathlib(q)` and `lift(q, ...)` help a profile's
callables do that (its constants combined at q's precision).

**Model** (k > 0: I = k M a^2 divides). Cartesian state: the centre X, its velocity V, the
angular velocity Omega (fixed frame), and the azimuth phi of the centre (integrated,
dphi/dt = (X x V)_z / rho^2). The centre stays on the offset surface (the touching surface moved
by a along its normal): the contact point P(q) is the foot of X on the meridian,
(rho - R) R' + (z - Z) Z' = 0 solved by Newton, and dq/dt follows by implicit differentiation.
With n the unit normal at P (from the contact point to the centre), d(n . V)/dt = 0 gives
n . A = -dn/dt . V, hence the normal force
N = M (g n_z - dn/dt . V). Rolling: the contact point's velocity S = V - a Omega x n stays zero;
with M A = -M g z + N n + F and I dOmega/dt = -a n x F + T_rr (I = k M a^2, F tangential),
the tangential part of dS/dt = 0 is linear in F and solved for it. Rolling resistance is the
couple T_rr = -c_rr N a Omega_t/|Omega_t| (Omega_t = Omega - (Omega . n) n), as
tests/hybrid_oracle.py models it on the cone. scipy's DOP853 at rtol 1e-12, atol 1e-14 times
each component's scale, stepped by hand with the events located on its dense output (brentq).

**Events.** Turning points of the meridian coordinate (u = V . t = 0, t the meridian's unit
tangent up the wall): `peri` where u turns from - to + (rho_min of the centre; the lowest
point; on the cylinder the lowest z), `apo` from + to -. Terminal (the fate): `rim` (the contact
point reaches height `rim_z` or distance `rim_rho` from the axis), `hole` (the contact point
reaches the funnel's hole), `left_surface` (N <= 0), `slipped` (|F| > mu N), `no_fit` (the
meridian's curvature nears 1/a: 1 - a kappa <= 1e-3; the centre's surface has a cusp where it
is 0, approached like sqrt(time), dq/dt ~ 1/(1 - a kappa)), `vertex` (the centre within
`vertex_rho` of
the axis), `rest` (with c_rr > 0 the speed falls to 1e-9 of its scale; carried on to zero at the
rate it falls, then held if tan(b) <= c_rr and tan(b) <= mu, b the slope angle, else the ball
starts again from rest), or `rolling` at the horizon.

**Launch convention** (the engine's): the centre at distance `rho0` [m] from the axis at
azimuth 0 (on the cylinder at height `z0`, rho0 = R - a), velocity V = u0 t + v0 e_phi with
v0 [m/s] along the parallel (counter-clockwise seen from above positive) and u0 [m/s] along the
meridian tangent t (up the wall positive; 0 unless given), rolling, and spin w0 = a Omega . n
[m/s] with n from the contact point to the centre: Omega = (-v0 t + u0 e_phi + w0 n)/a.

**Outputs** (`Run`): the time series (t, state), turning points with rho_min/rho_max of the
centre, the radial period (pericentre to pericentre), the apsidal angle (azimuth swept from a
pericentre to the next apocentre), the energy E = M V^2/2 + I Omega^2/2 + M g X_z, L_z = M (X x V)_z
(the centre's; on the cone the engine's L_z), the whole ball's L_ball = L_z + I Omega_z, the spin
w = a Omega . n (`series`), the fate and its time. The apsidal angle is signed (the azimuth swept,
counter-clockwise positive; L_z may change sign along an orbit on a curved meridian).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mpmath as mp
import numpy as np
from scipy.integrate import DOP853
from scipy.optimize import brentq


def mathlib(q):
    """The module of functions for q's kind of number: mpmath for mpmath numbers, else math."""
    return mp if isinstance(q, mp.mpf | mp.mpc) else math


def lift(q, *xs):
    """Constants as numbers of q's kind (mpmath for mpmath q), so that a meridian evaluated at
    40 digits combines its float parameters at 40 digits, not in double precision."""
    if mathlib(q) is mp:
        return tuple(mp.mpf(x) for x in xs)
    return xs


# ------------------------------------------------------------------------- surfaces
class Meridian:
    """The touching surface's meridian (R(q), Z(q)) for q in [q_lo, q_hi]."""

    q_lo = -math.inf
    q_hi = math.inf
    hole = None  # touching rho of a hole at the bottom (the funnel's)

    def at(self, q):
        """(R, Z, R', Z', R'', Z'') at q (float or mpmath)."""
        raise NotImplementedError

    def guess(self, rho, z):
        """Where to start looking for the foot of the point (rho, z): the nearest of a sampling."""
        lo = self.q_lo if math.isfinite(self.q_lo) else -10.0
        hi = self.q_hi if math.isfinite(self.q_hi) else 10.0
        qs = np.linspace(lo, hi, 4001)[1:-1]
        return float(min(qs, key=lambda q: math.hypot(self.at(q)[0] - rho, self.at(q)[1] - z)))


class Graph(Meridian):
    """z = f(rho) with its first two derivatives (q = the touching point's rho)."""

    def __init__(self, f=None, df=None, d2f=None, q_lo=0.0, q_hi=math.inf, name="profile"):
        self.f, self.df, self.d2f = f, df, d2f
        self.q_lo, self.q_hi, self.name = q_lo, q_hi, name

    def at(self, q):
        return q, self.f(q), 1, self.df(q), 0, self.d2f(q)

    def guess(self, rho, z):
        return min(max(rho, self.q_lo), self.q_hi)

    def __repr__(self):
        return self.name


class Parametric(Meridian):
    """(rho(q), z(q)) with derivatives; the ball lies to the left of the direction of travel."""

    def __init__(self, r, z, dr, dz, d2r, d2z, q_lo=-math.inf, q_hi=math.inf, name="meridian"):
        self.fns = (r, z, dr, dz, d2r, d2z)
        self.q_lo, self.q_hi, self.name = q_lo, q_hi, name

    def at(self, q):
        return tuple(fn(q) for fn in self.fns)

    def __repr__(self):
        return self.name


class Cone(Graph):
    def __init__(self, alpha):
        self.alpha = alpha
        super().__init__(q_lo=0.0, name=f"Cone({alpha})")

    def at(self, q):
        (alpha,) = lift(q, self.alpha)
        cot = 1 / mathlib(q).tan(alpha)
        return q, q * cot, 1, cot, 0, 0


class Bowl(Graph):
    def __init__(self, radius):
        self.R = radius
        super().__init__(q_lo=0.0, q_hi=radius, name=f"Bowl({radius})")

    def at(self, q):
        (R,) = lift(q, self.R)
        s = mathlib(q).sqrt(R * R - q * q)
        return q, R - s, 1, q / s, 0, R * R / s**3


class Paraboloid(Graph):
    def __init__(self, radius):
        self.R = radius
        super().__init__(q_lo=0.0, name=f"Paraboloid({radius})")

    def at(self, q):
        (R,) = lift(q, self.R)
        return q, q * q / (2 * R), 1, q / R, 0, 1 / R


class Funnel(Graph):
    def __init__(self, scale, hole):
        self.scale, self.hole = scale, hole
        super().__init__(q_lo=hole, name=f"Funnel({scale}, {hole})")

    def at(self, q):
        (c,) = lift(q, self.scale)
        return q, -c / q, 1, c / q**2, 0, -2 * c / q**3


class PowerLaw(Graph):
    def __init__(self, scale, n):
        self.scale, self.n = scale, n
        super().__init__(q_lo=0.0, name=f"PowerLaw({scale}, {n})")

    def at(self, q):
        c, n = lift(q, self.scale, self.n)
        return q, c * q**n, 1, n * c * q ** (n - 1), 0, n * (n - 1) * c * q ** (n - 2)


class Cylinder(Parametric):
    def __init__(self, radius):
        self.R = radius
        self.q_lo, self.q_hi, self.name = -math.inf, math.inf, f"Cylinder({radius})"

    def at(self, q):
        (R,) = lift(q, self.R)
        return R, q, 0, 1, 0, 0

    def guess(self, rho, z):
        return z


# ------------------------------------------------------------------------- the model
class FootError(ArithmeticError):
    """The centre has no contact point a away on the meridian (past a fit limit)."""


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@dataclass
class Run:
    """What one launch did (module docstring, "Outputs")."""

    t: np.ndarray
    y: np.ndarray
    turns: list = field(default_factory=list)  # (kind, t, rho, z, phi, state)
    fate: str = "rolling"
    fate_time: float = math.nan
    fate_state: np.ndarray | None = None
    rests: list = field(default_factory=list)  # times the ball stopped and was not held

    def _times(self, kind):
        return [tp for tp in self.turns if tp[0] == kind]

    @property
    def rho_min(self):
        return min((tp[2] for tp in self.turns), default=math.nan)

    @property
    def rho_max(self):
        return max((tp[2] for tp in self.turns), default=math.nan)

    @property
    def period(self):
        p = self._times("peri")
        return p[1][1] - p[0][1] if len(p) >= 2 else math.nan

    @property
    def apsidal_angle(self):
        p = self._times("peri")
        if not p:
            return math.nan
        later = [tp for tp in self._times("apo") if tp[1] > p[0][1]]
        return later[0][4] - p[0][4] if later else math.nan


class SurfaceOracle:
    """A sphere (M, a, I = k M a^2) rolling on the inside of `surface` under gravity g."""

    def __init__(self, surface, M=1.0, g=9.81, a=0.01, k=0.4, mu=math.inf, c_rr=0.0,
                 rim_z=None, rim_rho=None, vertex_rho=None, rtol=1e-12):  # fmt: skip
        self.S, self.M, self.g, self.a, self.k = surface, M, g, a, k
        self.I = k * M * a * a
        self.mu, self.c_rr, self.rtol = mu, c_rr, rtol
        self.rim_z, self.rim_rho, self.vertex_rho = rim_z, rim_rho, vertex_rho
        self._q = None

    # ------------------------------------------------------------- geometry
    def foot(self, rho, z):
        """The contact point's parameter q: the foot of the centre (rho, z) on the meridian, by
        Newton from the last one (or from the meridian's guess), a distance a away."""
        for attempt in range(2):
            q = self._q if attempt == 0 else self.S.guess(rho, z)
            try:
                for _ in range(100):
                    R, Z, R1, Z1, R2, Z2 = self.S.at(q)
                    phi = (rho - R) * R1 + (z - Z) * Z1
                    dphi = -(R1 * R1 + Z1 * Z1) + (rho - R) * R2 + (z - Z) * Z2
                    dq = phi / dphi
                    noise = 1e-15 * (abs((rho - R) * R1) + abs((z - Z) * Z1))
                    if abs(phi) > noise:  # near a fit limit dphi -> 0: stop at phi's rounding
                        q -= dq
                    if abs(dq) <= 1e-15 * (abs(q) + self.a) or abs(phi) <= noise:
                        R, Z = self.S.at(q)[:2]
                        if abs(math.hypot(rho - R, z - Z) - self.a) <= 1e-3 * self.a:
                            return q
                        break
            except (ValueError, ZeroDivisionError, OverflowError):
                pass
        raise FootError(f"no contact point for the centre at rho={rho}, z={z}")

    def centre_at(self, q):
        """(rho, z) of the centre when the contact point is at q."""
        R, Z, R1, Z1, _, _ = self.S.at(q)
        m = math.hypot(R1, Z1)
        return R - self.a * Z1 / m, Z + self.a * R1 / m

    def evaluate(self, y):
        """Everything the right-hand side and the events need at state y."""
        X, V, W = y[0:3], y[3:6], y[6:9]
        rho = math.hypot(X[0], X[1])
        e = (X[0] / rho, X[1] / rho) if rho > 0.0 else (1.0, 0.0)
        q = self.foot(rho, X[2])
        self._q = q
        R, Z, R1, Z1, R2, Z2 = self.S.at(q)
        m2 = R1 * R1 + Z1 * Z1
        m = math.sqrt(m2)
        nm = (-Z1 / m, R1 / m)
        tm = (R1 / m, Z1 / m)
        dproj = (R1 * R2 + Z1 * Z2) / m2
        dnm = (-Z2 / m - nm[0] * dproj, R2 / m - nm[1] * dproj)
        dtm = (R2 / m - tm[0] * dproj, Z2 / m - tm[1] * dproj)
        n = (nm[0] * e[0], nm[0] * e[1], nm[1])
        t = (tm[0] * e[0], tm[0] * e[1], tm[1])
        rhod = V[0] * e[0] + V[1] * e[1]
        dphi = -m2 + (rho - R) * R2 + (X[2] - Z) * Z2
        qd = -(R1 * rhod + Z1 * V[2]) / dphi
        de = ((V[0] - rhod * e[0]) / rho, (V[1] - rhod * e[1]) / rho) if rho > 0 else (0, 0)
        nd = (dnm[0] * qd * e[0] + nm[0] * de[0], dnm[0] * qd * e[1] + nm[0] * de[1], dnm[1] * qd)
        td = (dtm[0] * qd * e[0] + tm[0] * de[0], dtm[0] * qd * e[1] + tm[0] * de[1], dtm[1] * qd)
        M, a, g, k = self.M, self.a, self.g, self.k
        N = M * (g * nm[1] - _dot(nd, V))
        wn = _dot(W, n)
        Wt = (W[0] - wn * n[0], W[1] - wn * n[1], W[2] - wn * n[2])
        wt = math.sqrt(_dot(Wt, Wt))
        T = (0.0, 0.0, 0.0)
        if self.c_rr > 0.0 and wt > 0.0:
            c = -self.c_rr * N * a / wt
            T = (c * Wt[0], c * Wt[1], c * Wt[2])
        # dS/dt = -g z + N n/M + F (1/M + a^2/I) - (a/I) T x n - a Omega x dn/dt: its
        # tangential part vanishes for this F (F tangential, (n x F) x n = F).
        Txn = _cross(T, n)
        Wxnd = _cross(W, nd)
        b = [-a / self.I * Txn[i] - a * Wxnd[i] for i in range(3)]
        b[2] -= g
        bn = _dot(b, n)
        f = -M * k / (1 + k)
        F = tuple(f * (b[i] - bn * n[i]) for i in range(3))
        A = tuple((N * n[i] + F[i]) / M for i in range(3))
        A = (A[0], A[1], A[2] - g)
        aF = _cross(n, F)
        Wd = tuple((-a * aF[i] + T[i]) / self.I for i in range(3))
        kap = (R1 * Z2 - Z1 * R2) / m**3
        return dict(q=q, R=R, Z=Z, rho=rho, n=n, nm=nm, t=t, N=N, F=F, A=A, Wd=Wd,
                    u=_dot(V, t), ud=_dot(A, t) + _dot(V, td), fit=1.0 - a * kap,
                    tanb=Z1 / R1 if R1 else math.inf)  # fmt: skip

    def rhs(self, t, y):
        ev = self.evaluate(y)
        X, V = y[0:3], y[3:6]
        rho2 = X[0] * X[0] + X[1] * X[1]
        phid = (X[0] * V[1] - X[1] * V[0]) / rho2 if rho2 > 0.0 else 0.0
        return np.array([*V, *ev["A"], *ev["Wd"], phid])

    # ------------------------------------------------------------- invariants
    def energy(self, y):
        V, W = y[3:6], y[6:9]
        return 0.5 * self.M * _dot(V, V) + 0.5 * self.I * _dot(W, W) + self.M * self.g * y[2]

    def Lz(self, y):
        return self.M * (y[0] * y[4] - y[1] * y[3])

    def L_ball(self, y):
        return self.Lz(y) + self.I * y[8]

    def spin(self, y):
        return self.a * _dot(y[6:9], self.evaluate(y)["n"])

    def slip(self, y):
        n = self.evaluate(y)["n"]
        Wxn = _cross(y[6:9], n)
        return tuple(y[3 + i] - self.a * Wxn[i] for i in range(3))

    def series(self, run: Run) -> dict:
        """The run's time series as arrays: t, rho, z, phi (centre), E, Lz, L_ball, w (spin),
        N (normal force)."""
        out = {"t": run.t, "rho": np.hypot(run.y[:, 0], run.y[:, 1]), "z": run.y[:, 2],
               "phi": run.y[:, 9]}  # fmt: skip
        for name, fn in (("E", self.energy), ("Lz", self.Lz), ("L_ball", self.L_ball),
                         ("w", self.spin), ("N", lambda y: self.evaluate(y)["N"])):  # fmt: skip
            out[name] = np.array([fn(y) for y in run.y])
        return out

    def offset(self, y):
        """(X - P) . n - a: 0 on the constraint (P the contact point)."""
        ev = self.evaluate(y)
        return (ev["rho"] - ev["R"]) * ev["nm"][0] + (y[2] - ev["Z"]) * ev["nm"][1] - self.a

    # ------------------------------------------------------------- launch and run
    def launch(self, rho0=None, v0=0.0, w0=0.0, u0=0.0, q0=None):
        """The state of the launch convention (module docstring); `q0` (the contact point's
        parameter) instead of rho0 on a parametric meridian (the cylinder's q is the height)."""
        if q0 is None:
            if isinstance(self.S, Parametric):
                raise ValueError("a parametric meridian takes the launch point as q0")

            def f(q):
                return self.centre_at(q)[0] - rho0

            lo, hi = rho0, min(self.S.q_hi * (1 - 1e-12), rho0 + self.a)
            if f(lo) > 0:  # a meridian that slopes down: the contact lies inward
                lo, hi = max(self.S.q_lo, rho0 - self.a), rho0
            q0 = brentq(f, lo, hi, xtol=1e-300, rtol=8.9e-16)
        R, Z, R1, Z1, _, _ = self.S.at(q0)
        m = math.hypot(R1, Z1)
        t, n = (R1 / m, 0.0, Z1 / m), (-Z1 / m, 0.0, R1 / m)
        rc, zc = self.centre_at(q0)
        self._q = q0
        V = (u0 * t[0], v0, u0 * t[2])
        W = tuple((-v0 * t[i] + w0 * n[i]) / self.a for i in range(3))
        W = (W[0], u0 / self.a, W[2])
        return np.array([rc, 0.0, zc, *V, *W, 0.0])

    def _events(self, vs):
        ev = [("turn", lambda e, y: e["u"], 0, False)]
        if self.rim_z is not None:
            ev.append(("rim", lambda e, y: e["Z"] - self.rim_z, 1, True))
        if self.rim_rho is not None:
            ev.append(("rim", lambda e, y: e["R"] - self.rim_rho, 1, True))
        if self.S.hole is not None:
            ev.append(("hole", lambda e, y: e["R"] - self.S.hole, -1, True))
        ev.append(("left_surface", lambda e, y: e["N"], -1, True))
        if math.isfinite(self.mu):
            ev.append(("slipped", lambda e, y: math.sqrt(_dot(e["F"], e["F"])) - self.mu * e["N"],
                       1, True))  # fmt: skip
        ev.append(("no_fit", lambda e, y: e["fit"] - 1e-3, -1, True))
        if self.vertex_rho is not None:
            ev.append(("vertex", lambda e, y: e["rho"] - self.vertex_rho, -1, True))
        if self.c_rr > 0.0:
            ev.append(("rest", lambda e, y: math.sqrt(_dot(y[3:6], y[3:6])) - 1e-9 * vs, -1, True))
        return ev

    def run(self, y0, t_end, periods=None, max_steps=200_000):
        """Integrate from y0 (t = 0) to t_end, to the fate, or to the (periods + 1)-th
        pericentre; a `Run`."""
        y0 = np.asarray(y0, float)
        scale = max(math.sqrt(_dot(y0[0:3], y0[0:3])), self.a)
        vs = max(math.sqrt(_dot(y0[3:6], y0[3:6])), abs(self.spin(y0)), math.sqrt(self.g * scale))
        atol = 1e-2 * self.rtol * np.array([scale] * 3 + [vs] * 3 + [vs / self.a] * 3 + [1.0])
        events = self._events(vs)
        out = Run(t=np.empty(0), y=np.empty((0, 10)))
        ts, ys = [0.0], [y0]
        t, y = 0.0, y0
        while True:  # from the launch, and again from each stop the resistance cannot hold
            g_old, fired = self._start(out, events, t, y, vs)
            if fired:
                return self._finish(out, ts, ys, fired, t, y)
            solver = DOP853(self.rhs, t, y, t_end, rtol=self.rtol, atol=atol)
            h = None
            for _ in range(max_steps):
                try:
                    msg = solver.step()
                except FootError:  # a stage past a fit limit: again from the last step, shorter
                    h = (h or solver.step_size or 1e-3 * (t_end - solver.t)) / 4
                    if h <= 1e-15 * max(1.0, abs(solver.t)):
                        raise
                    solver = DOP853(self.rhs, solver.t, solver.y, t_end, rtol=self.rtol,
                                    atol=atol, max_step=h, first_step=h)  # fmt: skip
                    continue
                if msg is not None or solver.status == "failed":
                    raise RuntimeError(f"the integration failed: {msg}")
                e = self.evaluate(solver.y)
                g_new = [fn(e, solver.y) for _, fn, _, _ in events]
                restart = None
                for te, name, term, kind, ye in self._crossings(solver, events, g_old, g_new):
                    if not term:
                        out.turns.append(self._turn(kind, te, ye))
                        if periods is not None and len(out._times("peri")) > periods:
                            ts.append(te)
                            ys.append(ye)
                            return self._finish(out, ts, ys, "rolling", te, ye, math.nan)
                    elif name != "rest":
                        return self._finish(out, ts, ys, name, te, ye)
                    else:
                        restart = self._rest(out, te, ye)
                        if restart is None:  # held
                            return self._finish(out, ts, ys, "rest", out.rests.pop(), ye)
                        break
                if restart is not None:
                    t, y = restart
                    ts.append(t)
                    ys.append(y)
                    break
                ts.append(solver.t)
                ys.append(solver.y)
                g_old = g_new
                if solver.status == "finished":
                    return self._finish(out, ts, ys, "rolling", solver.t, solver.y, math.nan)
            else:
                raise RuntimeError("step budget exhausted")

    def _start(self, out, events, t, y, vs):
        """The event functions at a start, and the fate if one holds there already. A start at
        a turning point (u = 0) is one, of the kind the sign of du/dt says."""
        e = self.evaluate(y)
        g = [fn(e, y) for _, fn, _, _ in events]
        if abs(e["u"]) <= 1e-14 * vs:
            out.turns.append(self._turn("peri" if e["ud"] > 0 else "apo", t, y))
            g[0] = math.copysign(1e-300, e["ud"])
        for (name, _, d, term), gv in zip(events, g, strict=True):
            if term and name != "rest" and (gv <= 0 if d < 0 else gv >= 0):
                return g, name
        return g, None

    def _crossings(self, solver, events, g_old, g_new):
        """The events in the last step, located on its dense output, in time order:
        (t, name, terminal, kind, state)."""
        found = []
        for (name, fn, d, term), a, b in zip(events, g_old, g_new, strict=True):
            if (a < 0 <= b and d >= 0) or (a > 0 >= b and d <= 0):
                sol = solver.dense_output()

                def h(s, fn=fn, sol=sol):
                    ys_ = sol(s)
                    return fn(self.evaluate(ys_), ys_)

                te = solver.t
                if b != 0:
                    te = brentq(h, solver.t_old, solver.t, xtol=1e-15 * max(1.0, abs(te)),
                                rtol=8.9e-16)  # fmt: skip
                found.append((te, name, term, "peri" if b > a else "apo", sol(te)))
        return sorted(found, key=lambda f: f[0])

    def _rest(self, out, te, ye):
        """The stop: carried on to zero speed at the rate the speed falls; None if held there,
        else (t, the state at rest) to start again from."""
        e = self.evaluate(ye)
        V = ye[3:6]
        sp = math.sqrt(_dot(V, V))
        rate = _dot(V, e["A"]) / sp
        t0 = te + sp / -rate if rate < 0 else te
        out.rests.append(t0)
        if e["tanb"] <= self.c_rr and e["tanb"] <= self.mu:
            return None
        y = ye.copy()
        n = e["n"]
        wn = _dot(ye[6:9], n)
        y[3:6] = 0.0
        y[6:9] = [wn * n[i] for i in range(3)]
        return t0, y

    def _turn(self, kind, t, y):
        return (kind, t, math.hypot(y[0], y[1]), y[2], y[9], np.array(y))

    def _finish(self, out, ts, ys, fate, t, y, fate_time=None):
        out.t, out.y = np.array(ts), np.array(ys)
        out.fate = fate
        out.fate_time = t if fate_time is None else fate_time
        out.fate_state = np.asarray(y)
        return out

"""An independent rigid-body model of a sphere on the inside of a surface of revolution that
rolls AND slides, with Coulomb friction, for the tests (nothing from engine/).

It generalises tests/hybrid_oracle.py (the cone) to any meridian of tests/surface_oracle.py
(`Graph`, `Parametric`, `Cone`, `Bowl`, `Paraboloid`, `Funnel`, `PowerLaw`, `Cylinder`, whose
classes, foot-point Newton and launch placement it reuses), and mirrors its event semantics and
interface (`run(y0, mode, t_end, speed)` -> (events, final state, final mode), `fate`,
`t_fate`), so that the same test code can drive both. Rolling resistance (c_rr) is left out:
`c_rr != 0` is refused with ValueError (hybrid_oracle's tangential-spin stick, the stop and the
rest that go with it are therefore absent too: without c_rr its ball never comes to `rest`).

**State** (12 numbers, fixed frame): the centre X, its velocity V, the angular velocity Omega,
the centre's azimuth phi (dphi/dt = (X x V)_z / rho^2), and the works done against friction,
W_slide (kinetic friction at the contact, plus the sticking impulses' losses) and W_spin (spin
friction), integrated along with the motion so that E + W_slide + W_spin stays E(0).

**Model** (Newton-Euler in Cartesian coordinates; M, radius a, I = k M a^2, k > 0). The centre
stays on the offset surface (the touching surface moved by a along its normal): the contact
point P(q) is the foot of X on the meridian (surface_oracle's Newton), n the unit normal there
(from P to the centre; also the offset surface's normal at X), dn/dt from dq/dt by implicit
differentiation of the foot condition. The contact force is N n + f, f tangential; the couple
of spin friction T = T_n n (along n). Then

    M dV/dt = -M g z + N n + f,     I dOmega/dt = (-a n) x f + T,

and d(n . V)/dt = 0 (contact kept) gives N = M (g n_z - dn/dt . V) (f and T do not enter it).
The slip (the contact point's velocity) is S = V - a Omega x n (tangential on the constraint).

- sliding: f = -mu_k N S_t/|S_t|; at a slip start (S = 0) f = mu_k N d, d the direction of the
  rolling force at the slip (hybrid_oracle's `start_dir`), projected on the tangent plane;
- rolling: f such that the tangential part of dS/dt vanishes. dS/dt = b + f (1/M + a^2/I) with
  b = -g z + N n/M - a Omega x dn/dt - (a/I) T x n (for tangential f, ((-a n) x f) x n = -a f),
  so the 2x2 system in any tangent basis is (1 + k)/(k M) times the identity: f = -k M b_t/(1+k)
  (T is along n: T x n = 0). Static friction holds while |f| <= mu N;
- spin friction: T_n = -c_spin a N s while the spin about the normal turns the way s = +-1
  (the stretch's, fixed between spin events: Omega . n has that sign there, and the stretch
  ends where it reaches zero); the contact force's torque is tangential, so
  d(Omega . n)/dt = T_n/I + Omega . dn/dt, and the couple that holds Omega . n at zero is
  T_hold = -I Omega . dn/dt (the spin stick). s is not read from Omega . n itself (hybrid_oracle
  does): that field jumps at Omega . n = 0, and where the spin should stick there
  (|T_hold| < c_spin a N) both sides push it back to zero, so the steps crawl along it (a
  Filippov sliding mode) and their ends never reach zero (Omega . n ~ 1e-11 rad/s, steps ~1e-12 s,
  each spin stop on Funnel(0.05, 0.03) exhausted the step budget). With s fixed the field is
  smooth in a stretch and Omega . n crosses zero where the event is located (the same event
  times: they agree with hybrid_oracle's within 5e-12 relative on the cones).

The power of the contact force is f . S and that of the couple T . Omega (N n . S = N n . V = 0):
dW_slide/dt = -f . S, dW_spin/dt = -T . Omega. The sticking impulse J = -k M S_t/(1+k) (the
return to rolling) loses k M |S_t|^2/(2(1+k)), booked to W_slide. (Numerically V . n drifts by
the integration's error, and N V . n, unbooked, is nearly all the balance's error: on
Funnel(0.05, 0.03), N ~ 12 M g and V . n ~ 5e-12 of the speed, 6e-10 of the energy in 2 s.)

**Events** (hybrid_oracle's semantics; EPS = 1e-9 of the launch's speed scale `speed`):

- `slip`: rolling, the friction needed reaches mu N (also at a stretch's start if beyond);
- `roll`: sliding, |S_t| falls to EPS: the sticking impulse; a return only if static friction
  then holds the rolling (else it slides on from the unstuck state, not recorded). A return is
  armed again only once |S_t| has exceeded 2 EPS. (hybrid_oracle measures |S|; S . n = V . n is
  only the constraint's drift, ~1e-12 of the speed, but a model whose forces push V off the
  tangent plane would otherwise never reach EPS and chatter at S_t = 0);
- `spin_stop` (c_spin > 0): Omega . n reaches zero (projected to exactly zero there); it stays
  stuck if |T_hold| <= c_spin a N (1 + 1e-9), else turns the way -T_hold points (at a stop the
  spin passes through: the other way);
- `spin_go`: stuck, |T_hold| reaches c_spin a N (1 + 1e-9); it turns the way -T_hold points.
  A spin that turns from zero (after `spin_go`, a reversal, or a launch with Omega . n = 0 that
  cannot stick) has its stop armed once |a Omega . n| has exceeded 2 EPS (as the return to
  rolling): it leaves zero with zero slope after `spin_go`, so the first steps' Omega . n is
  rounding (~1e-16 |Omega|) and could fake a stop; before that a fall to -2 EPS the wrong way
  is a stop;
- terminal: `spill` (the contact point reaches `rim_rho` from the axis, height `rim_z` or
  meridian parameter `rim_q`; fate `spilled`), `vertex` (the centre within `vertex_rho` of the
  axis; on a `Cone` it defaults to a sin(alpha)/100, hybrid_oracle's |X| < a/100, elsewhere off),
  `left_surface` (N falls to 0: rolling or sliding, the ball leaves the wall), `hole` (the
  contact point reaches the funnel's hole), `no_fit` (1 - a kappa falls to 1e-3, surface_oracle's
  fit limit).

The fate (`fate`, at `t_fate`): the mode at t_end ("rolling" / "sliding"), or the terminal
event's ("spilled", "vertex", "left_surface", "hole", "no_fit").

scipy's DOP853 at rtol 1e-12 (atol 1e-2 rtol times each component's scale), stepped by hand
(a stage past a fit limit is retried with a shorter step, as surface_oracle does) with the
events located on its dense output by brentq (solve_ivp's rules: a rise is g from <= 0 to >= 0).

**Launch** (`launch`, the engine's convention with a slip): the centre at distance `rho0` from
the axis (or the contact point at `q0`), azimuth 0, V = u0 t + v0 e_phi, and
Omega = ((slip_v - v0) t + (u0 - slip_u) e_phi + w0 n)/a, so that S = slip_u t + slip_v e_phi
(t the meridian's unit tangent up the wall, n the normal towards the centre). On `Cone(alpha)`
this is hybrid_oracle's start_state with the centre's cone moved up by a/sin(alpha): see
`cone_state`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import DOP853
from scipy.optimize import brentq
from surface_oracle import Cone, FootError, SurfaceOracle

#: Thresholds of the switches, relative to the launch's speed scale (hybrid_oracle's).
EPS = 1e-9
_FEPS = np.finfo(float).eps


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(a):
    return math.sqrt(_dot(a, a))


def _tangential(v, n):
    c = _dot(v, n)
    return (v[0] - c * n[0], v[1] - c * n[1], v[2] - c * n[2])


def cone_state(y_cone, alpha, a):
    """This model's 12-number state of hybrid_oracle's 9-number cone state (its centre's cone
    has its vertex at the origin; here the touching cone does, the centre's one is a/sin(alpha)
    higher): X moved up, V and Omega as they are, phi the azimuth, no work done yet."""
    y = np.zeros(12)
    y[0:9] = y_cone[0:9]
    y[2] += a / math.sin(alpha)
    y[9] = math.atan2(y[1], y[0])
    return y


class SlideOracle:
    """A sphere (M, a, I = k M a^2) rolling and sliding on the inside of `surface` (a Meridian
    of tests/surface_oracle.py) under gravity g, with static friction mu, kinetic mu_k and spin
    friction c_spin (module docstring)."""

    def __init__(self, surface, M=1.0, g=9.81, a=0.01, k=0.4, mu=math.inf, mu_k=0.0, c_rr=0.0,
                 c_spin=0.0, rim_rho=None, rim_z=None, rim_q=None, vertex_rho=None,
                 rtol=1e-12):  # fmt: skip
        if c_rr != 0.0:
            raise ValueError("rolling resistance is not modelled here (c_rr must be 0)")
        if not (k > 0 and a > 0 and M > 0):
            raise ValueError("k, a and M must be positive")
        if not (mu >= 0 and mu_k >= 0 and c_spin >= 0):
            raise ValueError("mu, mu_k and c_spin must be >= 0")
        self.S, self.M, self.g, self.a, self.k = surface, M, g, a, k
        self.I = k * M * a * a
        self.mu, self.mu_k, self.c_rr, self.c_spin = mu, mu_k, 0.0, c_spin
        self.rim_rho, self.rim_z, self.rim_q = rim_rho, rim_z, rim_q
        if vertex_rho is None and isinstance(surface, Cone):
            vertex_rho = a * math.sin(surface.alpha) / 100.0
        self.vertex_rho = vertex_rho
        self.rtol = rtol
        self.geo = SurfaceOracle(surface, M=M, g=g, a=a, k=k)  # the foot point, the launch
        self.scale = 1.0
        self.fate, self.t_fate = None, math.nan

    # ---------------------------------------------------------------- geometry
    def evaluate(self, y):
        """The contact geometry at the state y (X, V): q, the contact point (R, Z), the centre's
        rho, n, the meridian tangent t, dn/dt, N, the fit 1 - a kappa."""
        X, V = y[0:3], y[3:6]
        rho = math.hypot(X[0], X[1])
        e = (X[0] / rho, X[1] / rho) if rho > 0.0 else (1.0, 0.0)
        q = self.geo.foot(rho, X[2])
        self.geo._q = q
        R, Z, R1, Z1, R2, Z2 = self.S.at(q)
        m2 = R1 * R1 + Z1 * Z1
        m = math.sqrt(m2)
        nm = (-Z1 / m, R1 / m)
        tm = (R1 / m, Z1 / m)
        dproj = (R1 * R2 + Z1 * Z2) / m2
        dnm = (-Z2 / m - nm[0] * dproj, R2 / m - nm[1] * dproj)
        n = (nm[0] * e[0], nm[0] * e[1], nm[1])
        t = (tm[0] * e[0], tm[0] * e[1], tm[1])
        rhod = V[0] * e[0] + V[1] * e[1]
        # the foot condition (rho - R) R' + (z - Z) Z' = 0 differentiated in time
        dfoot = -m2 + (rho - R) * R2 + (X[2] - Z) * Z2
        qd = -(R1 * rhod + Z1 * V[2]) / dfoot
        de = ((V[0] - rhod * e[0]) / rho, (V[1] - rhod * e[1]) / rho) if rho > 0 else (0.0, 0.0)
        nd = (dnm[0] * qd * e[0] + nm[0] * de[0], dnm[0] * qd * e[1] + nm[0] * de[1], dnm[1] * qd)
        N = self.M * (self.g * nm[1] - _dot(nd, V))
        kap = (R1 * Z2 - Z1 * R2) / m**3
        return dict(q=q, R=R, Z=Z, rho=rho, n=n, t=t, nd=nd, N=N, fit=1.0 - self.a * kap)

    def normal(self, X):
        return self.evaluate(np.concatenate([X, np.zeros(3)]))["n"]

    def normal_force(self, X, V):
        return self.evaluate(np.concatenate([X, V]))["N"]

    def slip(self, X, V, W, n=None):
        """The contact point's velocity S = V - a Omega x n."""
        n = self.normal(X) if n is None else n
        Wxn = _cross(W, n)
        return np.array([V[i] - self.a * Wxn[i] for i in range(3)])

    # ---------------------------------------------------------------- dynamics
    def spin_hold(self, X, V, W, ev=None):
        """The couple about n [N m] that keeps Omega . n constant: -I Omega . dn/dt."""
        ev = self.evaluate(np.concatenate([X, V])) if ev is None else ev
        return -self.I * _dot(W, ev["nd"])

    def spin_limit(self, X, V, ev=None):
        """The most static spin friction gives [N m], c_spin a N (1 + 1e-9) (hybrid_oracle's)."""
        ev = self.evaluate(np.concatenate([X, V])) if ev is None else ev
        return self.c_spin * self.a * ev["N"] * (1 + 1e-9)

    def spin_moves(self, y):
        """Whether a spin at zero cannot stay stuck: the holding couple exceeds the limit."""
        ev = self.evaluate(y)
        X, V, W = y[0:3], y[3:6], y[6:9]
        return abs(self.spin_hold(X, V, W, ev)) > self.spin_limit(X, V, ev)

    def rolling_force(self, y, ev=None):
        """The tangential contact force that keeps the tangential part of dS/dt zero (module
        docstring: f = -k M b_t/(1+k)); the spin couple (along n) does not enter it."""
        ev = self.evaluate(y) if ev is None else ev
        W = y[6:9]
        n, nd, N = ev["n"], ev["nd"], ev["N"]
        Wxnd = _cross(W, nd)
        b = [N * n[i] / self.M - self.a * Wxnd[i] for i in range(3)]
        b[2] -= self.g
        bt = _tangential(b, n)
        c = -self.k * self.M / (1 + self.k)
        return (c * bt[0], c * bt[1], c * bt[2])

    def sliding_force(self, y, start_dir, ev=None):
        ev = self.evaluate(y) if ev is None else ev
        n, N = ev["n"], ev["N"]
        St = _tangential(self.slip(y[0:3], y[3:6], y[6:9], n), n)
        sl = _norm(St)
        if sl > 0.0:
            c = -self.mu_k * N / sl
            return (c * St[0], c * St[1], c * St[2])
        d = _tangential(start_dir, n)
        dn = _norm(d)
        if dn == 0.0:
            return (0.0, 0.0, 0.0)
        c = self.mu_k * N / dn
        return (c * d[0], c * d[1], c * d[2])

    def forces(self, y, mode, start_dir, spin, ev=None):
        """(f, T, ev): the tangential contact force and the spin couple in this mode; spin 0:
        stuck (the holding couple), +1/-1 the way the spin turns (kinetic spin friction)."""
        ev = self.evaluate(y) if ev is None else ev
        W = y[6:9]
        n, N = ev["n"], ev["N"]
        if spin == 0:
            Tn = -self.I * _dot(W, ev["nd"])
        elif self.c_spin > 0.0:  # the stretch's sign, not Omega . n's (module docstring)
            Tn = -self.c_spin * self.a * N * spin
        else:
            Tn = 0.0
        if mode == "rolling":
            f = self.rolling_force(y, ev)
        else:
            f = self.sliding_force(y, start_dir, ev)
        return f, (Tn * n[0], Tn * n[1], Tn * n[2]), ev

    def rhs(self, t, y, mode, start_dir, spin):
        f, T, ev = self.forces(y, mode, start_dir, spin)
        X, V, W = y[0:3], y[3:6], y[6:9]
        n, N, M, a = ev["n"], ev["N"], self.M, self.a
        A = [(N * n[i] + f[i]) / M for i in range(3)]
        A[2] -= self.g
        tf = _cross(n, f)
        Wd = [(-a * tf[i] + T[i]) / self.I for i in range(3)]
        rho2 = X[0] * X[0] + X[1] * X[1]
        phid = (X[0] * V[1] - X[1] * V[0]) / rho2 if rho2 > 0.0 else 0.0
        S = self.slip(X, V, W, n)
        return np.array([*V, *A, *Wd, phid, -_dot(f, S), -_dot(T, W)])

    # ---------------------------------------------------------------- invariants
    def energy(self, y):
        X, V, W = y[0:3], y[3:6], y[6:9]
        return 0.5 * self.M * _dot(V, V) + 0.5 * self.I * _dot(W, W) + self.M * self.g * X[2]

    def works(self, y):
        """(W_slide, W_spin) done against friction so far [J]."""
        return float(y[10]), float(y[11])

    def balance(self, y):
        """E + W_slide + W_spin: E(0) along a run."""
        return self.energy(y) + y[10] + y[11]

    def Lz(self, y):
        return self.M * (y[0] * y[4] - y[1] * y[3])

    def L_ball(self, y):
        """The whole ball's angular momentum about the vertical axis: M (X x V)_z + I Omega_z."""
        return self.Lz(y) + self.I * y[8]

    def spin(self, y):
        """w = a Omega . n [m/s]."""
        return self.a * _dot(y[6:9], self.evaluate(y)["n"])

    def stick(self, y):
        """The sticking impulse J = -k M S_t/(1+k) (the tangential slip to zero), its loss
        k M |S_t|^2/(2(1+k)) booked to W_slide."""
        y = np.array(y, float)
        n = self.evaluate(y)["n"]
        St = _tangential(self.slip(y[0:3], y[3:6], y[6:9], n), n)
        c = -self.k * self.M / (1 + self.k)
        J = (c * St[0], c * St[1], c * St[2])
        nJ = _cross(n, J)
        for i in range(3):
            y[3 + i] += J[i] / self.M
            y[6 + i] += -self.a * nJ[i] / self.I
        y[10] += self.k * self.M * _dot(St, St) / (2 * (1 + self.k))
        return y

    # ---------------------------------------------------------------- launch
    def launch(self, rho0=None, u0=0.0, v0=0.0, w0=0.0, slip_u=0.0, slip_v=0.0, q0=None):
        """The 12-number state of the launch (module docstring, "Launch"); `q0` (the contact
        point's parameter) instead of rho0 on a parametric meridian."""
        y10 = self.geo.launch(rho0=rho0, v0=v0, w0=w0, u0=u0, q0=q0)
        y = np.zeros(12)
        y[0:6] = y10[0:6]
        ev = self.evaluate(y)
        t, n = ev["t"], ev["n"]
        ephi = (0.0, 1.0, 0.0)
        p1, p2 = slip_v - v0, u0 - slip_u
        y[6:9] = [(p1 * t[i] + p2 * ephi[i] + w0 * n[i]) / self.a for i in range(3)]
        return y

    # ---------------------------------------------------------------- the story
    def run(self, y0, mode, t_end, speed=None, max_switches=200, max_steps=50_000):
        """Events [(kind, t, y)] ('slip', 'roll', 'spin_stop', 'spin_go', and the terminal
        'spill', 'vertex', 'left_surface', 'hole', 'no_fit') up to t_end; (events, final
        state, final mode). :attr:`fate` and :attr:`t_fate` say how it ended; the accepted
        steps are in :attr:`times` and :attr:`states`. `speed` (the scale of the switches'
        thresholds) defaults to the largest of |V|, a |Omega| and |S|; a stretch between events
        that takes more than `max_steps` steps is a RuntimeError (a correct run takes a few
        hundred a second; a wrong model that chatters at a switch must not hang a test)."""
        story = self.story(y0, mode, t_end, speed, max_switches, max_steps)
        self.fate, self.t_fate = story["fate"], story["t"]
        self.times, self.states = story["times"], story["states"]
        return story["events"], story["y"], story["mode"]

    def _scales(self, y, speed):
        X = y[0:3]
        L = max(_norm(X), self.a)
        vs = max(speed, math.sqrt(self.g * L))
        Es = self.M * (vs * vs + self.g * L)
        return 1e-2 * self.rtol * np.array([L] * 3 + [vs] * 3 + [vs / self.a] * 3 + [1.0]
                                            + [Es] * 2)  # fmt: skip

    def story(self, y0, mode, t_end, speed=None, max_switches=200, max_steps=50_000):
        y = np.array(y0, float)
        if y.shape != (12,):
            raise ValueError("a 12-number state (X, V, Omega, phi, W_slide, W_spin)")
        if mode not in ("rolling", "sliding"):
            raise ValueError(f"mode {mode!r}")
        ev0 = self.evaluate(y)
        if speed is None:
            W = y[6:9]
            speed = max(_norm(y[3:6]), self.a * _norm(W),
                        _norm(self.slip(y[0:3], y[3:6], W, ev0["n"])))  # fmt: skip
        self.scale = speed
        eps = EPS * speed
        atol = self._scales(y, speed)
        events, times, states = [], [0.0], [y.copy()]
        t = 0.0
        start_dir = (0.0, 0.0, 0.0)
        if mode == "sliding" and self._slip_size(y, ev0) == 0:
            raise ValueError("a sliding start needs a slip")
        wn0 = _dot(y[6:9], ev0["n"])
        spin = math.copysign(1.0, wn0) if wn0 != 0.0 else 1.0
        if self.c_spin > 0 and wn0 == 0.0:  # stuck at the launch, or turning the way it must
            spin = self._spin_way(y) if self.spin_moves(y) else 0
        armed_slip = True
        armed_spin = wn0 != 0.0  # a spin launched at zero turns away from it first
        eps_w = eps / self.a  # the spin's threshold [rad/s]: a Omega . n against eps

        def end(fate, y_end, mode_end, t_):
            return dict(events=events, y=y_end, mode=mode_end, fate=fate, t=t_,
                        times=np.array(times), states=np.array(states))  # fmt: skip

        # terminal geometric events: (kind, g(y, ev), direction)
        geo_events = []
        if self.rim_rho is not None:
            geo_events.append(("spill", lambda y, e: e["R"] - self.rim_rho, 1))
        if self.rim_z is not None:
            geo_events.append(("spill", lambda y, e: e["Z"] - self.rim_z, 1))
        if self.rim_q is not None:
            geo_events.append(("spill", lambda y, e: e["q"] - self.rim_q, 1))
        if self.vertex_rho is not None:
            geo_events.append(("vertex", lambda y, e: e["rho"] - self.vertex_rho, -1))
        if self.S.hole is not None:
            geo_events.append(("hole", lambda y, e: e["R"] - self.S.hole, -1))
        geo_events.append(("left_surface", lambda y, e: e["N"], -1))
        geo_events.append(("no_fit", lambda y, e: e["fit"] - 1e-3, -1))
        fates = {"spill": "spilled"}

        for _ in range(max_switches):
            # ---- what the state at the start of the stretch decides
            ev = self.evaluate(y)
            for kind, fn, d in geo_events:  # a terminal condition met already
                gv = fn(y, ev)
                if gv <= 0.0 if d < 0 else gv >= 0.0:
                    events.append((kind, t, y.copy()))
                    return end(fates.get(kind, kind), y, mode, t)
            if mode == "rolling" and self._slip_margin(y) > 0.0:
                events.append(("slip", t, y.copy()))
                mode, start_dir = "sliding", self._slip_dir(y)
                armed_slip = False
                continue
            if spin == 0 and self.spin_moves(y):
                events.append(("spin_go", t, y.copy()))
                spin = self._spin_way(y)
                armed_spin = False
            if mode == "sliding":  # armed once beyond twice the threshold
                armed_slip |= self._slip_size(y) > 2 * eps
            # ---- the stretch, to its first event
            evs = list(geo_events)
            if mode == "rolling":
                evs.append(("switch", lambda y, e: self._slip_margin(y, e), 1))
            elif armed_slip:
                evs.append(("switch", lambda y, e: self._slip_size(y, e) - eps, -1))
            else:
                evs.append(("arm_slip", lambda y, e: self._slip_size(y, e) - 2 * eps, 1))
            if spin == 0:
                evs.append(("spin", lambda y, e: abs(self.spin_hold(y[0:3], y[3:6], y[6:9], e))
                            - self.spin_limit(y[0:3], y[3:6], e), 1))  # fmt: skip
            elif self.c_spin > 0 and armed_spin:
                evs.append(("spin", lambda y, e, s=spin: s * _dot(y[6:9], e["n"]), -1))
            elif self.c_spin > 0:  # just turned from zero: armed once beyond twice eps_w
                evs.append(("arm_spin", lambda y, e, s=spin: s * _dot(y[6:9], e["n"]) - 2 * eps_w,
                            1))  # fmt: skip
                evs.append(("spin", lambda y, e, s=spin: s * _dot(y[6:9], e["n"]) + 2 * eps_w,
                            -1))  # fmt: skip
            args = (mode, start_dir, spin)
            hit = self._stretch(t, y, t_end, atol, args, evs, times, states, max_steps)
            if hit is None:
                return end(mode, states[-1].copy(), mode, t_end)
            t, kind, y = hit
            y = y.copy()
            if kind in ("spill", "vertex", "left_surface", "hole", "no_fit"):
                events.append((kind, t, y))
                return end(fates.get(kind, kind), y, mode, t)
            if kind == "arm_slip":
                armed_slip = True
            elif kind == "arm_spin":
                armed_spin = True
            elif kind == "spin":  # the spin about the normal is zero from here (as located)
                n = self.evaluate(y)["n"]
                wn = _dot(y[6:9], n)
                y[6:9] = [y[6 + i] - wn * n[i] for i in range(3)]
                if spin == 0:
                    events.append(("spin_go", t, y.copy()))
                    spin = self._spin_way(y)
                else:
                    events.append(("spin_stop", t, y.copy()))
                    spin = self._spin_way(y) if self.spin_moves(y) else 0
                armed_spin = False
            elif mode == "rolling":
                events.append(("slip", t, y.copy()))
                mode, start_dir = "sliding", self._slip_dir(y)
                armed_slip = False
            else:  # the return to rolling, if static friction holds it
                ys = self.stick(y)
                if self._slip_margin(ys) <= 0.0:
                    y = ys
                    mode = "rolling"
                    events.append(("roll", t, y.copy()))
                armed_slip = False
        raise RuntimeError("too many switches")

    def _spin_way(self, y):
        """The way a spin at zero that cannot stay stuck turns: -sign(T_hold) (the unbalanced
        part of the holding couple, |T_hold| - c_spin a N > 0, turns it; at a genuine stop that
        passes through it is the reversal, -spin)."""
        return -math.copysign(1.0, self.spin_hold(y[0:3], y[3:6], y[6:9]))

    def _slip_size(self, y, ev=None):
        """|S_t|, the tangential slip's size (S . n = V . n is only the constraint's drift)."""
        n = self.evaluate(y)["n"] if ev is None else ev["n"]
        return _norm(_tangential(self.slip(y[0:3], y[3:6], y[6:9], n), n))

    def _slip_margin(self, y, ev=None):
        """|f| - mu N of the rolling force (> 0: static friction cannot hold the rolling)."""
        ev = self.evaluate(y) if ev is None else ev
        return _norm(self.rolling_force(y, ev)) - self.mu * ev["N"]

    def _slip_dir(self, y):
        f = self.rolling_force(y)
        return tuple(x / _norm(f) for x in f)

    def _stretch(self, t, y, t_end, atol, args, evs, times, states, max_steps):
        """DOP853 from (t, y) to the first of the events evs [(kind, g(y, ev), direction)]
        (located by brentq on the dense output; solve_ivp's rules) or to t_end (None). The
        accepted steps are appended to times, states."""

        def f(s, z):
            return self.rhs(s, z, *args)

        ev = self.evaluate(y)
        g_old = [fn(y, ev) for _, fn, _ in evs]
        solver = DOP853(f, t, y, t_end, rtol=self.rtol, atol=atol)
        h = None
        for _ in range(max_steps):
            try:
                msg = solver.step()
            except FootError:  # a stage past a fit limit: again from the last step, shorter
                h = (h or solver.step_size or 1e-3 * (t_end - solver.t)) / 4
                if h <= 1e-15 * max(1.0, abs(solver.t)):
                    raise
                solver = DOP853(f, solver.t, solver.y, t_end, rtol=self.rtol, atol=atol,
                                max_step=h, first_step=h)  # fmt: skip
                continue
            if msg is not None or solver.status == "failed":
                raise RuntimeError(f"the integration failed: {msg}")
            ev = self.evaluate(solver.y)
            g_new = [fn(solver.y, ev) for _, fn, _ in evs]
            found = []
            for (kind, fn, d), a, b in zip(evs, g_old, g_new, strict=True):
                up, down = a <= 0.0 <= b, a >= 0.0 >= b
                if (up and d > 0) or (down and d < 0) or ((up or down) and d == 0):
                    sol = solver.dense_output()

                    def g(s, fn=fn, sol=sol):
                        z = sol(s)
                        return fn(z, self.evaluate(z))

                    te = brentq(g, solver.t_old, solver.t, xtol=4 * _FEPS * max(1.0, solver.t),
                                rtol=4 * _FEPS)  # fmt: skip
                    found.append((te, kind, sol(te)))
            if found:
                te, kind, ye = min(found, key=lambda x: x[0])
                times.append(te)
                states.append(np.array(ye))
                return te, kind, np.array(ye)
            times.append(solver.t)
            states.append(solver.y.copy())
            g_old = g_new
            if solver.status == "finished":
                return None
        raise RuntimeError("step budget exhausted")

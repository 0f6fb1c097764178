"""An independent rigid-body model of a sphere inside a cone, rolling and sliding, for the tests.

Written from scratch in Cartesian coordinates (nothing from engine/): the centre's position X
and velocity V and the angular velocity Omega in the fixed frame; Newton and Euler with the
contact constraint (the centre on the cone z = rho cot(alpha) of the centre's positions), the
normal force from the constraint's second derivative, and at the contact either the tangential
force that keeps the contact point at rest (solved from d/dt(slip) = 0, a 2x2 linear system) or
kinetic Coulomb friction against the slip. Spin friction and rolling resistance are couples
against the normal and tangential parts of Omega. Spin stick: when the spin about the normal,
Omega . n, reaches zero and the couple that keeps it zero, -I Omega . dn/dt, is within
c_spin a N, static spin friction holds it there (that couple then acts) until the couple it
needs exceeds c_spin a N; otherwise the spin passes through zero. scipy's solve_ivp (DOP853,
rtol 1e-12) with events: the slip (needed friction reaches mu N), the return to rolling (slip
speed down to 1e-9 of the speed scale, then the sticking impulse), the spin reaching zero
(spin_stop, whether or not it then sticks), the stuck spin's release (spin_go), the rim.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

ZHAT = np.array([0.0, 0.0, 1.0])


class Oracle:
    def __init__(self, alpha, M, g, a, k, mu, mu_k, c_rr=0.0, c_spin=0.0, rim_centre=math.inf):
        self.s, self.c = math.sin(alpha), math.cos(alpha)
        self.M, self.g, self.a, self.k = M, g, a, k
        self.mu, self.mu_k, self.c_rr, self.c_spin = mu, mu_k, c_rr, c_spin
        self.rim = rim_centre
        self.I = k * M * a * a

    # ---------------------------------------------------------------- geometry
    def normal(self, X):
        rho = math.hypot(X[0], X[1])
        return np.array([-self.c * X[0] / rho, -self.c * X[1] / rho, self.s])

    def normal_rate(self, X, V):
        rho = math.hypot(X[0], X[1])
        rhod = (X[0] * V[0] + X[1] * V[1]) / rho
        return np.array(
            [
                -self.c * (V[0] / rho - X[0] * rhod / rho**2),
                -self.c * (V[1] / rho - X[1] * rhod / rho**2),
                0.0,
            ]
        )

    def normal_force(self, X, V):
        rho = math.hypot(X[0], X[1])
        vphi = (X[0] * V[1] - X[1] * V[0]) / rho
        return self.M * (self.g * self.s + self.c * vphi * vphi / rho)

    def slip(self, X, V, W):
        return V - self.a * np.cross(W, self.normal(X))

    # ---------------------------------------------------------------- dynamics
    def spin_hold(self, X, V, W):
        """The couple about n [N m] that keeps Omega . n constant: -I Omega . dn/dt (the
        contact force's torque is tangential, so it alone sets d(Omega . n)/dt)."""
        return -self.I * (W @ self.normal_rate(X, V))

    def couples(self, X, V, W, N, spin):
        """Rolling resistance, and the spin couple: ``spin`` = 0 stuck (the holding couple),
        +1 or -1 the sign of the spin's motion (kinetic spin friction against it)."""
        n = self.normal(X)
        wn = W @ n
        wt = W - wn * n
        T = np.zeros(3)
        if np.linalg.norm(wt) > 0:
            T -= self.c_rr * N * self.a * wt / np.linalg.norm(wt)
        if spin == 0:
            T += self.spin_hold(X, V, W) * n
        elif self.c_spin > 0.0:
            T -= self.c_spin * self.a * N * spin * n
        return T

    def accelerations(self, X, V, W, f, spin=1):
        n = self.normal(X)
        N = self.normal_force(X, V)
        A = -self.g * ZHAT + (N * n + f) / self.M
        tau = np.cross(-self.a * n, f) + self.couples(X, V, W, N, spin)
        return A, tau / self.I

    def slip_rate(self, X, V, W, f):
        A, Wd = self.accelerations(X, V, W, f)
        n = self.normal(X)
        return A - self.a * (np.cross(Wd, n) + np.cross(W, self.normal_rate(X, V)))

    def tangents(self, X):
        n = self.normal(X)
        t1 = X / np.linalg.norm(X)
        t1 = t1 - (t1 @ n) * n
        t1 /= np.linalg.norm(t1)
        return t1, np.cross(n, t1)

    def rolling_force(self, X, V, W):
        """The tangential contact force that keeps d(slip)/dt = 0 (linear in f: solved)."""
        t1, t2 = self.tangents(X)
        b = self.slip_rate(X, V, W, np.zeros(3))
        L1 = self.slip_rate(X, V, W, t1) - b
        L2 = self.slip_rate(X, V, W, t2) - b
        Mx = np.array([[t1 @ L1, t1 @ L2], [t2 @ L1, t2 @ L2]])
        f12 = np.linalg.solve(Mx, -np.array([t1 @ b, t2 @ b]))
        return f12[0] * t1 + f12[1] * t2

    def rhs(self, t, y, mode, start_dir, spin):
        X, V, W = y[0:3], y[3:6], y[6:9]
        if spin != 0:  # the spin's sign, or the way it leaves zero
            wn = W @ self.normal(X)
            spin = math.copysign(1.0, wn) if wn != 0.0 else spin
        if mode == "rolling":
            f = self.rolling_force(X, V, W)
        else:
            S = self.slip(X, V, W)
            sl = np.linalg.norm(S)
            if sl > 0.0:
                f = -self.mu_k * self.normal_force(X, V) * S / sl
            else:
                f = self.mu_k * self.normal_force(X, V) * start_dir
        A, Wd = self.accelerations(X, V, W, f, spin)
        return np.concatenate([V, A, Wd])

    # ---------------------------------------------------------------- invariants
    def invariants(self, y):
        """(calE, h, L_z) of a rolling state (docs' definitions, from the Cartesian state)."""
        X, V, W = y[0:3], y[3:6], y[6:9]
        E = 0.5 * self.M * V @ V + 0.5 * self.I * W @ W + self.M * self.g * X[2]
        Lz = self.M * (X[0] * V[1] - X[1] * V[0])
        h = self.a * W[2] / self.s
        calE = E / (1 + self.k) - self.k * self.M * h * h / (2 * (1 + self.k))
        return calE, h, Lz

    def energy(self, y):
        X, V, W = y[0:3], y[3:6], y[6:9]
        return 0.5 * self.M * V @ V + 0.5 * self.I * W @ W + self.M * self.g * X[2]

    def stick(self, y):
        X, V, W = y[0:3], y[3:6], y[6:9]
        n = self.normal(X)
        S = self.slip(X, V, W)
        S = S - (S @ n) * n
        J = -self.k * self.M * S / (1 + self.k)
        V2 = V + J / self.M
        W2 = W + np.cross(-self.a * n, J) / self.I
        return np.concatenate([X, V2, W2])

    # ---------------------------------------------------------------- the story
    def run(self, y0, mode, t_end, speed, max_switches=50):
        """Events [(kind, t, y)] ('slip', 'roll', 'spin_stop', 'spin_go', 'spill') up to t_end;
        (events, final state, final mode)."""
        events = []
        t = 0.0
        y = np.array(y0, float)
        eps_s = 1e-9 * speed
        start_dir = np.zeros(3)
        if mode == "sliding" and np.linalg.norm(self.slip(y[0:3], y[3:6], y[6:9])) == 0:
            raise ValueError("a sliding start needs a slip")
        wn0 = y[6:9] @ self.normal(y[0:3])
        spin = math.copysign(1.0, wn0) if wn0 != 0.0 else 1.0
        if self.c_spin > 0 and wn0 == 0.0 and not self.spin_moves(y):
            spin = 0

        def rim(t, y, *_):
            return np.linalg.norm(y[0:3]) - self.rim

        rim.terminal = True
        rim.direction = 1
        for _ in range(max_switches):
            if mode == "rolling":

                def switch(t, y, *_):
                    X, V, W = y[0:3], y[3:6], y[6:9]
                    f = self.rolling_force(X, V, W)
                    return np.linalg.norm(f) - self.mu * self.normal_force(X, V)

                switch.direction = 1
            else:

                def switch(t, y, *_):
                    return np.linalg.norm(self.slip(y[0:3], y[3:6], y[6:9])) - eps_s

                switch.direction = -1
            switch.terminal = True

            def spin_event(t, y, *_, sgn=spin):
                X, V, W = y[0:3], y[3:6], y[6:9]
                if sgn == 0:  # stuck: the couple it needs reaches c_spin a N
                    return abs(self.spin_hold(X, V, W)) - self.spin_limit(X, V)
                return sgn * (W @ self.normal(X)) if self.c_spin > 0 else 1.0

            spin_event.terminal = True
            spin_event.direction = 1 if spin == 0 else -1
            if mode == "rolling" and switch(t, y) > 0.0:  # static friction cannot hold it
                kind, t_ev, y_ev = "switch", t, y
            else:
                sol = solve_ivp(
                    self.rhs, (t, t_end), y, method="DOP853", rtol=1e-12, atol=1e-14 * speed,
                    events=(rim, switch, spin_event), args=(mode, start_dir, spin),
                    dense_output=False,
                )  # fmt: skip
                if sol.status == 0:
                    return events, sol.y[:, -1], mode
                hits = [(te[0], i) for i, te in enumerate(sol.t_events) if te.size]
                t_ev, i_ev = min(hits)
                y_ev = sol.y_events[i_ev][0]
                kind = ("spill", "switch", "spin")[i_ev]
            t, y = t_ev, y_ev.copy()
            if kind == "spill":
                events.append(("spill", t, y))
                return events, y, mode
            if kind == "spin":  # the spin about the normal is zero from here (as located)
                n = self.normal(y[0:3])
                y[6:9] -= (y[6:9] @ n) * n
                if spin == 0:
                    events.append(("spin_go", t, y.copy()))
                    spin = -math.copysign(1.0, self.spin_hold(y[0:3], y[3:6], y[6:9]))
                else:
                    events.append(("spin_stop", t, y.copy()))
                    spin = -spin if self.spin_moves(y) else 0
                continue
            if mode == "rolling":
                X, V, W = y[0:3], y[3:6], y[6:9]
                f = self.rolling_force(X, V, W)
                start_dir = f / np.linalg.norm(f)
                mode = "sliding"
                events.append(("slip", t, y.copy()))
            else:
                y = self.stick(y)
                mode = "rolling"
                events.append(("roll", t, y.copy()))
        raise RuntimeError("too many switches")

    def spin_limit(self, X, V):
        """The most static spin friction gives [N m], c_spin a N (with the engine's relative
        band of 1e-9, docs/physics.md "Spin stick")."""
        return self.c_spin * self.a * self.normal_force(X, V) * (1 + 1e-9)

    def spin_moves(self, y):
        """Whether a spin at zero cannot stay stuck: the holding couple exceeds the limit."""
        X, V, W = y[0:3], y[3:6], y[6:9]
        return abs(self.spin_hold(X, V, W)) > self.spin_limit(X, V)


def start_state(alpha, r0, u0, v0, w0, slip_u, slip_v, a):
    """Cartesian (X, V, Omega) of the engine's launch (theta = 0; p1 = slip_v - v0,
    p2 = u0 - slip_u, omega = (p1 e1 + p2 e2 + w0 nu)/a)."""
    s, c = math.sin(alpha), math.cos(alpha)
    e1 = np.array([s, 0.0, c])
    e2 = np.array([0.0, 1.0, 0.0])
    nu = np.array([-c, 0.0, s])
    X = r0 * e1
    V = u0 * e1 + v0 * e2
    W = ((slip_v - v0) * e1 + (u0 - slip_u) * e2 + w0 * nu) / a
    return np.concatenate([X, V, W])


def polar(y, alpha):
    """(r, theta) of the centre."""
    X = y[0:3]
    return float(np.linalg.norm(X)), math.atan2(X[1], X[0])

"""An independent rigid-body model of a sphere inside a cone, rolling and sliding, for the tests.

Written from scratch in Cartesian coordinates (nothing from engine/): the centre's position X
and velocity V and the angular velocity Omega in the fixed frame; Newton and Euler with the
contact constraint (the centre on the cone z = rho cot(alpha) of the centre's positions), the
normal force from the constraint's second derivative, and at the contact either the tangential
force that keeps the contact point at rest (solved from d/dt(slip) = 0, a 2x2 linear system) or
kinetic Coulomb friction against the slip. Spin friction and rolling resistance are couples
against the normal and tangential parts of Omega, each Coulomb-like at zero:

- spin stick: when the spin about the normal, Omega . n, reaches zero and the couple that keeps
  it zero, -I Omega . dn/dt, is within c_spin a N, static spin friction holds it there (that
  couple then acts) until the couple it needs exceeds c_spin a N; otherwise it passes through;
- while sliding, the tangential part Omega_t likewise: once it reaches zero (or starts there)
  it stays zero while the couple that keeps it so, I (Omega . n) dn/dt - (-a n) x f, is within
  c_rr a N, and leaves zero against the full couple otherwise;
- the stop: rolling with rolling resistance, the centre's speed falls to zero (a threshold of
  1e-9 of the speed scale, carried on to zero at the deceleration there). At rest the contact
  force and the resistance's couple that would hold the sphere are the slope's pull
  M g (z - (z . n) n) and a n x that force: if c_rr a N cannot give the couple it starts again
  from rest, if mu N cannot give the force it slips; otherwise it stays, and its spin about the
  normal stops at the constant rate c_spin a N / I, or spins on without spin friction.

scipy's solve_ivp (DOP853, rtol 1e-12) with events: the slip (needed friction reaches mu N), the
return to rolling (slip speed down to 1e-9 of the speed scale, then the sticking impulse: a
return only if static friction then holds the rolling, or the sphere is then at rest), the spin
reaching zero (spin_stop, whether or not it then sticks), the stuck spin's release (spin_go),
the stop (rest), the rim (spill) and the vertex region (r below a/100). ``drag`` > 0 adds a
linear air drag on the centre, -drag M (1 + k) V (tangent to the cone of the centre's
positions, so N is unchanged): the recipe of docs/architecture.md's toy effect; ``twist`` > 0 a
couple -twist M a^2 Omega against the whole angular velocity (a test's toy effect with a couple:
it vanishes where a spin is held at zero, so the holds need no change). What a state decides
at the start of a stretch (rolling beyond the friction limit: a slip; within the stop threshold:
the stop) is decided before the stretch runs. A return or a stop of Omega_t is armed again only
once its quantity has exceeded twice its threshold.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

ZHAT = np.array([0.0, 0.0, 1.0])
#: Thresholds of the switches, relative to the launch's speed scale.
EPS = 1e-9


class Oracle:
    def __init__(self, alpha, M, g, a, k, mu, mu_k, c_rr=0.0, c_spin=0.0, rim_centre=math.inf,
                 drag=0.0, twist=0.0):  # fmt: skip
        self.s, self.c = math.sin(alpha), math.cos(alpha)
        self.drag, self.twist = drag, twist
        self.M, self.g, self.a, self.k = M, g, a, k
        self.mu, self.mu_k, self.c_rr, self.c_spin = mu, mu_k, c_rr, c_spin
        self.rim = rim_centre
        self.I = k * M * a * a
        self.r_vertex = a / 100.0

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

    def tangential_spin(self, X, W):
        n = self.normal(X)
        return W - (W @ n) * n

    # ---------------------------------------------------------------- dynamics
    def spin_hold(self, X, V, W):
        """The couple about n [N m] that keeps Omega . n constant: -I Omega . dn/dt (the
        contact force's torque is tangential, so it alone sets d(Omega . n)/dt)."""
        return -self.I * (W @ self.normal_rate(X, V))

    def tangential_hold(self, X, V, W, f):
        """The tangential couple [N m] that keeps Omega_t = 0 (sliding): the tangential part of
        I dOmega/dt must be I (Omega . n) dn/dt, and the contact force's torque gives part."""
        n = self.normal(X)
        return self.I * (W @ n) * self.normal_rate(X, V) - np.cross(-self.a * n, f)

    def couples(self, X, V, W, N, spin, f, tangential):
        """Rolling resistance, and the spin couple: ``spin`` = 0 stuck (the holding couple),
        +1 or -1 the sign of the spin's motion (kinetic spin friction against it).
        ``tangential``: None (kinetic against Omega_t), "stuck" (Omega_t held at zero while
        sliding) or a unit vector (Omega_t just released from zero: the couple's direction
        until Omega_t has one of its own)."""
        n = self.normal(X)
        wn = W @ n
        wt = W - wn * n
        T = np.zeros(3)
        if self.c_rr > 0.0:
            size = np.linalg.norm(wt)
            if isinstance(tangential, str):
                T += self.tangential_hold(X, V, W, f)
            elif size > 1e-13 * self.scale / self.a or tangential is None:
                if size > 0:
                    T -= self.c_rr * N * self.a * wt / size
            else:
                T += self.c_rr * N * self.a * tangential
        if spin == 0:
            T += self.spin_hold(X, V, W) * n
        elif self.c_spin > 0.0:
            T -= self.c_spin * self.a * N * spin * n
        return T

    def accelerations(self, X, V, W, f, spin=1, tangential=None):
        n = self.normal(X)
        N = self.normal_force(X, V)
        A = -self.g * ZHAT + (N * n + f) / self.M - self.drag * (1.0 + self.k) * V
        tau = np.cross(-self.a * n, f) + self.couples(X, V, W, N, spin, f, tangential)
        tau = tau - self.twist * self.M * self.a**2 * W
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

    def sliding_force(self, X, V, W, start_dir):
        S = self.slip(X, V, W)
        sl = np.linalg.norm(S)
        if sl > 0.0:
            return -self.mu_k * self.normal_force(X, V) * S / sl
        return self.mu_k * self.normal_force(X, V) * start_dir

    def rhs(self, t, y, mode, start_dir, spin, tangential):
        X, V, W = y[0:3], y[3:6], y[6:9]
        if spin != 0:  # the spin's sign, or the way it leaves zero
            wn = W @ self.normal(X)
            spin = math.copysign(1.0, wn) if wn != 0.0 else spin
        if mode == "rolling":
            f = self.rolling_force(X, V, W)
            tangential = None
        else:
            f = self.sliding_force(X, V, W, start_dir)
        A, Wd = self.accelerations(X, V, W, f, spin, tangential)
        return np.concatenate([V, A, Wd])

    # ---------------------------------------------------------------- at rest
    def rest_holds(self, X):
        """At rest (V = 0, Omega_t = 0): (rolling resistance holds it, friction holds it). The
        contact force that holds the centre is the slope's pull M g (z - (z . n) n) and the
        couple that then holds the rotation is a n x f."""
        n = self.normal(X)
        N = self.normal_force(X, np.zeros(3))
        f = self.M * self.g * (ZHAT - (ZHAT @ n) * n)
        T = np.cross(self.a * n, f)
        return (np.linalg.norm(T) <= self.c_rr * self.a * N,
                np.linalg.norm(f) <= self.mu * N)  # fmt: skip

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

    def spin_limit(self, X, V):
        """The most static spin friction gives [N m], c_spin a N (with the engine's relative
        band of 1e-9, docs/physics.md "Spin stick")."""
        return self.c_spin * self.a * self.normal_force(X, V) * (1 + 1e-9)

    def spin_moves(self, y):
        """Whether a spin at zero cannot stay stuck: the holding couple exceeds the limit."""
        X, V, W = y[0:3], y[3:6], y[6:9]
        return abs(self.spin_hold(X, V, W)) > self.spin_limit(X, V)

    # ---------------------------------------------------------------- the story
    def run(self, y0, mode, t_end, speed, max_switches=200):
        """Events [(kind, t, y)] ('slip', 'roll', 'spin_stop', 'spin_go', 'rest', 'spill',
        'vertex') up to t_end; (events, final state, final mode). :attr:`fate` and
        :attr:`t_fate` say how it ended (rolling, sliding, spilled, vertex, rest, spinning)."""
        story = self.story(y0, mode, t_end, speed, max_switches)
        self.fate, self.t_fate = story["fate"], story["t"]
        return story["events"], story["y"], story["mode"]

    def story(self, y0, mode, t_end, speed, max_switches=200):
        self.scale = speed
        eps = EPS * speed
        events = []
        t = 0.0
        y = np.array(y0, float)
        start_dir = np.zeros(3)
        if mode == "sliding" and np.linalg.norm(self.slip(y[0:3], y[3:6], y[6:9])) == 0:
            raise ValueError("a sliding start needs a slip")
        wn0 = y[6:9] @ self.normal(y[0:3])
        spin = math.copysign(1.0, wn0) if wn0 != 0.0 else 1.0
        if self.c_spin > 0 and wn0 == 0.0 and not self.spin_moves(y):
            spin = 0
        tangential = None  # the tangential spin's state while sliding (see couples)
        armed_slip = armed_rot = True
        if mode == "sliding":
            tangential = self._tangential_at_zero(y, start_dir)

        def end(fate, y_end, mode_end, t_end_):
            return dict(events=events, y=y_end, mode=mode_end, fate=fate, t=t_end_)

        def rim(t, y, *_):
            return np.linalg.norm(y[0:3]) - self.rim

        def vertex(t, y, *_):
            return np.linalg.norm(y[0:3]) - self.r_vertex

        rim.terminal = vertex.terminal = True
        rim.direction, vertex.direction = 1, -1
        for _ in range(max_switches):
            X, V, W = y[0:3], y[3:6], y[6:9]
            # ---- what the state at the start of the stretch decides
            if mode == "rolling" and self.c_rr > 0.0:
                sp = np.linalg.norm(V)
                if sp <= eps and (sp > 0.0 or self.rest_holds(X)[0]):
                    out = self._rest(t, y, spin, t_end, events)
                    if out is None:  # it slips at rest
                        t = events[-1][1]
                        y = events[-1][2].copy()
                        mode, start_dir = "sliding", self._slip_dir(y)
                        tangential = self._tangential_at_zero(y, start_dir)
                        armed_slip = False
                        continue
                    if out[0] == "restart":
                        t, y = out[1], out[2]
                        continue
                    return end(out[0], out[2], "rolling", out[1])
            if mode == "rolling" and self._slip_margin(y) > 0.0:
                events.append(("slip", t, y.copy()))
                mode, start_dir = "sliding", self._slip_dir(y)
                tangential = self._tangential_at_zero(y, start_dir)
                armed_slip = False
                continue
            if spin == 0 and self.spin_moves(y):
                events.append(("spin_go", t, y.copy()))
                spin = -math.copysign(1.0, self.spin_hold(X, V, W))
            if mode == "sliding":  # armed once beyond twice the threshold
                X, V, W = y[0:3], y[3:6], y[6:9]
                armed_slip |= np.linalg.norm(self.slip(X, V, W)) > 2 * eps
                armed_rot |= self.a * np.linalg.norm(self.tangential_spin(X, W)) > 2 * eps
            # ---- the stretch, to its first event
            evs, kinds = [rim, vertex], ["spill", "vertex"]
            if mode == "rolling":

                def switch(t, y, *_):
                    return self._slip_margin(y)

                switch.direction = 1
                evs.append(switch), kinds.append("switch")
                if self.c_rr > 0.0:

                    def stop(t, y, *_):
                        return np.linalg.norm(y[3:6]) - eps

                    stop.direction = -1
                    evs.append(stop), kinds.append("stop")
            else:

                def switch(t, y, *_, armed=armed_slip):
                    sl = np.linalg.norm(self.slip(y[0:3], y[3:6], y[6:9]))
                    return sl - eps if armed else sl - 2 * eps

                switch.direction = -1 if armed_slip else 1
                evs.append(switch), kinds.append("switch" if armed_slip else "arm_slip")
                if self.c_rr > 0.0 and isinstance(tangential, str):

                    def go(t, y, *_, sd=start_dir):
                        X, V, W = y[0:3], y[3:6], y[6:9]
                        f = self.sliding_force(X, V, W, sd)
                        hold = self.tangential_hold(X, V, W, f)
                        return np.linalg.norm(hold) - self.c_rr * self.a * self.normal_force(X, V)

                    go.direction = 1
                    evs.append(go), kinds.append("rot_go")
                elif self.c_rr > 0.0:

                    def rot(t, y, *_, armed=armed_rot):
                        size = self.a * np.linalg.norm(self.tangential_spin(y[0:3], y[6:9]))
                        return size - eps if armed else size - 2 * eps

                    rot.direction = -1 if armed_rot else 1
                    evs.append(rot), kinds.append("rot_stop" if armed_rot else "arm_rot")

            def spin_event(t, y, *_, sgn=spin):
                X, V, W = y[0:3], y[3:6], y[6:9]
                if sgn == 0:  # stuck: the couple it needs reaches c_spin a N
                    return abs(self.spin_hold(X, V, W)) - self.spin_limit(X, V)
                return sgn * (W @ self.normal(X)) if self.c_spin > 0 else 1.0

            spin_event.direction = 1 if spin == 0 else -1
            evs.append(spin_event), kinds.append("spin")
            for e in evs:
                e.terminal = True
            sol = solve_ivp(self.rhs, (t, t_end), y, method="DOP853", rtol=1e-12,
                            atol=1e-14 * speed, events=evs,
                            args=(mode, start_dir, spin, tangential))  # fmt: skip
            if sol.status == 0:
                return end(mode, sol.y[:, -1], mode, t_end)
            hits = [(te[0], i) for i, te in enumerate(sol.t_events) if te.size]
            t_ev, i_ev = min(hits)
            t, y = t_ev, sol.y_events[i_ev][0].copy()
            kind = kinds[i_ev]
            if kind in ("spill", "vertex"):
                events.append((kind, t, y))
                return end({"spill": "spilled"}.get(kind, kind), y, mode, t)
            if kind == "arm_slip":
                armed_slip = True
            elif kind == "arm_rot":
                armed_rot = True
            elif kind == "rot_stop":  # Omega_t to zero: held there, or off the other way
                n = self.normal(y[0:3])
                y[6:9] = (y[6:9] @ n) * n
                tangential = self._tangential_at_zero(y, start_dir)
                armed_rot = False
            elif kind == "rot_go":
                X, V, W = y[0:3], y[3:6], y[6:9]
                hold = self.tangential_hold(X, V, W, self.sliding_force(X, V, W, start_dir))
                tangential = hold / np.linalg.norm(hold)
                armed_rot = False
            elif kind == "spin":  # the spin about the normal is zero from here (as located)
                n = self.normal(y[0:3])
                y[6:9] -= (y[6:9] @ n) * n
                if spin == 0:
                    events.append(("spin_go", t, y.copy()))
                    spin = -math.copysign(1.0, self.spin_hold(y[0:3], y[3:6], y[6:9]))
                else:
                    events.append(("spin_stop", t, y.copy()))
                    spin = -spin if self.spin_moves(y) else 0
            elif kind == "stop":  # carried on to zero speed, and what follows
                out = self._rest(t, y, spin, t_end, events)
                if out is None:  # it slips at rest
                    t = events[-1][1]
                    y = events[-1][2].copy()
                    mode, start_dir = "sliding", self._slip_dir(y)
                    tangential = self._tangential_at_zero(y, start_dir)
                    armed_slip = False
                elif out[0] == "restart":
                    t, y = out[1], out[2]
                else:
                    return end(out[0], out[2], "rolling", out[1])
            elif mode == "rolling":
                events.append(("slip", t, y.copy()))
                mode, start_dir = "sliding", self._slip_dir(y)
                tangential = self._tangential_at_zero(y, start_dir)
                armed_slip = False
            else:  # the return to rolling, if static friction holds it (or it is at rest)
                ys = self.stick(y)
                X, V, W = ys[0:3], ys[3:6], ys[6:9]
                at_rest = (self.c_rr > 0.0 and np.linalg.norm(V) <= eps
                           and self.rest_holds(X)[0])  # fmt: skip
                if at_rest or self._slip_margin(ys) <= 0.0:
                    y = ys
                    mode = "rolling"
                    events.append(("roll", t, y.copy()))
                armed_slip = False
        raise RuntimeError("too many switches")

    def _slip_margin(self, y):
        X, V, W = y[0:3], y[3:6], y[6:9]
        if np.linalg.norm(V) == 0.0 and self.c_rr > 0.0:  # at rest: the pull, held or not
            n = self.normal(X)
            N = self.normal_force(X, V)
            pull = self.M * self.g * np.linalg.norm(ZHAT - (ZHAT @ n) * n)
            held = min(pull, self.c_rr * N)  # the most the resistance's couple takes
            f = self.k / (1 + self.k) * pull + held / (1 + self.k)
            return f - self.mu * N
        f = self.rolling_force(X, V, W)
        return np.linalg.norm(f) - self.mu * self.normal_force(X, V)

    def _slip_dir(self, y):
        X, V, W = y[0:3], y[3:6], y[6:9]
        if np.linalg.norm(V) == 0.0:  # from rest: along the pull's friction
            n = self.normal(X)
            f = self.M * self.g * (ZHAT - (ZHAT @ n) * n)
            return f / np.linalg.norm(f)
        f = self.rolling_force(X, V, W)
        return f / np.linalg.norm(f)

    def _tangential_at_zero(self, y, start_dir):
        """The tangential spin's state at a sliding start or stop with Omega_t = 0: "stuck" if
        rolling resistance holds it there, else the way its couple acts as it leaves. A state
        whose Omega_t is only rounding (a Cartesian start at rest) is put exactly at zero."""
        X, V, W = y[0:3], y[3:6], y[6:9]
        wt = self.tangential_spin(X, W)
        if self.c_rr == 0.0 or self.a * np.linalg.norm(wt) > 1e-13 * self.scale:
            return None
        y[6:9] = W - wt
        hold = self.tangential_hold(X, V, W, self.sliding_force(X, V, W, start_dir))
        if np.linalg.norm(hold) <= self.c_rr * self.a * self.normal_force(X, V):
            return "stuck"
        return hold / np.linalg.norm(hold)

    def _carry_to_rest(self, t, y, spin):
        """From the stop threshold to zero speed at the deceleration there."""
        X, V, W = y[0:3], y[3:6], y[6:9]
        d = self.rhs(t, y, "rolling", None, spin, None)
        sp = np.linalg.norm(V)
        decel = -(V @ d[3:6]) / sp
        dt = sp / decel if decel > 0 else 0.0
        n = self.normal(X)
        y = np.concatenate([X + 0.5 * dt * V, np.zeros(3), (W @ n) * n])
        return t + dt, y

    def _rest(self, t, y, spin, t_end, events):
        """At rest (speed within the threshold): None if it slips, ("restart", t, y) if the
        resistance cannot hold it, else (fate, t, y) at the end."""
        if np.linalg.norm(y[3:6]) > 0.0:
            t, y = self._carry_to_rest(t, y, spin)
        held_rr, held_mu = self.rest_holds(y[0:3])
        if not held_rr:
            events.append(("rest", t, y.copy()))
            return "restart", t, y
        if not held_mu:
            events.append(("slip", t, y.copy()))
            return None
        events.append(("rest", t, y.copy()))
        n = self.normal(y[0:3])
        wn = y[6:9] @ n
        if wn == 0.0:
            return "rest", t, y
        if self.c_spin == 0.0:
            return "spinning", t, y
        rate = self.c_spin * self.a * self.normal_force(y[0:3], np.zeros(3)) / self.I
        t_stop = t + abs(wn) / rate
        if t_stop > t_end:
            y = y.copy()
            y[6:9] = (wn - math.copysign(rate * (t_end - t), wn)) * n
            return "rolling", t_end, y
        y = y.copy()
        y[6:9] = 0.0
        events.append(("spin_stop", t_stop, y.copy()))
        return "rest", t_stop, y


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

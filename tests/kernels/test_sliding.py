"""The sliding model (engine.kernels.sliding): the energy balance on random states, the rolling
mode against the rolling equations of engine.kernels.model, and the textbook limits on a nearly
flat cone (a thrown ball slides then rolls; spin friction stops a spinning ball), integrated here
with scipy on the kernels' right-hand sides."""

import math

import numpy as np
import pytest
from newton_euler import newton_euler as _newton_euler
from scipy.integrate import solve_ivp

from engine.kernels import cone, layouts, model
from engine.kernels.model import CONE
from engine.kernels.sliding import (
    MODE_ROLLING,
    MODE_SLIDING,
    N_HYBRID,
    hybrid_params,
    hybrid_rhs,
    rolling_rates,
    sliding_rates,
    stick,
)
from engine.scene import Scene


def _hp(alpha, *, mu=0.3, mu_k=0.2, c_rr=0.0, c_spin=0.0, k=0.4, M=1.3, g=9.81):
    p = Scene(M=M, g=g, k=k, mu=mu, c_rr=c_rr).params(alpha)
    return hybrid_params(p, mu_k, c_spin)


def _energy_rate(hp, y, d):
    """dE/dt by the chain rule, E = M(u^2+v^2)/2 + kM(p1^2+p2^2+w^2)/2 + M g r cos(alpha)."""
    M, k, g, al = hp[layouts.P_M], hp[layouts.P_K], hp[layouts.P_G], hp[cone.P_ALPHA]
    r, _, u, v, p1, p2, w = y[:7]
    grad = [M * g * math.cos(al), 0.0, M * u, M * v, k * M * p1, k * M * p2, k * M * w]
    return sum(gi * di for gi, di in zip(grad, d[:7], strict=True))


def _powers(hp, y, mu_k, c_rr, c_spin, stuck):
    """The three dissipated powers, written here from the physics (not from the kernel)."""
    M, g, al = hp[layouts.P_M], hp[layouts.P_G], hp[cone.P_ALPHA]
    r, _, u, v, p1, p2, w = y[:7]
    N = M * (g * math.sin(al) + v * v / (r * math.tan(al)))
    slip = math.hypot(u - p2, v + p1)
    return c_rr * N * math.hypot(p1, p2), mu_k * N * slip, 0.0 if stuck else c_spin * N * abs(w)


@pytest.mark.parametrize("stuck", [False, True])
def test_sliding_energy_balance_on_random_states(stuck):
    rng = np.random.default_rng(16)
    worst = 0.0
    for _ in range(400):
        alpha = rng.uniform(0.05, 1.5)
        mu_k, c_rr, c_spin = rng.uniform(0.0, 0.8), rng.uniform(0.0, 0.2), rng.uniform(0.0, 0.5)
        k = rng.choice([0.4, 2.0 / 3.0, 1.3])
        hp = _hp(alpha, mu_k=mu_k, c_rr=c_rr, c_spin=c_spin, k=k, M=rng.uniform(0.1, 5.0))
        y = np.zeros(N_HYBRID)
        y[0] = rng.uniform(0.05, 5.0)
        y[1] = rng.uniform(-3, 3)
        y[2:7] = rng.uniform(-3.0, 3.0, 5)
        if stuck:
            y[6] = 0.0
        d = sliding_rates.py_func(CONE, y[0], y[2], y[3], y[4], y[5], y[6], stuck, hp)
        powers = _powers(hp, y, mu_k, c_rr, c_spin, stuck)
        dE = _energy_rate(hp, y, d)
        scale = hp[layouts.P_M] * (9.81 * y[0] + np.sum(y[2:7] ** 2)) / y[0] + sum(powers)
        err = abs(dE + sum(powers)) / scale
        worst = max(worst, err)
        assert np.allclose(d[7:], powers, rtol=1e-13, atol=1e-15 * scale)
    assert worst < 1e-13


def test_rolling_mode_is_the_rolling_model_plus_spin_couple():
    rng = np.random.default_rng(7)
    for _ in range(200):
        alpha = rng.uniform(0.05, 1.5)
        c_rr, c_spin = rng.uniform(0.0, 0.2), rng.uniform(0.01, 0.5)
        hp = _hp(alpha, c_rr=c_rr, c_spin=c_spin)
        p = hp[: model.N_PARAMS]
        r, u, v, w = rng.uniform(0.05, 5.0), *rng.uniform(-3, 3, 3)
        d = rolling_rates.py_func(CONE, r, u, v, w, False, hp)
        ref = cone.motion_rates.py_func(r, u, v, w, p, model.ROLLING_RESISTANCE)
        N = hp[layouts.P_M] * (9.81 * math.sin(alpha) + v * v / (r * math.tan(alpha)))
        spin = -c_spin * N * math.copysign(1.0, w) / (0.4 * hp[layouts.P_M])
        assert np.allclose(d[:4], ref[:4], rtol=1e-13, atol=1e-13)
        assert d[6] == pytest.approx(ref[4] + spin, rel=1e-12, abs=1e-13)
        assert (d[4], d[5]) == (-d[3], d[2])  # the constraint p1 = -v, p2 = u is kept
        y = np.array([r, 0.0, u, v, -v, u, w, 0, 0, 0])
        assert _energy_rate(hp, y, d) == pytest.approx(-(d[7] + d[9]), rel=1e-12, abs=1e-12)


def test_stick_removes_the_slip_and_books_the_energy():
    hp = _hp(1.0, c_spin=0.1)
    y = np.array([1.0, 0.0, 0.7, -0.2, 0.3, 0.1, 0.5, 0.0, 0.0, 0.0])
    args = (hp[layouts.P_M], hp[layouts.P_K])
    e0 = 0.5 * args[0] * (y[2] ** 2 + y[3] ** 2) + 0.5 * args[0] * args[1] * np.sum(y[4:7] ** 2)
    lost = stick.py_func(y, hp)
    e1 = 0.5 * args[0] * (y[2] ** 2 + y[3] ** 2) + 0.5 * args[0] * args[1] * np.sum(y[4:7] ** 2)
    assert (y[4], y[5]) == (-y[3], y[2])
    assert e0 - e1 == pytest.approx(lost, rel=1e-12)
    # the angular momentum about the contact point, M u + k M p2 (e1 part), is conserved
    assert y[2] + 0.4 * y[5] == pytest.approx(0.7 + 0.4 * 0.1, rel=1e-14)


def _slide_on_flat(u0, p2_0, k, mu_k):
    """Integrate the sliding rates on alpha = pi/2 - 1e-4 far from the vertex until the slip
    speed falls to 1e-9 u0; returns (t, u)."""
    hp = _hp(math.pi / 2 - 1e-4, mu=1.0, mu_k=mu_k, k=k)
    out = np.empty(N_HYBRID)

    def f(t, y):
        hybrid_rhs(CONE, y, hp, MODE_SLIDING, False, out)
        return out.copy()

    def stop(t, y):
        return math.hypot(y[2] - y[5], y[3] + y[4]) - 1e-9 * u0

    stop.terminal = True
    y0 = np.array([1000.0, 0.0, u0, 0.0, 0.0, p2_0, 0.0, 0.0, 0.0, 0.0])
    sol = solve_ivp(f, (0, 10.0), y0, method="DOP853", rtol=1e-12, atol=1e-14, events=stop)
    assert sol.status == 1
    return sol.t_events[0][0], sol.y_events[0][0]


@pytest.mark.parametrize("k", [0.4, 2.0 / 3.0])
def test_flat_limit_thrown_without_spin(k):
    u0, mu_k, g = 2.0, 0.25, 9.81
    t, y = _slide_on_flat(u0, 0.0, k, mu_k)
    # O(cot alpha) = 1e-4 from the slope; the threshold adds 1e-9.
    assert t == pytest.approx(k * u0 / ((1 + k) * mu_k * g), rel=1e-3)
    assert y[2] == pytest.approx(u0 / (1 + k), rel=1e-3)
    lost = y[8]  # work against sliding friction
    assert lost == pytest.approx(1.3 * u0**2 * k / (2 * (1 + k)), rel=1e-3)


@pytest.mark.parametrize("backspin", [0.5, 8.0])
def test_flat_limit_backspin(backspin):
    k, u0, mu_k = 0.4, 2.0, 0.25
    t, y = _slide_on_flat(u0, -backspin, k, mu_k)
    final = (u0 - k * backspin) / (1 + k)
    assert y[2] == pytest.approx(final, rel=1e-3)
    assert (y[2] < 0) == (backspin > u0 / k)  # it comes back when a omega0 > u0/k


def test_spin_friction_alone_stops_the_spin():
    k, w0, c_spin, g = 0.4, 3.0, 0.05, 9.81
    hp = _hp(math.pi / 2 - 1e-4, c_spin=c_spin, k=k)
    out = np.empty(N_HYBRID)

    def f(t, y):
        hybrid_rhs(CONE, y, hp, MODE_ROLLING, False, out)
        return out.copy()

    def stop(t, y):
        return y[6]

    stop.terminal = True
    y0 = np.array([1000.0, 0.0, 0.0, 0.0, 0.0, 0.0, w0, 0.0, 0.0, 0.0])
    sol = solve_ivp(f, (0, 100.0), y0, method="DOP853", rtol=1e-12, atol=1e-14, events=stop)
    t = sol.t_events[0][0]
    assert t == pytest.approx(k * w0 / (c_spin * g), rel=1e-6)
    assert sol.y_events[0][0][9] == pytest.approx(0.5 * k * 1.3 * w0**2, rel=1e-6)


# ------------------------------------------------------ any surface of revolution, from Newton
#: Centre meridians (rho(t), z(t)) with their first and second derivatives, written out here: a
#: sphere of radius 0.9 (a bowl's centre), a funnel's 1/rho wall, a profile curving both ways.
MERIDIANS = {
    "bowl": lambda t: (0.9 * math.sin(t), -0.9 * math.cos(t), 0.9 * math.cos(t),
                       0.9 * math.sin(t), -0.9 * math.sin(t), 0.9 * math.cos(t)),
    "funnel": lambda t: (t, -0.5 / t, 1.0, 0.5 / t**2, 0.0, -1.0 / t**3),
    "profile": lambda t: (t, 0.3 * t**2 - 0.2 * t**3, 1.0, 0.6 * t - 0.6 * t**2, 0.0,
                          0.6 - 1.2 * t),
}  # fmt: skip
SPOTS = {"bowl": (0.2, 1.3), "funnel": (0.3, 2.0), "profile": (0.2, 1.4)}


@pytest.mark.parametrize("name", sorted(MERIDIANS))
def test_the_sliding_equations_are_newton_and_euler_on_any_surface_of_revolution(name):
    """frame_rates (the sliding equations in the meridian frame, as every model's hybrid state
    uses them) against Newton-Euler in the fixed frame on a bowl, a funnel and a profile, with
    random speeds, spins, contact forces and couples; and the normal force the constraint needs
    against N = M (g cos b + kappa u^2 + sin(b)/rho v^2) (the models' formula)."""
    from engine.kernels.sliding import frame_rates

    rng = np.random.default_rng(5)
    M, k, g, a = 1.3, 0.4, 9.81, 0.02
    worst = 0.0
    for _ in range(50):
        t = rng.uniform(*SPOTS[name])
        theta = rng.uniform(-3.0, 3.0)
        u, v, p1, p2, w = rng.uniform(-2.0, 2.0, 5)
        f1, f2, t1, t2, t3 = rng.uniform(-3.0, 3.0, 5)
        rho, z, rt, zt, rtt, ztt = MERIDIANS[name](t)
        sig = math.hypot(rt, zt)
        cb, sb = rt / sig, zt / sig
        kappa = (rt * ztt - zt * rtt) / sig**3
        e1, e2, nu = _newton_euler(MERIDIANS[name], t, theta, 0.0, 0.0, np.zeros(3),
                                   np.zeros(3), np.zeros(3), M, k, g, a)[2]  # fmt: skip
        P = p1 * e1 + p2 * e2 + w * nu
        f = f1 * e1 + f2 * e2
        T = t1 * e1 + t2 * e2 + t3 * nu
        want, N, _ = _newton_euler(MERIDIANS[name], t, theta, u, v, P, f, T, M, k, g, a)
        frame = (v / rho, N, g * sb, cb / rho, kappa, sb / rho)
        got = frame_rates.py_func(frame, u, v, p1, p2, w, f1, f2, t1, t2, t3, M, k * M)
        scale = g + 4.0 / rho + 3.0 / (k * M)
        err = max(abs(x - y) for x, y in zip(got, want, strict=True)) / scale
        worst = max(worst, err)
        assert N == pytest.approx(M * (g * cb + kappa * u * u + sb / rho * v * v), rel=1e-12)
    assert worst < 1e-12


def _straight(sa, ca):
    """The cone's centre meridian rho = t sin(alpha), z = t cos(alpha) (t = r)."""
    return lambda t: (t * sa, t * ca, sa, ca, 0.0, 0.0)


def test_the_cones_frame_is_its_meridian_seen_as_any_surface():
    """cone.contact_frame (what the hybrid model reads on the cone) against the frame of the
    meridian rho = r sin(alpha), z = r cos(alpha) computed as for any surface above, and the
    cone's sliding rates against Newton-Euler there."""
    rng = np.random.default_rng(9)
    M, k, g = 1.3, 0.4, 9.81
    for _ in range(50):
        alpha = rng.uniform(0.1, 1.5)
        hp = _hp(alpha, M=M, k=k, g=g, mu_k=0.0)
        r, u, v = rng.uniform(0.05, 3.0), *rng.uniform(-2.0, 2.0, 2)
        sa, ca = math.sin(alpha), math.cos(alpha)
        thd, N, gt, c, kappa, kp, drds = cone.contact_frame.py_func(r, u, v, hp)
        assert (thd, c, kappa) == pytest.approx((v / (r * sa), 1.0 / r, 0.0), rel=1e-14)
        assert (gt, kp) == pytest.approx((g * ca, ca / (sa * r)), rel=1e-14)
        assert drds == 1.0  # r is the arc length
        line = _straight(sa, ca)
        _, N_want, _ = _newton_euler(line, r, 0.4, u, v, np.zeros(3), np.zeros(3),
                                     np.zeros(3), M, k, g, 0.02)  # fmt: skip
        assert N == pytest.approx(N_want, rel=1e-12)

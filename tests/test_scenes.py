"""Scenes: right-hand sides per effect set against the physics kernels and the invariants."""

import math

import numba
import numpy as np
import pytest

from engine.integrated import scene_params
from engine.kernels import physics, scenes
from engine.scene import Scene

RNG = np.random.default_rng(7)


@numba.njit
def _rates(y, p, effects):
    out = np.empty((1, y.shape[0]))
    scenes.rhs(y, p, numba.literally(effects), out, 0)
    return out[0]


def rates(y, p, effects):
    return _rates(np.asarray(y, float), p, effects)


def random_state(n=5):
    y = np.empty(n)
    y[0] = RNG.uniform(0.2, 3.0)
    y[1] = RNG.uniform(-10, 10)
    y[2:5] = RNG.normal(0, 2, 3)
    if n == 9:
        q = RNG.normal(size=4)
        y[5:] = q / np.linalg.norm(q)
    return y


@pytest.mark.parametrize("g,k", [(9.81, 0.4), (0.0, 0.4), (9.81, 0.0), (3.7, 2 / 3)])
def test_rhs_matches_physics_kernel(g, k):
    """The scene's rhs (precomputed sin, cos, cot) equals engine.kernels.physics.rhs."""
    for _ in range(20):
        alpha = RNG.uniform(0.05, 1.5)
        p = scene_params(Scene(g=g, k=k), alpha)
        y = random_state()
        got = rates(y, p, 0)
        want = physics.rhs(y[0], y[2], y[3], y[4], alpha, g, k)
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-14)


def _grad(fun, y, h=1e-6):
    g = np.zeros_like(y)
    for i in range(y.size):
        d = np.zeros_like(y)
        d[i] = h * max(1.0, abs(y[i]))
        g[i] = (fun(y + d) - fun(y - d)) / (2 * d[i])
    return g


@pytest.mark.parametrize("g,k", [(9.81, 0.4), (0.0, 0.4), (9.81, 0.0)])
def test_invariants_are_conserved_by_the_equations_of_motion(g, k):
    """dI/dt = grad I . f = 0 for I = E, L_z, h (central differences: relative 1e-7)."""
    M = 1.7
    for _ in range(10):
        alpha = RNG.uniform(0.1, 1.4)
        p = scene_params(Scene(M=M, g=g, k=k), alpha)
        y = random_state()
        f = rates(y, p, 0)
        for idx in range(3):

            def inv(x, idx=idx, p=p):
                return scenes.invariants(x, p)[idx]

            grad = _grad(inv, y)
            scale = np.abs(grad) @ np.abs(f)
            assert abs(grad @ f) <= 1e-7 * scale, ("E", "L_z", "h")[idx]


def test_rolling_resistance_dissipates_at_rate_c_rr_N_speed():
    """With rolling resistance dE/dt = -c_rr N |V| exactly (physics.md: the force c_rr N opposes
    the CM velocity (u, v)); L_z decays, the spin equation is unchanged."""
    for _ in range(10):
        alpha = RNG.uniform(0.1, 1.4)
        sc = Scene(c_rr=RNG.uniform(1e-3, 0.1))
        p = scene_params(sc, alpha)
        y = random_state()
        f = rates(y, p, scenes.ROLLING_RESISTANCE)
        f0 = rates(y, p, 0)
        F, N = scenes.forces(y, p)
        speed = math.hypot(y[2], y[3])
        dE = _grad(lambda x, p=p: scenes.invariants(x, p)[0], y) @ f
        assert dE == pytest.approx(-sc.c_rr * N * speed, rel=1e-6)
        assert f[4] == f0[4] and f[0] == f0[0] and f[1] == f0[1]


def test_quaternion_rate_keeps_norm_and_rolls():
    """q . qdot = 0, and the contact point's velocity R_dot + omega x (-a nu) is zero with omega
    recovered from (q, qdot)."""
    for _ in range(20):
        alpha = RNG.uniform(0.1, 1.4)
        p = scene_params(Scene(a=RNG.uniform(0.001, 0.5), attitude=True), alpha)
        y = random_state(9)
        f = rates(y, p, scenes.ATTITUDE)
        assert abs(y[5:] @ f[5:]) <= 1e-13 * np.linalg.norm(f[5:])
        v = np.array(scenes.contact_velocity(y, f, p))
        speed = math.sqrt(y[2] ** 2 + y[3] ** 2)
        assert np.linalg.norm(v) <= 1e-13 * speed


def test_contact_velocity_detects_a_wrong_convention():
    """The check is not vacuous: a body-frame rate (qdot = q omega / 2) breaks it."""
    alpha = 0.7
    p = scene_params(Scene(attitude=True), alpha)
    y = random_state(9)
    f = rates(y, p, scenes.ATTITUDE)
    wx, wy, wz = (2 * c for c in scenes.omega_fixed(y[1], y[2], y[3], y[4], p))
    q0, q1, q2, q3 = y[5:]
    wrong = f.copy()  # 1/2 q (0, omega): omega taken in body axes
    wrong[5] = 0.25 * (-q1 * wx - q2 * wy - q3 * wz)
    wrong[6] = 0.25 * (q0 * wx + q2 * wz - q3 * wy)
    wrong[7] = 0.25 * (q0 * wy + q3 * wx - q1 * wz)
    wrong[8] = 0.25 * (q0 * wz + q1 * wy - q2 * wx)
    v = np.array(scenes.contact_velocity(y, wrong, p))
    assert np.linalg.norm(v) > 1e-3 * math.hypot(y[2], y[3])


def test_forces_match_physics_kernel():
    for _ in range(10):
        alpha = RNG.uniform(0.1, 1.4)
        sc = Scene(k=0.4, g=9.81, mu=0.3)
        p = scene_params(sc, alpha)
        y = random_state()
        F, N = scenes.forces(y, p)
        F2, N2 = physics.contact_forces(y[0], y[3], y[4], alpha, sc.M, sc.g, sc.k)
        assert F == pytest.approx(F2, rel=1e-13, abs=1e-13)
        assert N == pytest.approx(N2, rel=1e-13)
        assert scenes.slip_margin(y, p) == pytest.approx(abs(F) - 0.3 * N, rel=1e-12, abs=1e-12)


def test_effects_mask_and_state_size():
    assert scenes.effects_mask(()) == 0
    sc = Scene(c_rr=0.1, rim=2.0, mu=0.5, attitude=True)
    assert scenes.effects_mask(sc.effects) == scenes.ALL_EFFECTS
    assert scenes.effects_mask(Scene(rim=1.0).effects) == scenes.RIM
    assert scenes.state_size(0) == 5
    assert scenes.state_size(scenes.ATTITUDE) == 9


def test_parameter_array_layout():
    sc = Scene(M=2.0, g=3.0, a=0.05, k=0.5, rim=7.0, mu=0.2, c_rr=0.01)
    p = scene_params(sc, 0.3)
    assert p.shape == (scenes.N_PARAMS,)
    assert p[scenes.P_ALPHA] == 0.3
    assert p[scenes.P_SIN] == math.sin(0.3) and p[scenes.P_COS] == math.cos(0.3)
    assert p[scenes.P_M] == 2.0 and p[scenes.P_G] == 3.0 and p[scenes.P_K] == 0.5
    assert p[scenes.P_RADIUS] == 0.05 and p[scenes.P_RIM] == 7.0 and p[scenes.P_MU] == 0.2
    assert p[scenes.P_CRR] == 0.01
    assert p[scenes.P_GC] == pytest.approx(3.0 * math.cos(0.3) / 1.5, rel=1e-15)
    q = p.copy()
    scenes.set_alpha(q, 1.1)
    np.testing.assert_array_equal(q, scene_params(sc, 1.1))
    inf = scene_params(Scene(), 0.3)
    assert inf[scenes.P_RIM] == math.inf and inf[scenes.P_MU] == math.inf

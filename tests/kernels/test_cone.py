"""The cone (engine.kernels.cone): equations of motion and invariants, the scene's right-hand
side per effect set through the model interface, contact forces and the parameter array; errata
of the seed paper, each with a test that the paper's version fails."""

import math

import model_oracle as oracle
import numba
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from model_oracle import invariants, rhs, state_from_invariants

from engine.kernels import cone, layouts, model
from engine.kernels import rates as state_rates
from engine.kernels.cone import coefficients, potential, radial_energy
from engine.kernels.effects import ROLLING_EFFECTS
from engine.kernels.geometry import ideal_orbit, scene_params
from engine.kernels.roots import circular_radius
from engine.scene import Scene


def _params(scene, alpha=math.pi / 4):
    return scene.params(alpha)


EPS = 2.220446049250313e-16

states = st.tuples(
    st.floats(0.05, 1.5),  # alpha
    st.floats(0.1, 10.0),  # r
    st.floats(-5.0, 5.0),  # u
    st.floats(-5.0, 5.0),  # v
    st.floats(-5.0, 5.0),  # w
    st.floats(0.1, 10.0),  # M
    st.sampled_from([0.0, 9.81]),  # g
    st.sampled_from([0.0, 0.4, 2.0 / 3.0]),  # k
)


def _invariant_rates(alpha, r, u, v, w, M, g, k, udot, vdot, wdot):
    """dE/dt, dLz/dt, dh/dt along given accelerations (chain rule on the invariants)."""
    s, c = math.sin(alpha), math.cos(alpha)
    dE = (1 + k) * M * (u * udot + v * vdot) + k * M * w * wdot + M * g * u * c
    dL = M * s * (u * v + r * vdot)
    Lz = M * r * v * s
    dh = wdot + Lz * c * u / (M * r * r * s * s) - c * dL / (M * r * s * s)
    scale_E = (1 + k) * M * (abs(u * udot) + abs(v * vdot)) + k * M * abs(w * wdot) + M * g * abs(u)
    scale_L = M * s * (abs(u * v) + abs(r * vdot))
    scale_h = abs(wdot) + abs(Lz * c * u / (M * r * r * s * s))
    return (dE, scale_E), (dL, scale_L), (dh, scale_h)


@given(states)
def test_invariants_conserved_by_equations_of_motion(state):
    alpha, r, u, v, w, M, g, k = state
    _, _, udot, vdot, wdot = rhs(r, u, v, w, alpha, g, k)
    for rate, scale in _invariant_rates(alpha, r, u, v, w, M, g, k, udot, vdot, wdot):
        assert abs(rate) <= 64 * EPS * (scale + 1e-300)


@given(states)
def test_radial_energy_equation(state):
    """calE = M u^2/2 + V(r) with the A, B, C of the README (k general)."""
    alpha, r, u, v, w, M, g, k = state
    E, Lz, h = invariants(r, u, v, w, alpha, M, g, k)
    A, B, C = coefficients(alpha, h, Lz, M, g, k)
    calE = radial_energy(E, h, M, k)
    terms = abs(E) + 0.5 * k * M * h * h + 0.5 * M * u * u + abs(A / r**2) + abs(B / r) + C * r
    assert calE == pytest.approx(0.5 * M * u * u + potential(r, A, B, C), abs=64 * EPS * terms)


def test_state_from_invariants_round_trip():
    alpha, M, g, k = 0.7, 2.0, 9.81, 0.4
    energy, h, Lz = 12.0, -1.3, 0.8
    for r in (0.3, 0.5, 0.9):
        u, v, w = state_from_invariants(r, energy, h, Lz, alpha, M, g, k, True)
        E, L2, h2 = invariants(r, u, v, w, alpha, M, g, k)
        assert L2 == pytest.approx(Lz, rel=1e-15)
        assert h2 == pytest.approx(h, rel=1e-14)
        assert radial_energy(E, h, M, k) == pytest.approx(energy, rel=1e-14)


@given(states)
def test_erratum_eq1_signs_break_Lz_conservation(state):
    """Eq. (1) of the paper: udot = -v^2/r + ..., vdot = +u v/r. Its dL_z/dt = 2 M sin(a) u v."""
    alpha, r, u, v, w, M, g, k = state
    s, c = math.sin(alpha), math.cos(alpha)
    kappa = c / (r * s)
    udot = -(v * v) / r + k / (1 + k) * kappa * v * w - g * c / (1 + k)
    vdot = u * v / r
    wdot = -kappa * u * v
    (_, _), (dL, _), (_, _) = _invariant_rates(alpha, r, u, v, w, M, g, k, udot, vdot, wdot)
    assert dL == pytest.approx(2 * M * s * u * v, rel=1e-12, abs=1e-300)
    if abs(u * v) > 1e-3:
        assert abs(dL) > 1e-6


def test_erratum_eq2_energy_not_conserved():
    """Eq. (2): E = 7/10 M (u^2+v^2) + 7/10 I w^2/a^2 + 7/5 M g z is not constant."""
    alpha, M, g, k = 0.6, 1.0, 9.81, 0.4
    r, u, v, w = 1.0, 0.7, 1.1, 0.4
    _, _, udot, vdot, wdot = rhs(r, u, v, w, alpha, g, k)
    c = math.cos(alpha)
    paper = 1.4 * M * (u * udot + v * vdot) + 1.4 * k * M * w * wdot + 1.4 * M * g * u * c
    ours = (1 + k) * M * (u * udot + v * vdot) + k * M * w * wdot + M * g * u * c
    assert abs(ours) < 1e-14
    assert abs(paper) > 1e-2


def test_erratum_eq21_needs_sin4():
    """k = 2/5: r_c solves 5 M^2 g sin^4 cos r^3 - 2 M Lz h sin^2 cos r - Lz^2 (7 - 5 cos^2) = 0."""
    alpha, M, g, k, h, Lz = 0.5, 1.3, 9.81, 0.4, 0.9, 0.7
    s, c = math.sin(alpha), math.cos(alpha)
    rc = circular_radius(*coefficients(alpha, h, Lz, M, g, k))
    fixed = (
        5 * M**2 * g * s**4 * c * rc**3 - 2 * M * Lz * h * s**2 * c * rc - Lz**2 * (7 - 5 * c**2)
    )
    paper = (
        5 * M**2 * g * s**2 * c * rc**3 - 2 * M * Lz * h * s**2 * c * rc - Lz**2 * (7 - 5 * c**2)
    )
    scale = 5 * M**2 * g * s**4 * c * rc**3
    assert abs(fixed) < 1e-13 * scale
    assert abs(paper) > 1e-2 * scale


bounded_orbits = st.tuples(
    st.floats(0.1, 1.4),
    st.floats(-4.0, 4.0),
    st.floats(0.1, 3.0),
    st.floats(1e-3, 10.0),
)


@given(bounded_orbits)
def test_erratum_universal_relation_factor_two(orbit):
    """r_c^3 = 2 r1^2 r2^2/(r1+r2) + (B/C)(r_c - 2 r1 r2/(r1+r2)); the paper drops the 2."""
    alpha, h, Lz, offset = orbit
    M, g, k = 1.0, 9.81, 0.4
    A, B, C = coefficients(alpha, h, Lz, M, g, k)
    rc = circular_radius(A, B, C)
    vmin = potential(rc, A, B, C)
    energy = vmin + offset * abs(vmin)
    cls, r1, r2, *_ = ideal_orbit(alpha, energy, h, Lz, scene_params(M, g, k), 1e-12)
    assert cls == 1
    hm = r1 * r2 / (r1 + r2)
    fixed = 2 * r1 * r2 * hm + B / C * (rc - 2 * hm)
    paper = 2 * r1 * r2 * hm + B / C * (rc - hm)
    scale = rc**3 + 2 * r1 * r2 * hm + abs(B / C) * (rc + 2 * hm)
    assert abs(rc**3 - fixed) <= 1e-12 * scale
    if abs(B / C) * hm > 1e-6 * scale:
        assert abs(rc**3 - paper) > 1e-9 * scale


def test_erratum_point_particle_free_fall_line():
    """k = 0, g = 0: the path is a straight line on the developed cone: sweep pi / sin(a)."""
    alpha = 0.4
    cls, r1, r2, rc, T, psi, *_ = ideal_orbit(
        alpha, 2.0, 0.0, 0.5, scene_params(1.0, 0.0, 0.0), 1e-12
    )
    assert cls == 3
    assert 2 * psi == pytest.approx(math.pi / math.sin(alpha), rel=1e-15)
    assert np.isinf(r2) and math.isnan(T)


# --- the scene's right-hand side, forces and parameters ---------------------------------
RNG = np.random.default_rng(7)


@numba.njit
def _rates(y, p, effects):
    out = np.empty((1, y.shape[0]))
    state_rates.rhs(y, p, numba.literally(effects), out, 0)
    return out[0]


def rates(y, p, effects):
    return _rates(np.asarray(y, float), p, effects)


def forces(y, p):
    """(F, N) of the state y: the friction along e1 that rolling needs and the normal force."""
    s, c, cot = p[cone.P_SIN], p[cone.P_COS], p[cone.P_COT]
    return cone.contact_forces_of(y[0], y[3], y[4], s, c, cot, p[layouts.P_M], p[layouts.P_G],
                                  p[layouts.P_KK])  # fmt: skip


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
    """The scene's rhs (precomputed sin, cos, cot) equals the plain statement of the equations
    in tests/model_oracle.py."""
    for _ in range(20):
        alpha = RNG.uniform(0.05, 1.5)
        p = _params(Scene(g=g, k=k), alpha)
        y = random_state()
        got = rates(y, p, 0)
        want = oracle.rhs(y[0], y[2], y[3], y[4], alpha, g, k)
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
        p = _params(Scene(M=M, g=g, k=k), alpha)
        y = random_state()
        f = rates(y, p, 0)
        for idx in range(3):

            def inv(x, idx=idx, p=p):
                return cone.invariants(x, p)[idx]

            grad = _grad(inv, y)
            scale = np.abs(grad) @ np.abs(f)
            assert abs(grad @ f) <= 1e-7 * scale, ("E", "L_z", "h")[idx]


def test_rolling_resistance_dissipates_at_rate_c_rr_N_speed():
    """With rolling resistance dE/dt = -c_rr N |V| exactly (docs/physics.md: the force c_rr N
    opposes the CM velocity (u, v)); L_z decays, the spin equation is unchanged."""
    for _ in range(10):
        alpha = RNG.uniform(0.1, 1.4)
        sc = Scene(c_rr=RNG.uniform(1e-3, 0.1))
        p = _params(sc, alpha)
        y = random_state()
        f = rates(y, p, model.ROLLING_RESISTANCE)
        f0 = rates(y, p, 0)
        F, N = forces(y, p)
        speed = math.hypot(y[2], y[3])
        dE = _grad(lambda x, p=p: cone.invariants(x, p)[0], y) @ f
        assert dE == pytest.approx(-sc.c_rr * N * speed, rel=1e-6)
        assert f[4] == f0[4] and f[0] == f0[0] and f[1] == f0[1]


def test_quaternion_rate_keeps_norm_and_rolls():
    """q . qdot = 0, and the contact point's velocity R_dot + omega x (-a nu) is zero with omega
    recovered from (q, qdot)."""
    for _ in range(20):
        alpha = RNG.uniform(0.1, 1.4)
        p = _params(Scene(a=RNG.uniform(0.001, 0.5), attitude=True), alpha)
        y = random_state(9)
        f = rates(y, p, layouts.ATTITUDE)
        assert abs(y[5:] @ f[5:]) <= 1e-13 * np.linalg.norm(f[5:])
        v = np.array(cone.contact_velocity(y, f, p))
        speed = math.sqrt(y[2] ** 2 + y[3] ** 2)
        assert np.linalg.norm(v) <= 1e-13 * speed


def test_contact_velocity_detects_a_wrong_convention():
    """The check is not vacuous: a body-frame rate (qdot = q omega / 2) breaks it."""
    alpha = 0.7
    p = _params(Scene(attitude=True), alpha)
    y = random_state(9)
    f = rates(y, p, layouts.ATTITUDE)
    wx, wy, wz = (2 * c for c in cone.omega_fixed(y[0], y[1], y[2], y[3], y[4], p))
    q0, q1, q2, q3 = y[5:]
    wrong = f.copy()  # 1/2 q (0, omega): omega taken in body axes
    wrong[5] = 0.25 * (-q1 * wx - q2 * wy - q3 * wz)
    wrong[6] = 0.25 * (q0 * wx + q2 * wz - q3 * wy)
    wrong[7] = 0.25 * (q0 * wy + q3 * wx - q1 * wz)
    wrong[8] = 0.25 * (q0 * wz + q1 * wy - q2 * wx)
    v = np.array(cone.contact_velocity(y, wrong, p))
    assert np.linalg.norm(v) > 1e-3 * math.hypot(y[2], y[3])


def test_forces_match_physics_kernel():
    for _ in range(10):
        alpha = RNG.uniform(0.1, 1.4)
        sc = Scene(k=0.4, g=9.81, mu=0.3)
        p = _params(sc, alpha)
        y = random_state()
        F, N = forces(y, p)
        F2, N2 = oracle.contact_forces(y[0], y[3], y[4], alpha, sc.M, sc.g, sc.k)
        assert F == pytest.approx(F2, rel=1e-13, abs=1e-13)
        assert N == pytest.approx(N2, rel=1e-13)
        assert cone.slip_margin(y, p, 0) == pytest.approx(abs(F) - 0.3 * N, rel=1e-12, abs=1e-12)


def test_effects_mask_and_state_size():
    assert Scene().effects_mask == 0
    sc = Scene(c_rr=0.1, rim=2.0, mu=0.5, attitude=True)
    assert sc.effects_mask == ROLLING_EFFECTS
    assert Scene(rim=1.0).effects_mask == model.RIM
    assert layouts.state_size(0) == 5
    assert layouts.state_size(layouts.ATTITUDE) == 9


def test_parameter_array_layout():
    sc = Scene(M=2.0, g=3.0, a=0.05, k=0.5, rim=7.0, mu=0.2, c_rr=0.01)
    p = _params(sc, 0.3)
    assert p.shape == (model.N_PARAMS,)
    assert p[cone.P_ALPHA] == 0.3
    assert p[cone.P_SIN] == math.sin(0.3) and p[cone.P_COS] == math.cos(0.3)
    assert p[layouts.P_M] == 2.0 and p[layouts.P_G] == 3.0 and p[layouts.P_K] == 0.5
    assert p[layouts.P_RADIUS] == 0.05 and p[layouts.P_RIM_SLANT] == 7.0 and p[layouts.P_MU] == 0.2
    assert p[layouts.P_RIM] == pytest.approx(7.0 - 0.05 / math.tan(0.3), rel=1e-15)
    assert p[layouts.P_CRR] == 0.01
    assert p[cone.P_GC] == pytest.approx(3.0 * math.cos(0.3) / 1.5, rel=1e-15)
    q = p.copy()
    cone.set_alpha(q, 1.1)
    np.testing.assert_array_equal(q, _params(sc, 1.1))
    inf = _params(Scene(), 0.3)
    assert inf[layouts.P_RIM] == math.inf and inf[layouts.P_MU] == math.inf

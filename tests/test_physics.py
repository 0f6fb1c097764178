"""Equations of motion and invariants; errata of the seed paper, each with a test that the
paper's version fails."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from engine.kernels.geometry import orbit_point
from engine.kernels.physics import (
    coefficients,
    invariants,
    potential,
    radial_energy,
    rhs,
    state_from_invariants,
)
from engine.kernels.roots import circular_radius

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


def _rates(alpha, r, u, v, w, M, g, k, udot, vdot, wdot):
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
    for rate, scale in _rates(alpha, r, u, v, w, M, g, k, udot, vdot, wdot):
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
    (_, _), (dL, _), (_, _) = _rates(alpha, r, u, v, w, M, g, k, udot, vdot, wdot)
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
    cls, r1, r2, *_ = orbit_point(alpha, energy, h, Lz, M, g, k, math.inf, 1e-12)
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
    cls, r1, r2, rc, T, psi, *_ = orbit_point(alpha, 2.0, 0.0, 0.5, 1.0, 0.0, 0.0, math.inf, 1e-12)
    assert cls == 3
    assert 2 * psi == pytest.approx(math.pi / math.sin(alpha), rel=1e-15)
    assert np.isinf(r2) and math.isnan(T)

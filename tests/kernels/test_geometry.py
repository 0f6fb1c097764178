"""Closed-form geometry: hard cases against the mpmath oracle, properties, conventions."""

import math

import mpmath as mp
import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from model_oracle import contact_forces, state_from_invariants
from oracle import reference, tolerance

import engine
from engine.kernels.cone import coefficients, potential, potential_d1
from engine.kernels.ending import mu_required
from engine.kernels.geometry import (
    BOUNDED,
    CIRCULAR,
    FM_C,
    FM_IGAM,
    FM_RC,
    FORBIDDEN,
    HYPERBOLIC,
    RADIAL,
    SPILLS,
    family,
    ideal_orbit,
    orbit_point,
    scene_params,
)
from engine.kernels.roots import TP_STEPS, cbrt, circular_radius, tp_accept, tp_starts, tp_step

EPS = 2.220446049250313e-16
NAMES = {"r1": 1, "r2": 2, "r_c": 3, "T_r": 4, "psi": 5, "precession_rate": 6}


def _vmin_exact(alpha, h, Lz, M, g, k):
    """V_min in 50-digit arithmetic (so the test's inputs do not come from the code under test)."""
    with mp.workdps(50):
        alpha, h, Lz, M, g, k = map(mp.mpf, (alpha, h, Lz, M, g, k))
        s, c = mp.sin(alpha), mp.cos(alpha)
        kk = k / (1 + k)
        A = Lz**2 / (2 * M * s**2) * (1 + kk * (c / s) ** 2)
        B = kk * h * Lz * c / s**2
        C = M * g * c / (1 + k)
        if C == 0:
            return -(B**2) / (4 * A), A, B
        rc = [
            r
            for r in mp.polyroots([C, 0, -B, -2 * A], maxsteps=200, extraprec=200)
            if abs(mp.im(r)) < 1e-30 and mp.re(r) > 0
        ][0]
        rc = mp.re(rc)
        return A / rc**2 + B / rc + C * rc, A, B


def _check_against_oracle(alpha, energy, h, Lz, M=1.0, g=9.81, k=0.4):
    cls_ref, vals, cond = reference(alpha, energy, h, Lz, M, g, k)
    got = ideal_orbit(alpha, energy, h, Lz, scene_params(M, g, k), 1e-12)
    assert engine.CLASS_NAMES[got[0]] == cls_ref
    for key, idx in NAMES.items():
        if key == "r2" and cls_ref == "hyperbolic":
            assert got[2] == math.inf
            continue
        if key not in vals:
            assert math.isnan(got[idx]), key
            continue
        assert np.isfinite(got[idx]), key
        assert got[idx] == pytest.approx(vals[key], rel=tolerance(cond.get(key))), key
    if cls_ref != "hyperbolic":
        assert np.isfinite(got[7])
    return got, vals, cond


# --- named hard cases -------------------------------------------------------------------


def test_hard_alpha_near_cylinder():
    _check_against_oracle(1e-3, 5e4, 1.5, 2e-3)


def test_hard_alpha_near_plane():
    alpha = math.pi / 2 - 1e-3
    vmin, *_ = _vmin_exact(alpha, 0.7, 0.8, 1.0, 9.81, 0.4)
    _check_against_oracle(alpha, float(vmin * 3), 0.7, 0.8)


def test_hard_Lz_grazes_axis():
    got, vals, _ = _check_against_oracle(0.6, 2.0, -1.2, 1e-7)
    assert 0 < got[1] < 1e-6 < got[2]


def test_hard_energy_just_above_circular_minimum():
    alpha, h, Lz = 0.7, 1.1, 0.9
    vmin, *_ = _vmin_exact(alpha, h, Lz, 1.0, 9.81, 0.4)
    energy = float(vmin * (1 + mp.mpf("1e-10")))
    got, vals, cond = _check_against_oracle(alpha, energy, h, Lz)
    assert got[0] == BOUNDED
    # The gap r2 - r1 (~1e-5 r_c) as accurate as its conditioning allows.
    with mp.workdps(50):
        gap_ref = mp.mpf(vals["r2"]) - mp.mpf(vals["r1"])
    gap_cond = (cond["r1"] * vals["r1"] + cond["r2"] * vals["r2"]) / float(gap_ref)
    assert got[2] - got[1] == pytest.approx(
        float(gap_ref), rel=tolerance(gap_cond) + 4 * EPS * got[2] / float(gap_ref)
    )


@pytest.mark.parametrize("e", [0.999, 1.001])
def test_hard_free_fall_eccentricity_near_one(e):
    alpha, h, Lz, k = 0.5, -2.0, 0.7, 0.4
    vmin, A, B = _vmin_exact(alpha, h, Lz, 1.0, 0.0, k)
    energy = float(vmin * (1 - mp.mpf(e) ** 2))
    got, vals, _ = _check_against_oracle(alpha, energy, h, Lz, g=0.0, k=k)
    Om = math.sqrt(1 - math.cos(alpha) ** 2 / (1 + k))
    if e < 1:
        assert got[0] == BOUNDED
        assert got[5] == pytest.approx(math.pi / Om, rel=4 * EPS)
    else:
        assert got[0] == HYPERBOLIC
        # half the sweep 2 arccos(-1/e)/Omega, evaluated independently in mpmath
        with mp.workdps(40):
            e_exact = mp.sqrt(1 + 4 * A * mp.mpf(energy) / B**2)
            half = mp.acos(-1 / e_exact) / mp.sqrt(1 - mp.cos(mp.mpf(alpha)) ** 2 / (1 + mp.mpf(k)))
        assert got[5] == pytest.approx(float(half), rel=1e-12)


@pytest.mark.parametrize("M", [1e-3, 1e3])
def test_hard_extreme_mass(M):
    alpha, h, Lz = 0.4, -1.0, 0.3 * M
    vmin, *_ = _vmin_exact(alpha, h, Lz, M, 9.81, 0.4)
    _check_against_oracle(alpha, float(vmin * 1.7), h, Lz, M=M)


@pytest.mark.parametrize("k", [0.0, 2.0 / 3.0])
def test_other_inertia_factors(k):
    vmin, *_ = _vmin_exact(0.9, 2.0, -0.4, 1.0, 9.81, k)
    _check_against_oracle(0.9, float(vmin * 1.3), 2.0, -0.4, k=k)


def test_spin_dominated_orbits_both_signs():
    for h in (40.0, -40.0):
        vmin, *_ = _vmin_exact(0.6, h, 0.5, 1.0, 9.81, 0.4)
        _check_against_oracle(0.6, float(vmin + 0.5 * abs(vmin)), h, 0.5)


# --- conventions ------------------------------------------------------------------------


def test_radial_convention():
    alpha, energy, M, g, k = 0.5, 3.0, 2.0, 9.81, 0.4
    cls, r1, r2, rc, T, psi, prec, mu = ideal_orbit(
        alpha, energy, 0.3, 0.0, scene_params(M, g, k), 1e-12
    )
    C = M * g * math.cos(alpha) / (1 + k)
    assert cls == RADIAL and r1 == 0.0
    assert r2 == pytest.approx(energy / C, rel=4 * EPS)
    assert T == pytest.approx(2 * math.sqrt(2 * M * r2 / C), rel=4 * EPS)
    assert math.isnan(psi) and math.isnan(prec) and math.isnan(rc)
    assert mu == pytest.approx(k / (1 + k) / math.tan(alpha), rel=4 * EPS)
    assert ideal_orbit(alpha, -1.0, 0.3, 0.0, scene_params(M, g, k), 1e-12)[0] == FORBIDDEN
    assert ideal_orbit(alpha, 1.0, 0.3, 0.0, scene_params(M, 0.0, k), 1e-12)[0] == FORBIDDEN


def test_forbidden_reports_r_circ_and_nothing_else():
    cls, r1, r2, rc, T, psi, prec, mu = ideal_orbit(
        0.5, -100.0, 1.0, 1.0, scene_params(1.0, 9.81, 0.4), 1e-12
    )
    assert cls == FORBIDDEN and np.isfinite(rc)
    assert all(math.isnan(x) for x in (r1, r2, T, psi, prec, mu))


def test_free_fall_zero_energy_rules():
    # B < 0, calE = 0: the e = 1 escape sweeping 2 pi / Omega; B > 0, calE = 0: forbidden.
    alpha, k = 0.5, 0.4
    Om = math.sqrt(1 - math.cos(alpha) ** 2 / (1 + k))
    got = ideal_orbit(alpha, 0.0, -1.0, 1.0, scene_params(1.0, 0.0, k), 1e-12)
    assert got[0] == HYPERBOLIC and 2 * got[5] == pytest.approx(2 * math.pi / Om, rel=4 * EPS)
    assert ideal_orbit(alpha, 0.0, 1.0, 1.0, scene_params(1.0, 0.0, k), 1e-12)[0] == FORBIDDEN
    # B = 0 (h = 0): sweep pi / Omega
    got = ideal_orbit(alpha, 1.0, 0.0, 1.0, scene_params(1.0, 0.0, k), 1e-12)
    assert got[0] == HYPERBOLIC and 2 * got[5] == pytest.approx(math.pi / Om, rel=4 * EPS)


def test_circular_class_tolerance_and_limit_values():
    alpha, h, Lz, M, g, k = 0.8, 0.5, 1.2, 1.0, 9.81, 0.4
    A, B, C = coefficients(alpha, h, Lz, M, g, k)
    rc = circular_radius(A, B, C)
    vmin = potential(rc, A, B, C)
    got = ideal_orbit(alpha, vmin, h, Lz, scene_params(M, g, k), 1e-12)
    assert got[0] == CIRCULAR and got[1] == got[2] == rc
    # a wider tolerance turns a near-circular orbit into the circular class
    e = vmin + 1e-9 * abs(vmin)
    assert ideal_orbit(alpha, e, h, Lz, scene_params(M, g, k), 1e-12)[0] == BOUNDED
    assert ideal_orbit(alpha, e, h, Lz, scene_params(M, g, k), 1e-8)[0] == CIRCULAR


def test_rim_spills():
    alpha, h, Lz = 0.7, 0.5, 1.0
    got = ideal_orbit(alpha, 20.0, h, Lz, scene_params(1.0, 9.81, 0.4), 1e-12)
    assert got[0] == BOUNDED
    r2 = got[2]
    # the rim is the real cone's slant length: the centre reaches it at rim - a cot(alpha)
    a = 0.01
    rim = r2 + a / math.tan(alpha)
    args = (alpha, 20.0, h, Lz)
    assert orbit_point(*args, scene_params(1.0, 9.81, 0.4, a, rim * 0.99), 1e-12)[0] == SPILLS
    assert orbit_point(*args, scene_params(1.0, 9.81, 0.4, a, rim * 1.01), 1e-12)[0] == BOUNDED


# --- properties -------------------------------------------------------------------------

orbits = st.tuples(
    st.floats(0.02, 1.55),  # alpha
    # h: 0 or |h| >= 1e-6 (below ~1e-150, B^2 underflows and V_min rounds to 0: outside the
    # supported domain of double precision)
    st.one_of(st.just(0.0), st.floats(1e-6, 10.0), st.floats(-10.0, -1e-6)),
    st.floats(1e-4, 5.0),  # |Lz|
    st.booleans(),  # sign of Lz
    st.floats(-8.0, 3.0),  # log10 relative offset above V_min
    st.sampled_from([0.0, 0.4, 2.0 / 3.0]),
    st.sampled_from([9.81, 1.0, 0.0]),
)


def _bounded_point(o):
    alpha, h, Lz, neg, logoff, k, g = o
    Lz = -Lz if neg else Lz
    A, B, C = coefficients(alpha, h, Lz, 1.0, g, k)
    rc = circular_radius(A, B, C)
    assume(not math.isnan(rc))
    vmin = potential(rc, A, B, C)
    off = 10.0**logoff
    if g == 0.0:
        off = min(off, 0.999)  # stay bounded in free fall (energy < 0)
    energy = vmin + off * abs(vmin)
    return alpha, energy, h, Lz, k, g, A, B, C, rc


@given(orbits)
def test_turning_points_are_roots_and_bracket_r_circ(o):
    alpha, energy, h, Lz, k, g, A, B, C, rc = _bounded_point(o)
    cls, r1, r2, rc2, T, psi, prec, mu = ideal_orbit(
        alpha, energy, h, Lz, scene_params(1.0, g, k), 1e-12
    )
    assert cls == BOUNDED
    assert r1 <= rc2 <= r2
    for r in (r1, r2):
        terms = abs(A / r**2) + abs(B / r) + abs(C * r) + abs(energy)
        resid = potential(r, A, B, C) - energy
        assert abs(resid) <= 64 * EPS * (terms + r * abs(potential_d1(r, A, B, C)))
    assert all(np.isfinite(x) and x > 0 for x in (T, psi))
    assert np.isfinite(mu) and (mu > 0 if k > 0 else mu == 0)


@given(orbits)
def test_apsidal_angle_continuous_across_circular_limit(o):
    alpha, _, h, Lz, k, g, A, B, C, rc = _bounded_point(o)
    vmin = potential(rc, A, B, C)
    circ = ideal_orbit(alpha, vmin, h, Lz, scene_params(1.0, g, k), 1e-12)
    off = 1e-10
    near = ideal_orbit(alpha, vmin + off * abs(vmin), h, Lz, scene_params(1.0, g, k), 1e-12)
    assert circ[0] == CIRCULAR and near[0] == BOUNDED
    # T and psi are smooth in energy: they move by O(offset) (here O(1) x 1e-10) plus rounding.
    for idx in (4, 5):
        assert near[idx] == pytest.approx(circ[idx], rel=1e3 * off + 1e-12)


@given(orbits)
def test_mu_required_is_max_of_force_ratio_on_orbit(o):
    alpha, energy, h, Lz, k, g, A, B, C, rc = _bounded_point(o)
    assume(k > 0)
    got = ideal_orbit(alpha, energy, h, Lz, scene_params(1.0, g, k), 1e-12)
    r1, r2, mu = got[1], got[2], got[7]
    rs = np.geomspace(r1, r2, 2001)
    ratios = []
    for r in rs:
        u, v, w = state_from_invariants(r, energy, h, Lz, alpha, 1.0, g, k, True)
        F, N = contact_forces(r, v, w, alpha, 1.0, g, k)
        ratios.append(abs(F) / N)
    sampled = max(ratios)
    assert sampled <= mu * (1 + 1e-12)
    # the sampled maximum approaches the exact one (2001 geometric samples)
    assert sampled >= mu * (1 - 1e-3 * (1 + math.log(r2 / r1)))


def test_mu_required_free_fall_escape_is_infinite_with_spin():
    # Far away N falls off like r^-3 but the needed friction only like r^-2.
    assert mu_required(1.0, math.inf, 0.5, 1.0, 1.0, 1.0, 0.0, 0.4) == math.inf
    assert mu_required(1.0, math.inf, 0.5, 0.0, 1.0, 1.0, 0.0, 0.4) == pytest.approx(
        0.4 / 1.4 / math.tan(0.5), rel=4 * EPS
    )


# --- roots: the fast paths and their fallbacks -------------------------------------------------


def test_circular_radius_over_all_scales_against_mpmath():
    # b = B/(C q^2) over 20 decades of both signs, and 2A/C outside the bit estimate's range
    # (the monotone Newton path); the root to a few ulps of the 50-digit one.
    cases = [(1.0, b * 3.0, 2.0) for b in (-1e10, -1e3, -3.0, -0.46, -1e-8, 0.0, 1e-8, 0.58, 1.07,
                                           40.0, 1e6, 1e10)]  # fmt: skip
    cases += [(1e-160, -1e-100, 1e150), (1e150, 1e100, 1e-151), (3e-300, 0.0, 1.0)]
    for A, B, C in cases:
        with mp.workdps(50):  # in units of q = (2A/C)^(1/3): t^3 - b t - 1 = 0
            q = mp.cbrt(2 * mp.mpf(A) / mp.mpf(C))
            b = mp.mpf(B) / (mp.mpf(C) * q * q)
            roots = mp.polyroots([1, 0, -b, -1], maxsteps=400, extraprec=400)
            ref = q * max(mp.re(t) for t in roots if abs(mp.im(t)) < mp.mpf(10) ** -30)
        got = circular_radius(A, B, C)
        assert got == pytest.approx(float(ref), rel=4 * EPS, abs=0), (A, B, C)


def test_cube_root_estimate_and_halley_steps():
    x = 10.0 ** np.linspace(-299, 299, 2001)
    got = np.array([cbrt(v) for v in x])
    with mp.workdps(30):
        ref = np.array([float(mp.cbrt(mp.mpf(v))) for v in x])
    assert np.max(np.abs(got / ref - 1)) < 1e-14
    assert cbrt(1e-310) == pytest.approx(1e-310 ** (1 / 3), rel=1e-14)  # outside: x ** (1/3)


def test_outer_root_that_plain_halley_steps_miss_takes_the_safe_path():
    # c3 = C r_c / (C r_c + A/r_c^2) ~ 4e-22 (nearly free fall) and energy - V_min ~ the well's
    # depth: the plain steps from the start of r2 converge to r1; the bracketed path finds r2.
    alpha, energy, h, Lz = (
        0.312333948390878,
        -0.013947063978987541,
        -673061.7799951712,
        5.818775364816308e-05,
    )
    M, g, k = 1e3, 50.0, 2.0 / 3.0
    fam = family(alpha, h, Lz, scene_params(M, g, k), False)
    rc, a, vmin, c3, igam = fam[FM_RC : FM_IGAM + 1]
    delta = energy - vmin
    r1, r2 = tp_starts(rc, a, delta, c3, igam)
    for _ in range(TP_STEPS):
        r1, d1 = tp_step(r1, rc, fam[FM_C], a, delta)
        r2, d2 = tp_step(r2, rc, fam[FM_C], a, delta)
    assert tp_accept(r1, d1, rc, True) and not tp_accept(r2, d2, rc, False)
    got, vals, _ = _check_against_oracle(alpha, energy, h, Lz, M=M, g=g, k=k)
    assert got[2] / got[1] > 1e10


def test_hard_near_circular_turning_point_not_polished_on_a_flat_function():
    # Near the minimum energy - V(r) is flat at the turning points; a Newton polish on it (taken
    # where V there is evaluated with about the same rounding as V_min) left r_min and r_max
    # ~1e-10 off (inside their conditioning, 5e-8) but T_r, psi and the precession rate too
    # (condition numbers ~3: tolerance 1e-12).
    _check_against_oracle(
        1.039111649458888, 80.3900030086475, -128.52878923409097, 1728.5256646277282
    )

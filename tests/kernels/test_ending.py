"""Where a conservative orbit stops rolling on the scene's cone (engine.kernels.ending and the
scene rules of engine.kernels.geometry), against computations written here: a dense scan of
|F|/N along the orbit, mpmath quadrature of dt and dtheta, and the 3-D geometry of the contact
point."""

import math

import mpmath as mp
import numpy as np
import pytest
from model_oracle import coefficients, contact_forces, state_from_invariants

import engine
from engine.kernels.ending import first_slip, time_and_azimuth
from engine.kernels.geometry import (
    BOUNDED,
    HYPERBOLIC,
    OFF_CONE,
    OUT_OF_RANGE,
    RADIAL,
    SLIPS,
    SPILLS,
    ideal_orbit,
    orbit_point,
    scene_params,
)

M, G, K = 1.0, 9.81, 0.4


def _ratio_along(r, alpha, energy, h, Lz, M=M, g=G, k=K):
    """|F|/N at radius r of the orbit, from the plain statement of the forces."""
    u, v, w = state_from_invariants(r, energy, h, Lz, alpha, M, g, k, True)
    F, N = contact_forces(r, v, w, alpha, M, g, k)
    return abs(F) / N


def _first_slip_scan(r1, r2, mu, *args):
    """The smallest r in [r1, r2] with |F|/N > mu: a scan of 20000 points, then bisection."""
    rs = np.linspace(r1, r2, 20001)
    ratios = np.array([_ratio_along(r, *args) for r in rs])
    over = np.flatnonzero(ratios > mu)
    if over.size == 0:
        return math.nan
    i = over[0]
    if i == 0:
        return r1
    lo, hi = rs[i - 1], rs[i]
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _ratio_along(mid, *args) > mu else (mid, hi)
    return hi


@pytest.mark.parametrize(
    "alpha,energy,h,Lz,mu",
    [
        (1.1, 9.0, -2.0, 1.2, 0.1),  # |F|/N grows from 0.041 at r_min to 0.140 at r_max
        (0.9, 8.0, -3.0, 0.6, 0.15),  # 0.038 .. 0.208
        (0.5, 20.0, 1.0, 0.8, 0.6),  # 0.591 at r_min, 0.616 inside
        (1.2, 6.0, 2.0, 1.5, 0.1),  # largest at r_min: slips at once
        (1.2, 6.0, 2.0, 1.5, 0.2),  # never
    ],
)
def test_first_slip_radius_matches_a_dense_scan(alpha, energy, h, Lz, mu):
    cls, r1, r2, *_ = ideal_orbit(alpha, energy, h, Lz, scene_params(M, G, K), 1e-12)
    assert cls == BOUNDED
    args = (alpha, energy, h, Lz)
    want = _first_slip_scan(r1, r2, mu, *args)
    got = first_slip(r1, r2, alpha, h, Lz, M, G, K, mu)
    if math.isnan(want):
        assert math.isnan(got)
    else:
        assert got == pytest.approx(want, rel=1e-10)
        assert _ratio_along(got * (1 + 1e-9), *args) > mu or got == r1


def _quad_t_theta(r_end, energy, alpha, h, Lz, g=G):
    """t and theta from the inner turning point to r_end by mpmath tanh-sinh on r = r1 + s^2
    (no elliptic integrals, no Gauss-Kronrod), at 30 digits, r1 found here (polyroots)."""
    A, B, C = coefficients(alpha, h, Lz, M, g, K)
    Kang = abs(Lz) / (M * math.sin(alpha) ** 2)
    with mp.workdps(30):
        A, B, C, E = (mp.mpf(x) for x in (A, B, C, energy))
        roots = mp.polyroots([C, -E, B, A] if g > 0 else [-E, B, A], maxsteps=200, extraprec=60)
        r1m = min(mp.re(z) for z in roots if mp.re(z) > 0 and abs(mp.im(z)) < 1e-20)

        def rate(s):
            r = r1m + s * s
            kin = (2 / M) * (E - A / r**2 - B / r - C * r)
            return 2 * s / mp.sqrt(kin) if kin > 0 else mp.mpf(0)

        smax = mp.sqrt(mp.mpf(r_end) - r1m)
        t = mp.quad(rate, [0, smax])
        th = mp.quad(lambda s: Kang * rate(s) / (r1m + s * s) ** 2, [0, smax])
    return float(t), float(th)


@pytest.mark.parametrize("frac", [0.3, 0.9, 0.999])
def test_time_and_azimuth_to_a_radius_under_gravity(frac):
    alpha, h, Lz = 0.6, 1.0, 0.7
    vmin = float(engine.minimum_energy(alpha, h, Lz))
    energy = vmin + 1.2 * abs(vmin)
    cls, r1, r2, rc, T, psi, *_ = ideal_orbit(alpha, energy, h, Lz, scene_params(M, G, K), 1e-12)
    A, B, C = coefficients(alpha, h, Lz, M, G, K)
    r_end = r1 + frac * (r2 - r1)
    Kang = abs(Lz) / (M * math.sin(alpha) ** 2)
    t, th = time_and_azimuth(r_end, r1, r2, energy, A, C, M, Kang)
    t_ref, th_ref = _quad_t_theta(r_end, energy, alpha, h, Lz)
    assert t == pytest.approx(t_ref, rel=1e-11)
    assert th == pytest.approx(th_ref, rel=1e-11)


def test_time_and_azimuth_to_the_outer_turning_point_are_half_the_period_and_psi():
    """Quadrature to r2 against the closed form's cel (two independent evaluations)."""
    for alpha, h, Lz, rel in [(0.6, 1.0, 0.7, 1.2), (1.3, -2.0, 0.2, 30.0), (0.2, 0.5, 1.0, 1e-3)]:
        vmin = float(engine.minimum_energy(alpha, h, Lz))
        energy = vmin + rel * abs(vmin)
        cls, r1, r2, rc, T, psi, *_ = ideal_orbit(
            alpha, energy, h, Lz, scene_params(M, G, K), 1e-12
        )
        A, B, C = coefficients(alpha, h, Lz, M, G, K)
        Kang = abs(Lz) / (M * math.sin(alpha) ** 2)
        t, th = time_and_azimuth(r2, r1, r2, energy, A, C, M, Kang)
        assert t == pytest.approx(T / 2, rel=1e-12)
        assert th == pytest.approx(psi, rel=1e-12)


def test_time_and_azimuth_of_free_fall_ellipse_escape_and_radial_orbit():
    alpha, h, Lz = 0.7, -1.5, 0.6
    A, B, C = coefficients(alpha, h, Lz, M, 0.0, K)
    Kang = abs(Lz) / (M * math.sin(alpha) ** 2)
    # ellipse: the quadrature to r2 is half of T = pi (r1 + r2) sqrt(M / (2 |calE|))
    e = -0.05
    cls, r1, r2, rc, T, psi, *_ = ideal_orbit(alpha, e, h, Lz, scene_params(M, 0.0, K), 1e-12)
    t, th = time_and_azimuth(r2, r1, r2, e, A, 0.0, M, Kang)
    assert t == pytest.approx(T / 2, rel=1e-12) and th == pytest.approx(psi, rel=1e-12)
    # escape: against mpmath
    e = 0.3
    cls, r1, r2, *_ = ideal_orbit(alpha, e, h, Lz, scene_params(M, 0.0, K), 1e-12)
    assert cls == HYPERBOLIC
    r_end = 7.0 * r1
    t, th = time_and_azimuth(r_end, r1, math.inf, e, A, 0.0, M, Kang)
    t_ref, th_ref = _quad_t_theta(r_end, e, alpha, h, Lz, g=0.0)
    assert t == pytest.approx(t_ref, rel=1e-11) and th == pytest.approx(th_ref, rel=1e-11)
    # radial (L_z = 0): t = sqrt(2M)/C (sqrt(calE) - sqrt(calE - C r))
    A, B, C = coefficients(alpha, 0.0, 0.0, M, G, K)
    t, th = time_and_azimuth(0.5, 0.0, 3.0 / C, 3.0, A, C, M, 0.0)
    assert th == 0.0
    assert t == pytest.approx(math.sqrt(2 * M) / C * (math.sqrt(3.0) - math.sqrt(3.0 - 0.5 * C)))


def test_rim_is_the_real_cones_slant_length():
    """The contact point's distance from the real vertex, in 3-D: R - a nu from the vertex
    (0, 0, -a / sin(alpha)) is r + a cot(alpha)."""
    for alpha, r, a in [(0.2, 1.0, 0.01), (1.2, 0.3, 0.05), (0.7, 5.0, 0.2)]:
        s, c = math.sin(alpha), math.cos(alpha)
        e1 = np.array([s, 0.0, c])
        nu = np.array([-c, 0.0, s])
        contact = r * e1 - a * nu
        vertex = np.array([0.0, 0.0, -a / s])
        slant = np.linalg.norm(contact - vertex)
        assert slant == pytest.approx(r + a * c / s, rel=1e-14)
    # a = 1 cm, alpha = 0.2: the centre is 4.93 cm short of the rim
    assert 0.01 / math.tan(0.2) == pytest.approx(0.0493, abs=1e-4)


def test_scene_rules_off_cone_escapes_spill_and_slips_first():
    a = 0.01
    alpha, h, Lz = 0.7, -1.5, 0.6
    esc = orbit_point(alpha, 0.3, h, Lz, scene_params(M, 0.0, K, a, 2.0, math.inf), 1e-12)
    assert esc[0] == SPILLS  # every escape spills on a finite cone
    assert esc[8] == pytest.approx(2.0 - a / math.tan(alpha), rel=1e-15)
    ell = orbit_point(alpha, -0.05, h, Lz, scene_params(M, 0.0, K, a, 2.0, math.inf), 1e-12)
    r1 = ell[1]
    beyond = orbit_point(alpha, -0.05, h, Lz, scene_params(M, 0.0, K, a, 0.5 * r1, math.inf), 1e-12)
    assert beyond[0] == OFF_CONE and math.isnan(beyond[8])
    # slip before the rim: SLIPS at the first failing radius; the rim first: SPILLS
    orbit = (1.1, 9.0, -2.0, 1.2)
    cls, r1, r2, *_, mur = ideal_orbit(*orbit, scene_params(M, G, K), 1e-12)
    mu = 0.1
    rs = first_slip(r1, r2, 1.1, -2.0, 1.2, M, G, K, mu)
    assert r1 < rs < r2
    far = orbit_point(*orbit, scene_params(M, G, K, a, 1e3, mu), 1e-12)
    assert far[0] == SLIPS and far[8] == rs
    rim_first = (rs + r1) / 2 + a / math.tan(1.1)
    near = orbit_point(*orbit, scene_params(M, G, K, a, rim_first, mu), 1e-12)
    assert near[0] == SPILLS
    holds = orbit_point(*orbit, scene_params(M, G, K, a, math.inf, mur * 1.001), 1e-12)
    assert holds[0] == BOUNDED
    # a radial orbit slips at once where cot(alpha) k/(1+k) > mu
    rad = orbit_point(0.5, 3.0, 0.0, 0.0, scene_params(M, G, K, a, math.inf, 0.1), 1e-12)
    assert rad[0] == SLIPS and rad[8] == 0.0 and rad[9] == 0.0
    assert (
        orbit_point(0.5, 3.0, 0.0, 0.0, scene_params(M, G, K, a, math.inf, 0.9), 1e-12)[0] == RADIAL
    )


def test_tiny_Lz_is_right_or_out_of_range():
    """L_z -> 0 (issue 9: 1e-125 gave r_min 4.3e-108 and psi 6.4e-18). The apsidal angle
    converges as L_z -> 0 (the orbit tends to a radial one): 1e-125 agrees with 1e-60 and
    1e-30 to rounding; r_min solves calE = V(r) (V written here); past double precision the
    class is out_of_range, never bounded with NaN."""
    lz = np.array([1e-30, 1e-60, 1e-100, 1e-125, 1e-140])
    ds = engine.evaluate(0.5, 5.0, 0.0, lz)
    assert (ds.orbit_class.values == BOUNDED).all()
    psi = ds.apsidal_angle.values
    np.testing.assert_allclose(psi, psi[0], rtol=1e-13)
    assert psi[0] == pytest.approx(2.342, abs=1e-3)
    for L, r in zip(lz, ds.r_min.values, strict=True):
        A, B, C = coefficients(0.5, 0.0, L, M, G, K)
        assert (A / r**2 + C * r) == pytest.approx(5.0, rel=1e-13)
    far = engine.evaluate(0.5, 5.0, 0.0, [1e-170, 1e-200])
    assert (far.orbit_class.values == OUT_OF_RANGE).all()
    assert np.isnan(far.r_min.values).all()
    big = engine.evaluate(0.5, 5.0, 0.0, 1e160)  # A ~ L_z^2 / (2 M sin^2 alpha) overflows
    assert int(big.orbit_class) == OUT_OF_RANGE
    with pytest.raises(ValueError, match="Scene.M must be at most 1e150"):
        engine.Scene(M=1e308)  # refused before any run (docs/api.md, "Input bounds")
    thin = engine.evaluate(1e-78, 5.0, 0.0, 0.8)
    assert int(thin.orbit_class) == OUT_OF_RANGE


def test_free_fall_mu_required_far_out_is_finite():
    """Free fall: |F|/N = k/(1+k) |h M sin(a) r / L_z + cot(a)| is linear in r, so
    mu_required is its larger end value; an orbit reaching r ~ 2e194 (where p2 / x overflowed)
    has a finite one."""
    alpha, energy, h, Lz = 1.0, -1e-80, -1.0, 1e115
    cls, r1, r2, *_, mur = ideal_orbit(alpha, energy, h, Lz, scene_params(M, 0.0, K), 1e-12)
    assert cls == BOUNDED and r2 > 1e194
    f = [h * M * math.sin(alpha) / Lz * r + 1.0 / math.tan(alpha) for r in (r1, r2)]
    assert mur == pytest.approx(K / (1 + K) * max(abs(x) for x in f), rel=1e-14)

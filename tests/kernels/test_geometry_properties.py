"""Property-based tests (hypothesis): the exact kernels over the whole physical domain against
the class table of the README."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, target
from hypothesis import strategies as st

import engine
from engine.kernels.geometry import (
    BOUNDED,
    CIRCULAR,
    FORBIDDEN,
    HYPERBOLIC,
    OFF_CONE,
    OUT_OF_RANGE,
    RADIAL,
    SPILLS,
)

PI_2 = math.pi / 2
BELOW_PI_2 = math.nextafter(PI_2, 0.0)
EPS = 2.220446049250313e-16
FLOAT_NAMES = (
    "r_min",
    "r_max",
    "r_circ",
    "period",
    "apsidal_angle",
    "precession_rate",
    "mu_required",
)

# --- 3. kernels over the whole valid domain ---------------------------------------------------

# Input domain. A = Lz^2 (1 + k/(1+k) cot^2 a)/(2 M sin^2 a), B = k/(1+k) h Lz cos a/sin^2 a and
# C = M g cos a/(1+k) must neither overflow nor underflow in double precision, so:
# |h|, |Lz| in [1e-6, 1e6] or exactly 0; alpha in [1e-8, pi/2) (up to the largest double below
# pi/2, where cos a ~ 2.8e-16); M in [1e-3, 1e3]; g in {0} U [1e-3, 1e2]; k in {0} U [1e-4, 5]
# (k/(1+k) >= ~1e-4 keeps B clear of underflow). Then 1e-50 < |A|, |B|, C < 1e50 (or exactly
# 0). The energy is either absolute (0 or +-[1e-6, 1e6]) or V_min + x |V_min| with
# x in {0} U +-[1e-16, 1e3], so that bounded, circular and near-circular orbits occur at any
# scale of V_min.


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi).map(lambda e: 10.0**e)


def signed(s: st.SearchStrategy[float]) -> st.SearchStrategy[float]:
    return st.tuples(st.sampled_from([1.0, -1.0]), s).map(lambda t: t[0] * t[1])


k_alpha = st.one_of(
    st.floats(0.0, PI_2, exclude_min=True, exclude_max=True).filter(lambda a: a >= 1e-8),
    log_uniform(-8, -6),  # within 1e-6 of 0
    log_uniform(-17, -6).map(lambda d: min(PI_2 - d, BELOW_PI_2)),  # within 1e-6 of pi/2
)


def weighted(*pairs: tuple[int, st.SearchStrategy]) -> st.SearchStrategy:
    """Branches drawn with the given integer weights (one_of's own choice is far from even)."""
    table = [s for w, s in pairs for _ in range(w)]
    return st.integers(0, len(table) - 1).flatmap(lambda i: table[i])


k_hl = weighted((4, signed(log_uniform(-6, 6))), (1, st.just(0.0)))
k_abs_energy = weighted((4, signed(log_uniform(-6, 6))), (1, st.just(0.0)))
k_rel_offset = weighted(
    (4, log_uniform(-16, 3)), (1, st.just(0.0)), (1, log_uniform(-16, 3).map(lambda x: -x))
)
k_M = log_uniform(-3, 3)
k_g = weighted((2, log_uniform(-3, 2)), (1, st.just(0.0)))
k_k = st.one_of(st.sampled_from([0.0, 0.4, 2 / 3]), st.floats(1e-4, 5.0))
k_rim = st.one_of(st.none(), log_uniform(-3, 6))

# --- regressions found by these properties (fixed in the kernels) ---

# 1. mu_required of a free-fall escape of a point particle (k = 0) with h != 0 was
#    k/(1+k) * inf = 0 * inf = NaN instead of 0.
K0_ESCAPE = dict(alpha=0.5, energy=1.0, h=1.0, Lz=1.0)

# 2. In a deep well (|V_min| >> the energy scale at r_max) the outer turning point found from
#    V(r) - V_min = (r - r_c)^2 G(r) carried an error ~eps |V_min| / V'(r_max) though r_max is
#    well conditioned (9 % here, the period 10 %); fixed by polishing on energy - V(r).
DEEP_WELL = dict(alpha=1.0, energy=0.0, h=-1e6, Lz=1e-6)
DEEP_WELL_SCENE = dict(M=1e3, g=1e-3, k=5.0)
DEEP_WELL_R_MAX = 2.6573322406479313  # mpmath, 50 digits: root of C r^3 + B r + A
DEEP_WELL_PERIOD = 291.07358395731396  # mpmath quadrature, 50 digits


@st.composite
def kernel_points(draw) -> tuple:
    n = draw(st.integers(1, 12))
    alpha = np.array([draw(k_alpha) for _ in range(n)])
    h = np.array([draw(k_hl) for _ in range(n)])
    Lz = np.array([draw(k_hl) for _ in range(n)])
    relative = np.array([draw(st.integers(0, 3)) < 3 for _ in range(n)])
    absolute = np.array([draw(k_abs_energy) for _ in range(n)])
    offset = np.array([draw(k_rel_offset) for _ in range(n)])
    return alpha, h, Lz, relative, absolute, offset


def _nan(x: float) -> bool:
    return math.isnan(x)


def _fin(x: float) -> bool:
    return math.isfinite(x)


def check_point(cls: int, o: dict, alpha, E, h, Lz, M, g, k, offset, vmin=None) -> float:
    """The README's class table for one point on the infinite cone. Returns the worst
    turning-point residual relative to its tolerance scale (for hypothesis.target)."""
    where = dict(alpha=alpha, energy=E, h=h, Lz=Lz, M=M, g=g, k=k, offset=offset, **o)
    assert cls in (FORBIDDEN, BOUNDED, CIRCULAR, HYPERBOLIC, RADIAL), where
    B_neg = k > 0 and h != 0 and (h < 0) != (Lz < 0)
    has_min = Lz != 0 and (g > 0 or B_neg)
    # class rules (reference README, rule order 1-4)
    if Lz == 0:
        assert cls == (RADIAL if g > 0 and E > 0 else FORBIDDEN), where
    elif offset is not None and has_min:
        if offset == 0.0:
            assert cls == CIRCULAR, where
        elif offset < -1e-11:
            assert cls == FORBIDDEN, where
        elif offset > 1e-11:
            expect = BOUNDED if g > 0 or E < 0 else HYPERBOLIC
            assert cls == expect, where
    if g > 0:
        assert cls != HYPERBOLIC, where
    # r_circ is a property of the potential
    assert _fin(o["r_circ"]) == has_min, where
    if has_min:
        assert o["r_circ"] > 0, where
    # which outputs are defined
    defined = {
        FORBIDDEN: (),
        BOUNDED: FLOAT_NAMES,
        CIRCULAR: FLOAT_NAMES,
        HYPERBOLIC: ("r_min", "apsidal_angle", "mu_required"),
        RADIAL: ("r_min", "r_max", "period", "mu_required"),
    }[cls]
    for name in FLOAT_NAMES:
        if name == "r_circ":
            continue
        x = o[name]
        if name in defined:
            if cls == HYPERBOLIC and name == "mu_required" and h != 0 and k > 0:
                assert x == math.inf, where  # spinning free-fall escape
            else:
                assert _fin(x), (name, where)
        elif cls == HYPERBOLIC and name == "r_max":
            assert x == math.inf, where
        else:
            assert _nan(x), (name, where)
    for name in ("r_min", "r_max", "apsidal_angle", "mu_required"):
        assert _nan(o[name]) or o[name] >= 0, (name, where)
    if _fin(o["period"]):
        assert o["period"] > 0, where
    if cls == CIRCULAR:
        assert o["r_min"] == o["r_max"] == o["r_circ"], where
    if cls == RADIAL:
        assert o["r_min"] == 0.0 and o["r_max"] > 0, where
    if cls in (BOUNDED, HYPERBOLIC):
        assert o["r_min"] > 0, where
    r1, rc, r2 = o["r_min"], o["r_circ"], o["r_max"]
    if _fin(r1) and _fin(rc) and _fin(r2):
        assert r1 <= rc <= r2, where
    # turning points are roots of E - V(r); V computed here independently of the kernels
    sa, ca = math.sin(alpha), math.cos(alpha)
    kk = k / (1.0 + k)
    A = Lz * Lz / (2.0 * M * sa * sa) * (1.0 + kk * (ca / sa) ** 2)
    B = kk * h * Lz * ca / (sa * sa)
    C = M * g * ca / (1.0 + k)
    worst = 0.0
    if cls in (BOUNDED, HYPERBOLIC):
        for r in (r1, r2):
            if _fin(r):
                scale = 2 * (A / r) / r + abs(B) / r + C * r + abs(E)  # no overflow of r^2
                residual = abs((A / r) / r + B / r + C * r - E)
                worst = max(worst, residual / scale)
                tol = 1e-12 * scale
                assert residual <= tol, (r, where)
    if cls in (BOUNDED, CIRCULAR):
        prec = (2 * o["apsidal_angle"] - 2 * math.pi) / o["period"]
        assert math.isclose(o["precession_rate"], prec, rel_tol=1e-12, abs_tol=1e-300), where
    if g == 0 and cls != FORBIDDEN:  # free fall: psi = pi/Omega; an escape sweeps less
        omega = math.sqrt((sa * sa + k) / (1.0 + k))
        if cls == BOUNDED:
            assert math.isclose(o["apsidal_angle"], math.pi / omega, rel_tol=1e-13), where
        elif cls == HYPERBOLIC:
            assert 0 < o["apsidal_angle"] <= math.pi / omega * (1 + 1e-15), where
    if cls == RADIAL:
        assert math.isclose(o["r_max"], E / C, rel_tol=1e-15), where
    return worst


def _run_points(alpha, E, h, Lz, scene):
    ds = engine.evaluate(alpha, E, h, Lz, scene=scene)
    cls = ds.orbit_class.values
    f = {name: ds[name].values for name in FLOAT_NAMES}
    return cls, f


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(pts=kernel_points(), M=k_M, g=k_g, k=k_k, rim=k_rim)
def test_kernels_follow_the_class_table(pts, M, g, k, rim):
    alpha, h, Lz, relative, absolute, offset = pts
    scene = engine.Scene(M=M, g=g, k=k)
    vmin = engine.minimum_energy(alpha, h, Lz, scene=scene)
    use_rel = relative & np.isfinite(vmin)
    E = np.where(use_rel, vmin + offset * np.abs(vmin), absolute)
    assert np.isfinite(E).all()
    cls, f = _run_points(alpha, E, h, Lz, scene)
    assert cls.dtype == np.int8
    worst = 0.0
    for i in range(alpha.size):
        o = {name: float(f[name][i]) for name in FLOAT_NAMES}
        off = float(offset[i]) if use_rel[i] else None
        w = check_point(int(cls[i]), o, alpha[i], E[i], h[i], Lz[i], M, g, k, off, vmin[i])
        worst = max(worst, w)
    target(math.log10(worst + 1e-300), label="log10 relative turning-point residual")
    if rim is not None:  # the rim relabels orbits: off this cone, or reaching beyond it
        scene_r = engine.Scene(M=M, g=g, k=k, rim=rim)
        cls_r, f_r = _run_points(alpha, E, h, Lz, scene_r)
        for name in FLOAT_NAMES:
            np.testing.assert_array_equal(f_r[name], f[name])
        r_rim = rim - scene_r.a / np.tan(alpha)  # the rim is measured on the real cone
        has_orbit = np.isin(cls, [BOUNDED, CIRCULAR, RADIAL, HYPERBOLIC])
        off = has_orbit & (f["r_min"] > r_rim)
        spills = has_orbit & ~off & (f["r_max"] > r_rim)  # every escape spills
        expected = np.where(off, OFF_CONE, np.where(spills, SPILLS, cls))
        np.testing.assert_array_equal(cls_r, expected)


def test_regression_mu_required_point_particle_escape():
    """k = 0 (point particle) in free fall, escaping with h != 0. The friction force is
    k/(1+k) (...) = 0, so mu_required must be 0 (the README's +inf is for a *spinning* sphere,
    k > 0), not k/(1+k) * inf = NaN."""
    ds = engine.evaluate(**K0_ESCAPE, scene=engine.Scene(g=0.0, k=0.0))
    assert int(ds.orbit_class) == HYPERBOLIC
    assert float(ds.mu_required) == 0.0


def test_regression_deep_well_outer_turning_point():
    """A well-conditioned outer turning point (r_max ~ sqrt(-B/C)) in a potential whose
    minimum is 1e14 J deep (the kernel's r_max and period were ~10 % off)."""
    ds = engine.evaluate(**DEEP_WELL, scene=engine.Scene(**DEEP_WELL_SCENE))
    assert int(ds.orbit_class) == BOUNDED
    assert float(ds.r_max) == pytest.approx(DEEP_WELL_R_MAX, rel=1e-12)
    assert float(ds.period) == pytest.approx(DEEP_WELL_PERIOD, rel=1e-10)


# --- the whole double range ------------------------------------------------------------------
def _signed_log(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.builds(lambda e, s: s * 10.0**e, st.floats(lo, hi), st.sampled_from([-1.0, 1.0]))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    alpha=st.floats(1e-3, PI_2 - 1e-3),
    energy=_signed_log(-150, 150),
    h=st.one_of(st.just(0.0), _signed_log(-150, 150)),
    Lz=st.one_of(st.just(0.0), _signed_log(-150, 150)),
    g=st.sampled_from([0.0, 9.81]),
)
def test_no_silent_wrong_values_across_the_double_range(alpha, energy, h, Lz, g):
    """L_z, h and calE across 1e-150..1e150: a class that promises numbers has them, finite
    and right (turning points solve calE = V(r), V written here; r_min <= r_circ <= r_max),
    and what cannot be computed in double precision is out_of_range, never a class with NaN."""
    ds = engine.evaluate(alpha, energy, h, Lz, scene=engine.Scene(g=g))
    cls = int(ds.orbit_class)
    o = {name: float(ds[name]) for name in FLOAT_NAMES}
    where = dict(alpha=alpha, energy=energy, h=h, Lz=Lz, g=g, cls=cls, **o)
    if cls == OUT_OF_RANGE:
        assert all(math.isnan(x) for x in o.values()), where
        return
    check_point(cls, o, alpha, energy, h, Lz, 1.0, g, 0.4, None)

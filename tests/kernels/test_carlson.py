"""Carlson integrals against mpmath (40 digits) and DLMF identities."""

import math

import mpmath as mp
import numpy as np
import pytest
from carlson_ref import rc, rd, rf, rj
from hypothesis import given
from hypothesis import strategies as st

from engine.kernels.carlson import cel, cel_pair, cel_pair_lanes

# The duplication algorithm with TOL = 2^-53 promises ~1e-16 truncation plus the rounding of
# a few dozen operations: 1e-14 relative is a generous but meaningful bound (errors of a wrong
# series coefficient are ~1e-6).
TOL = 1e-14

pos = st.floats(1e-6, 1e6)


def _rel(a, b):
    return abs(a - float(b)) / abs(float(b))


@given(pos, pos, pos)
def test_rf_matches_mpmath(x, y, z):
    with mp.workdps(40):
        assert _rel(rf(x, y, z), mp.elliprf(x, y, z)) < TOL


@given(pos, pos, pos)
def test_rd_matches_mpmath(x, y, z):
    with mp.workdps(40):
        assert _rel(rd(x, y, z), mp.elliprd(x, y, z)) < TOL


@given(pos, pos, pos, pos)
def test_rj_matches_mpmath(x, y, z, p):
    with mp.workdps(40):
        assert _rel(rj(x, y, z, p), mp.elliprj(x, y, z, p)) < TOL


@pytest.mark.parametrize("y,z", [(1e-12, 1.0), (1.0, 1e-12), (0.5, 2.0), (1.0, 1.0), (1e8, 1e-8)])
def test_complete_cases_with_zero_argument(y, z):
    with mp.workdps(40):
        assert _rel(rf(0.0, y, z), mp.elliprf(0, y, z)) < TOL
        assert _rel(rd(0.0, y, z), mp.elliprd(0, y, z)) < TOL
        for p in (1e-10, 0.3, 1.0, 7.0):
            assert _rel(rj(0.0, y, z, p), mp.elliprj(0, y, z, p)) < TOL


def test_rc_closed_forms():
    assert rc(0.0, 1.0) == pytest.approx(math.pi / 2, rel=1e-15)
    assert rc(1.0, 2.0) == pytest.approx(math.pi / 4, rel=1e-15)  # atan(1)
    with mp.workdps(30):
        assert _rel(rc(2.0, 1.0), mp.elliprc(2, 1)) < TOL


def test_legendre_relation():
    """E K' + E' K - K K' = pi/2 (DLMF 19.7.1) through R_F and R_D."""
    for m in np.linspace(0.05, 0.95, 7):
        K = rf(0.0, 1 - m, 1.0)
        E = K - m / 3 * rd(0.0, 1 - m, 1.0)
        Kp = rf(0.0, m, 1.0)
        Ep = Kp - (1 - m) / 3 * rd(0.0, m, 1.0)
        assert E * Kp + Ep * K - K * Kp == pytest.approx(math.pi / 2, rel=1e-14)


@given(st.floats(1.0, 1e4), st.floats(1e-3, 1e3), st.floats(0.1, 3.0), st.floats(0.1, 3.0))
def test_cel_matches_quadrature(kc, p, a, b):
    """Bulirsch's cel against its defining integral (mpmath, 30 digits)."""
    with mp.workdps(30):
        ref = mp.quad(
            lambda t: (
                (a * mp.cos(t) ** 2 + b * mp.sin(t) ** 2)
                / (
                    (mp.cos(t) ** 2 + p * mp.sin(t) ** 2)
                    * mp.sqrt(mp.cos(t) ** 2 + kc**2 * mp.sin(t) ** 2)
                )
            ),
            [0, mp.pi / 4, mp.pi / 2],
        )
        assert _rel(cel(kc, p, a, b), ref) < TOL


@given(st.floats(0.01, 10.0), st.floats(1e-6, 10.0), st.floats(1e-3, 100.0))
def test_cel_period_and_angle_agree_with_carlson_forms(r1, gap, r3abs):
    """The hot path's cel forms of T_r and psi against the Carlson forms (a second evaluation)."""
    r2, r3 = r1 + gap, -r3abs
    d13, d23, d21 = r1 - r3, r2 - r3, r2 - r1
    t_cel = 2.0 * cel(math.sqrt(d23 / d13), 1.0, r1, r2) / math.sqrt(d13)
    t_carlson = r1 * 2 * rf(0.0, d13, d23) + 2 / 3 * d21 * d13 * rd(0.0, d23, d13)
    assert t_cel == pytest.approx(t_carlson, rel=TOL)
    m1, n = d13 / d23, d21 / r2
    p_cel = cel(math.sqrt(d23 / d13), r2 / r1, 1.0, 1.0) / (r1 * math.sqrt(d13))
    p_carlson = (rf(0.0, m1, 1.0) + n / 3 * rj(0.0, m1, 1.0, r1 / r2)) / (r2 * math.sqrt(d23))
    assert p_cel == pytest.approx(p_carlson, rel=TOL)


@given(
    st.lists(
        st.tuples(
            st.floats(1e-3, 1e4), st.floats(1e-3, 1e3), st.floats(0.01, 10.0), st.floats(0.01, 10.0)
        ),
        min_size=1,
        max_size=40,
    )
)
def test_cel_pair_and_its_lanes_are_two_cel_calls_bit_for_bit(args):
    """The hot path's cel forms, (kc, 1, r1, r2) and (kc, p, 1, 1), in one loop and over lanes in
    lock-step: the very numbers of cel."""
    m = len(args)
    kc, p, a, b = (np.array(x) for x in zip(*args, strict=True))
    want = [(cel(kc[j], 1.0, a[j], b[j]), cel(kc[j], p[j], 1.0, 1.0)) for j in range(m)]
    assert [cel_pair(kc[j], 1.0, a[j], b[j], p[j], 1.0, 1.0) for j in range(m)] == want
    one = np.ones(m)
    o1, o2 = np.empty(m), np.empty(m)
    cel_pair_lanes(m, kc, one.copy(), a.copy(), b.copy(), p.copy(), one.copy(), one.copy(),
                   np.empty((4, m)), o1, o2)  # fmt: skip
    assert list(zip(o1, o2, strict=True)) == want

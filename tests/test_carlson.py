"""Carlson integrals against mpmath (40 digits) and DLMF identities."""

import math

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from engine.kernels.carlson import rc, rd, rf, rj

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

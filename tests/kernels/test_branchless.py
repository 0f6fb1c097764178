"""The branch-free helpers of the lanes (engine.kernels.branchless): x ** a without a library
call, within (2 + |a log x|) ulp of the C library's correctly rounded-or-nearly pow over the
whole range of floats (subnormals too), and x ** a's values at 0, inf and NaN."""

import math

import numba
import numpy as np
import pytest

from engine.kernels.branchless import pick, power


@numba.njit
def _powers(x, a):
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        out[i] = power(x[i], a)
    return out


@numba.njit
def _picks(c, a, b):
    return pick(c, a, b)


@pytest.mark.parametrize("a", [-0.17, -0.2, 0.04, -0.125, 2.5, -3.0])
def test_power_within_a_few_ulp_of_pow(a):
    rng = np.random.default_rng(7)
    lim = min(700.0, 700.0 / abs(a))  # |a log x| <= 700: the documented range
    x = np.exp(rng.uniform(-lim, lim, 200_000))
    edges = [1.0, 2.0, 0.5, 2.2250738585072014e-308, 5e-324, 1e-310, 3e-320]  # subnormals too
    x = np.concatenate([x, rng.uniform(0.5, 2.0, 50_000), edges])
    x = x[np.abs(a * np.log(x)) <= 700.0]
    got = _powers(x, a)
    want = x**a
    ulps = np.abs(got - want) / np.spacing(np.abs(want))
    bound = 2.0 + np.abs(a * np.log(x))
    assert np.all(ulps <= bound), (x[np.argmax(ulps / bound)], ulps.max())


def test_power_edges_are_those_of_pow():
    x = np.array([0.0, math.inf, math.nan, -1.0, 1.0])
    with np.errstate(divide="ignore", invalid="ignore"):
        for a in (-0.2, 0.04):
            np.testing.assert_array_equal(_powers(x, a), x**a)


def test_pick_is_a_select():
    assert _picks(True, 1.5, 2.5) == 1.5 and _picks(False, 1.5, 2.5) == 2.5
    assert _picks(False, 1, 2.5) == 2.5

"""Butcher tableaux and composition weights: consistency and order conditions, from the data."""

import math

import numpy as np
import pytest

from engine.kernels import tableaux as tb
from engine.kernels.rk_codegen import generated_source

#: Every Runge-Kutta pair the engine offers: (A, C, B, E, E3, P, n_stages, order).
RK = {
    t.name: (t.A, t.C, t.A[t.n_stages, : t.n_stages], t.E, t.E3, t.P, t.n_stages, t.order)
    for t in tb.RK_TABLEAUX
}
EPS = np.finfo(float).eps


@pytest.mark.parametrize("name", RK)
def test_weights_sum_to_one_and_error_weights_to_zero(name):
    A, C, B, E, E3, P, ns, order = RK[name]
    assert B.sum() == pytest.approx(1.0, abs=8 * EPS)
    assert E.sum() == pytest.approx(0.0, abs=8 * EPS)
    assert E3.sum() == pytest.approx(0.0, abs=8 * EPS)
    # The FSAL row of A is b (its stage is f(y_new)), at c = 1.
    np.testing.assert_array_equal(A[ns, :ns], B)
    assert C[ns] == 1.0


@pytest.mark.parametrize("name", RK)
def test_row_sums_of_A_are_c(name):
    A, C, *_ = RK[name]
    np.testing.assert_allclose(A.sum(axis=1), C, rtol=0, atol=64 * EPS)
    assert np.all(np.triu(A) == 0.0), "explicit methods: A strictly lower triangular"


@pytest.mark.parametrize("name", RK)
def test_quadrature_order_conditions(name):
    """b . c^(q-1) = 1/q for q = 1..order (the bushy-tree conditions)."""
    A, C, B, E, E3, P, ns, order = RK[name]
    c = C[:ns]
    for q in range(1, order + 1):
        assert B @ c ** (q - 1) == pytest.approx(1.0 / q, rel=1e-14), q


@pytest.mark.parametrize("name", RK)
def test_embedded_solution_is_one_order_lower(name):
    """b_hat = b - e satisfies the quadrature conditions up to the error-estimator order and
    fails the next one (otherwise the estimate would vanish)."""
    A, C, B, E, E3, P, ns, order = RK[name]
    c = C[: ns + 1]
    b = np.append(B, 0.0)
    bhat = b - E
    q_err = 4 if name == "rk45" else 5  # DOP853's E is the 5th-order companion
    for q in range(1, q_err + 1):
        assert bhat @ c ** (q - 1) == pytest.approx(1.0 / q, rel=1e-13), q
    assert abs(bhat @ c**q_err - 1.0 / (q_err + 1)) > 1e-6


@pytest.mark.parametrize("name", RK)
def test_dense_output_ends_at_the_solution(name):
    """sum_m P[i, m] = b_i (theta = 1 gives y_new); the derivative at theta = 1 picks the FSAL
    stage f(y_new) and at theta = 0 the first stage f(y)."""
    A, C, B, E, E3, P, ns, order = RK[name]
    S = A.shape[0]
    b = np.zeros(S)
    b[:ns] = B
    np.testing.assert_allclose(P.sum(axis=1), b, atol=1e-12)
    deg = P.shape[1]
    d1 = P @ np.arange(1, deg + 1)  # d/dtheta at 1
    expect = np.zeros(S)
    expect[ns] = 1.0
    np.testing.assert_allclose(d1, expect, atol=1e-11)
    d0 = P[:, 0]  # d/dtheta at 0
    expect0 = np.zeros(S)
    expect0[0] = 1.0
    np.testing.assert_allclose(d0, expect0, atol=1e-12)


@pytest.mark.parametrize("name", RK)
def test_dense_output_order(name):
    """The interpolant integrates y' = y with local error O(h^(deg+1)): slope of the error at
    mid-step over four step sizes."""
    A, C, B, E, E3, P, ns, order = RK[name]
    S = A.shape[0]
    errs = []
    # step sizes in the asymptotic range and above rounding (DOP853 reaches 1e-12 at h = 0.2)
    hs = np.array([0.1, 0.05, 0.025, 0.0125]) if name == "rk45" else np.array([0.8, 0.4, 0.2])
    for h in hs:
        K = np.zeros(S)
        for i in range(S):
            K[i] = 1.0 + h * (A[i, :i] @ K[:i])  # f(y) = y from y0 = 1
        theta = 0.5
        w = P @ theta ** np.arange(1, P.shape[1] + 1)
        errs.append(abs(1.0 + h * (w @ K) - math.exp(theta * h)))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    expected = P.shape[1] + 1  # DP5: 5, DOP853: 8
    assert expected - 0.3 < slope < expected + 0.6


@pytest.mark.parametrize("order,w", [(2, tb.LEAPFROG), (4, tb.YOSHIDA4), (6, tb.YOSHIDA6)])
def test_composition_weights(order, w):
    assert w.sum() == pytest.approx(1.0, abs=4 * EPS)
    np.testing.assert_array_equal(w, w[::-1])  # symmetric
    if order >= 4:
        assert (w**3).sum() == pytest.approx(0.0, abs=1e-14)
    if order >= 6:
        assert (w**5).sum() == pytest.approx(0.0, abs=1e-13)
    np.testing.assert_array_equal(tb.composition_weights(order), w)


def test_composition_weights_rejects_other_orders():
    with pytest.raises(ValueError, match="order must be 2, 4 or 6; got 3"):
        tb.composition_weights(3)


@pytest.mark.parametrize("method", range(len(tb.RK_TABLEAUX)))
def test_generated_stepper_holds_every_nonzero_coefficient(method):
    """The unrolled step is generated from the data: every nonzero A and E entry appears in it
    exactly as a float literal, and no zero does."""
    A, C, B, E, E3, P, ns, order = RK[tb.RK_TABLEAUX[method].name]
    src = generated_source("attempt", method, 5)
    for i in range(1, ns + 1):
        for m in range(i):
            if A[i, m] != 0.0:
                assert repr(float(A[i, m])) in src
    for e in E:
        if e != 0.0:
            assert repr(float(e)) in src
    assert "0.0 * " not in src
    compile(src, "<test>", "exec")

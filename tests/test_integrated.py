"""Integrated maps (engine.integrated): one radial period per point against the closed form on the
hard cases and the reference data; the batch kernel's statuses; validation (tests/cases.py has
the accuracy promise)."""

import math

import numba
import numpy as np
import pytest
from cases import (
    BOUNDED_REF,
    HARD,
    METHODS,
    P003,
    RTOL,
    STEP_BOUND,
    closed_form,
    integrate,
    kappa,
    vmin,
)

import engine
from engine.integrated import evaluate_integrated, integrate_points
from engine.kernels.protocol import MAX_STEPS, NOT_BOUNDED, UNSUPPORTED
from engine.kernels.symplectic import SYMPLECTIC
from engine.scene import Scene


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("name", HARD)
def test_hard_case(name, method):
    c = HARD[name]
    T, psi = closed_form(c)
    r = integrate(c, method)
    print(f"{name} {method}: {r['n_steps']} steps per period")
    assert r["status"] == 0
    for key in ("period", "apsidal_angle", "precession_rate", "energy_drift"):
        assert np.isfinite(r[key]), key
    bound = 100 * RTOL * kappa(c)
    assert r["period"] == pytest.approx(T, rel=bound)
    assert r["apsidal_angle"] == pytest.approx(psi, rel=100 * RTOL)
    assert r["n_steps"] <= STEP_BOUND[method]
    assert r["energy_drift"] <= 100 * RTOL


@pytest.mark.parametrize("method", METHODS)
def test_reference_cases(method):
    """Bounded typical/other_k/freefall cases of the shared 40-digit data."""
    ins = [c["inputs"] for c in BOUNDED_REF]
    by_scene: dict = {}
    for i, c in enumerate(BOUNDED_REF):
        key = (c["inputs"]["M"], c["inputs"]["g"], c["inputs"]["k"])
        by_scene.setdefault(key, []).append(i)
    for (M, g, k), idx in by_scene.items():
        res = evaluate_integrated(
            np.array([ins[i]["alpha"] for i in idx]),
            np.array([ins[i]["calE"] for i in idx]),
            np.array([ins[i]["h"] for i in idx]),
            np.array([ins[i]["Lz"] for i in idx]),
            Scene(M=M, g=g, k=k),
            method,
            RTOL,
        )
        for j, i in enumerate(idx):
            case = BOUNDED_REF[i]
            out = case["outputs"]
            c = {"alpha": ins[i]["alpha"], "energy": ins[i]["calE"], "h": ins[i]["h"]}
            c.update(Lz=ins[i]["Lz"], scene=Scene(M=M, g=g, k=k))
            assert res["status"][j] == 0, case["id"]
            bound = 100 * RTOL * kappa(c)
            assert res["period"][j] == pytest.approx(out["T_r"], rel=bound), case["id"]
            assert res["apsidal_angle"][j] == pytest.approx(out["psi"], rel=100 * RTOL), case["id"]
            prec = (2 * res["apsidal_angle"][j] - 2 * math.pi) / res["period"][j]
            assert res["precession_rate"][j] == prec
            assert res["n_steps"][j] <= STEP_BOUND[method], case["id"]


def test_batch_kernel_never_raises_or_hangs_on_bad_points():
    sc = Scene()
    e = 1.5 * vmin(0.6, 1.0, 0.5, sc)  # a bounded orbit at index 2; the others are not
    alpha = np.array([0.6, 0.6, 0.6, 0.6, 0.0, 2.0, 0.6, 0.6, np.nan, 0.6])
    energy = np.array([-1.0, e, e, np.inf, e, e, e, 1e300, e, e])
    h = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, np.nan, 1.0, 1.0, 1.0])
    Lz = np.array([0.5, 0.0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 1e-300])
    for method in METHODS:
        res = evaluate_integrated(alpha, energy, h, Lz, sc, method, RTOL)
        st = res["status"]
        assert st.dtype == np.int8
        assert st[2] == 0 and np.isfinite(res["period"][2])
        bad = np.delete(np.arange(alpha.size), 2)
        assert np.all(st[bad] != 0), (method, st)
        assert np.all(np.isnan(res["period"][bad]))


def test_batch_free_fall_escape_and_step_budget():
    c = HARD["free_fall_e_0.999"]
    esc = dict(c, energy=0.1)  # hyperbolic: no turning points
    assert integrate(esc, "rk45")["status"] == NOT_BOUNDED
    r = integrate(c, "rk45", max_steps=10)
    assert r["status"] == MAX_STEPS and math.isnan(r["period"])
    r = integrate(c, "symplectic", max_steps=10)
    assert r["status"] == MAX_STEPS


def test_symplectic_refuses_dissipative_scenes():
    c = dict(HARD["M_1e3"], scene=Scene(M=1e3, c_rr=1e-3))
    for _ in range(2):  # the check of a (method, scene) is cached: a refusal is not
        with pytest.raises(ValueError, match="symplectic.*rolling_resistance"):
            integrate(c, "symplectic")
    with pytest.raises(ValueError, match="symplectic.*attitude"):
        integrate(dict(c, scene=Scene(attitude=True)), "symplectic")
    # the kernel itself answers with a status code
    out_f, out_n, out_s = np.empty((5, 1)), np.empty(1, np.int64), np.empty(1, np.int8)
    arr = [np.array([c[k]]) for k in ("alpha", "energy", "h", "Lz")]
    integrate_points(*arr, c["scene"].params(), SYMPLECTIC, 1, RTOL, 1000, out_f, out_n,
                     out_s)  # fmt: skip
    assert out_s[0] == UNSUPPORTED


def test_rolling_resistance_reports_energy_loss():
    i = P003
    c = {"alpha": i["alpha"], "energy": i["calE"], "h": i["h"], "Lz": i["Lz"], "scene": Scene()}
    base = integrate(c, "rk45")
    assert "energy_loss" not in base
    lossy = integrate(dict(c, scene=Scene(c_rr=1e-3)), "rk45")
    assert lossy["status"] == 0
    assert lossy["energy_loss"] > 0
    assert np.isfinite(lossy["apsidal_angle"]) and np.isfinite(lossy["period"])
    # the drift is then the (physical) loss relative to the energy scale
    assert lossy["energy_drift"] > 1e3 * base["energy_drift"]
    # the conservative scene integrates to r_max and doubles (time symmetry); the dissipative
    # one, whose way back is not the mirror image of the way out, the whole period
    assert 1.6 * base["n_steps"] < lossy["n_steps"] < 2.5 * base["n_steps"]


@pytest.mark.parametrize("bad", [0.0, 1e-15, 1e-2, -1e-10, "x", math.nan])
def test_rtol_is_validated(bad):
    c = HARD["M_1e3"]
    with pytest.raises(ValueError, match="rtol"):
        integrate(c, "rk45", rtol=bad)


def test_method_and_shapes_are_validated():
    c = HARD["M_1e3"]
    for bad in ("euler", ["rk45"]):
        with pytest.raises(ValueError, match="method must be (a string, )?one of"):
            integrate(c, bad)
    with pytest.raises(ValueError, match="energy has length 2"):
        evaluate_integrated(np.ones(1), np.ones(2), np.ones(1), np.ones(1), Scene(), "rk45")
    empty = evaluate_integrated(*[np.empty(0)] * 4, Scene(), "rk45")
    assert empty["period"].shape == (0,) and empty["status"].dtype == np.int8


@pytest.mark.parametrize("method", ["rk45", "dop853"])
def test_maps_are_the_same_at_1_and_2_threads(method):
    """The lanes' workers take different pieces of the points at 1 and 2 threads: every output
    bit for bit the same, and the same on a second scene (its parameters are not the first's)."""
    rng = np.random.default_rng(3)
    a, h, lz = rng.uniform(0.2, 1.4, 90), rng.uniform(-2, 2, 90), rng.uniform(0.05, 2, 90)
    for sc in (Scene(), Scene(M=2.0, k=0.5)):
        v = engine.minimum_energy(a, h, lz, sc)
        e = v + rng.uniform(0.01, 1.0, 90) * np.abs(v)
        before = numba.get_num_threads()
        try:
            numba.set_num_threads(1)
            one = evaluate_integrated(a, e, h, lz, sc, method, RTOL)
            numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
            two = evaluate_integrated(a, e, h, lz, sc, method, RTOL)
        finally:
            numba.set_num_threads(before)
        assert np.all(one["status"] == 0)
        for key in one:
            np.testing.assert_array_equal(one[key], two[key], err_msg=key)

"""Integrators against the closed form: hard cases, reference data, orders, events, invariants.

Accuracy promise checked here (documented in engine.integrated): with relative tolerance rtol the
integrated radial period and apsidal angle are within 100 rtol kappa relative, where kappa =
max(1, (A / r1^2) / |calE|) is the amplification of a relative velocity error at the pericentre
into the radial energy (1 for most orbits; (1 + e)/(1 - e) for a free-fall ellipse, where the
period depends on the small binding energy). The factor 100 covers the growth of the local
errors over the ~10^2-10^3 steps of a period.
"""

import json
import math
from pathlib import Path

import numba
import numpy as np
import pytest

import engine
from engine.integrated import evaluate_integrated, integrate_points, scene_params
from engine.kernels import integrators as itg
from engine.kernels import symplectic as sym
from engine.kernels.physics import coefficients
from engine.scene import Scene
from engine.simulate import simulate

METHODS = ("rk45", "dop853", "symplectic")
RTOL = 1e-10
#: Accepted steps per radial period at rtol 1e-10 never exceed these (measured maxima over the
#: hard cases and the reference data: rk45 563, dop853 140, symplectic 937).
STEP_BOUND = {"rk45": 1500, "dop853": 500, "symplectic": 2500}

REF = Path(__file__).resolve().parents[2] / "shared" / "reference" / "public.json"
if not REF.exists():  # CI clones main with shared/ beside it
    REF = Path(__file__).resolve().parents[1] / "data" / "reference_public.json"
CASES = json.loads(REF.read_text())
BOUNDED_REF = [
    c
    for c in CASES
    if c["outputs"]["class"] == "bounded" and c["tag"] in ("typical", "other_k", "freefall")
]


def vmin(alpha, h, Lz, scene):
    return float(np.asarray(engine.minimum_energy(alpha, h, Lz, scene)).reshape(-1)[0])


def _case(alpha, h, Lz, scene=None, rel=0.5, energy=None):
    scene = scene or Scene()
    if energy is None:
        v = vmin(alpha, h, Lz, scene)
        energy = v + rel * abs(v)
    return {"alpha": alpha, "energy": energy, "h": h, "Lz": Lz, "scene": scene}


def _free_fall(e, alpha=0.6, h=-2.0, Lz=0.5):
    sc = Scene(g=0.0)
    A, B, C = coefficients(alpha, h, Lz, sc.M, 0.0, sc.k)
    assert B < 0
    return _case(alpha, h, Lz, sc, energy=-B * B / (4 * A) * (1 - e * e))


#: The named hard cases of the integrators issue.
HARD = {
    "alpha_1e-3": _case(1e-3, 1.0, 0.5),
    "alpha_pi/2-1e-3": _case(math.pi / 2 - 1e-3, 1.0, 0.5),
    "Lz_1e-7_grazes_axis": _case(0.6, 1.0, 1e-7, energy=1.0),
    "energy_1e-10_above_circular": _case(0.6, 1.0, 0.5, rel=1e-10),
    "free_fall_e_0.999": _free_fall(0.999),
    "spin_dominated_hLz>0": _case(0.6, 50.0, 0.3, rel=0.3),
    "spin_dominated_hLz<0": _case(0.6, -50.0, 0.3, rel=0.3),
    "spin_dominated_hLz<0_Lz<0": _case(0.6, 50.0, -0.3, rel=0.3),
    "M_1e-3": _case(0.6, 1.0, 0.5e-3, Scene(M=1e-3)),
    "M_1e3": _case(0.6, 1.0, 0.5e3, Scene(M=1e3)),
}


def kappa(c):
    """Energy amplification factor of the accuracy promise (module docstring)."""
    sc = c["scene"]
    A, B, C = coefficients(c["alpha"], c["h"], c["Lz"], sc.M, sc.g, sc.k)
    r1 = float(engine.evaluate(c["alpha"], c["energy"], c["h"], c["Lz"], sc).r_min)
    return max(1.0, A / r1**2 / abs(c["energy"]))


def closed_form(c):
    ds = engine.evaluate(c["alpha"], c["energy"], c["h"], c["Lz"], c["scene"])
    assert engine.CLASS_NAMES[int(ds.orbit_class)] == "bounded"
    return float(ds.period), float(ds.apsidal_angle)


def integrate(c, method, rtol=RTOL, **kw):
    res = evaluate_integrated(
        np.array([c["alpha"]]),
        np.array([c["energy"]]),
        np.array([c["h"]]),
        np.array([c["Lz"]]),
        c["scene"],
        method,
        rtol,
        **kw,
    )
    return {k: v[0] for k, v in res.items()}


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


# ------------------------------------------------------------------------------ orders
P003 = next(c for c in CASES if c["id"] == "P003")["inputs"]


def _p003_start():
    sc = Scene()
    p = scene_params(sc, P003["alpha"])
    ok, r1, r2, rc = itg.orbit_start(p, P003["calE"], P003["h"], P003["Lz"])
    y0 = itg.initial_state(p, 0, r1, P003["calE"], P003["h"], P003["Lz"])
    y0[2] = 0.0
    return p, y0


@numba.njit
def _fixed(method, y0, p, h, n):
    return itg.rk_fixed(numba.literally(method), 0, y0, p, h, n)


@pytest.mark.parametrize("method,order", [(itg.RK45, 5), (itg.DOP853, 8)])
def test_fixed_step_convergence_order(method, order):
    """Error after a fixed time vs step size: slope of the log-log fit = the method's order."""
    p, y0 = _p003_start()
    t_span = 0.4
    ref = _fixed(itg.DOP853, y0, p, t_span / 4000, 4000)
    ns = [40, 56, 80, 113] if method == itg.RK45 else [12, 16, 20, 24]
    errs = [np.abs(_fixed(method, y0, p, t_span / n, n) - ref).max() for n in ns]
    slope = np.polyfit(np.log(t_span / np.array(ns)), np.log(errs), 1)[0]
    assert order - 0.35 < slope < order + 0.6, (errs, slope)


@pytest.mark.parametrize("order", [2, 4, 6])
def test_yoshida_convergence_order(order):
    """The TTL leapfrog composed by Yoshida: global error at a fixed fictitious time ~ h^order."""
    p, y0 = _p003_start()
    E, hh, Lz = P003["calE"], P003["h"], P003["Lz"]
    z0 = sym.initial_z(p, y0[0], 0.0, E, hh, Lz)
    s_span = 4.0
    ref = sym.sym_fixed(z0, p, E, hh, Lz, 6, s_span / 4096, 4096)
    ns = {2: [64, 128, 256, 512], 4: [32, 48, 64, 96], 6: [16, 24, 32, 48]}[order]
    errs = []
    for n in ns:
        z = sym.sym_fixed(z0, p, E, hh, Lz, order, s_span / n, n)
        errs.append(max(abs(z[0] - ref[0]) / ref[0], abs(z[2] - ref[2]), abs(z[3] - ref[3])))
    slope = np.polyfit(np.log(s_span / np.array(ns)), np.log(errs), 1)[0]
    assert order - 0.3 < slope < order + 0.6, (errs, slope)


# ------------------------------------------------------------------------------ events
@pytest.mark.parametrize("method", METHODS)
def test_apsides_are_roots_of_the_cubic(method):
    """Event radii = positive roots of C r^3 - calE r^2 + B r + A (numpy.roots), within
    10 rtol relative (r is stationary at an apsis, so a timing error enters squared)."""
    i = P003
    sc = Scene()
    A, B, C = coefficients(i["alpha"], i["h"], i["Lz"], sc.M, sc.g, sc.k)
    roots = np.sort(np.roots([C, -i["calE"], B, A]).real)
    r1, r2 = roots[1], roots[2]
    assert roots[0] < 0 < r1 < r2
    ds = simulate(i["alpha"], i["calE"], i["h"], i["Lz"], periods=3, method=method)
    kinds = ds.event_kind.values
    np.testing.assert_array_equal(kinds, [1, 0, 1, 0, 1, 0])  # apocentre, pericentre, ...
    r_ev = ds.event_r.values
    np.testing.assert_allclose(r_ev[kinds == 1], r2, rtol=10 * RTOL)
    np.testing.assert_allclose(r_ev[kinds == 0], r1, rtol=10 * RTOL)
    # u = 0 at the events: the trajectory's last point is the last event
    assert ds.time.values[-1] == ds.event_time.values[-1]
    assert abs(ds.u.values[-1]) <= 1e-7 * abs(ds.v.values[-1])


@pytest.mark.parametrize("method", ["rk45", "dop853"])
def test_rk_conserves_invariants_at_tight_tolerance(method):
    """rtol 1e-12: E, L_z and h stay within 1e-11 relative over five periods (h is conserved
    by the equations exactly, its drift is rounding)."""
    i = P003
    ds = simulate(i["alpha"], i["calE"], i["h"], i["Lz"], periods=5, method=method,
                         rtol=1e-12)  # fmt: skip
    assert np.abs(ds.E_drift).max() <= 1e-11 * abs(ds.attrs["E0"])
    assert np.abs(ds.Lz_drift).max() <= 1e-11 * abs(ds.attrs["Lz0"])
    assert np.abs(ds.h_drift).max() <= 1e-11 * abs(ds.attrs["h0"])


def _deciles(x):
    n = x.size
    return np.array([np.abs(x[k * n // 10 : (k + 1) * n // 10]).max() for k in range(10)])


def test_symplectic_energy_error_bounded_over_1e4_periods():
    """10^4 radial periods (rtol 1e-8, so the method's error dominates rounding): the energy
    error oscillates with a constant envelope, no secular growth, and stays below rtol."""
    i = P003
    T = float(engine.evaluate(i["alpha"], i["calE"], i["h"], i["Lz"]).period)
    ds = simulate(i["alpha"], i["calE"], i["h"], i["Lz"], periods=10_000,
                         method="symplectic", rtol=1e-8, dt_out=0.77 * T)  # fmt: skip
    dec = _deciles(ds.E_drift.values / ds.attrs["E0"])
    print("symplectic |dE/E| per decile of 10^4 periods:", dec)
    assert dec.max() <= 1e-8
    assert dec[-1] <= 1.2 * dec[0]
    assert ds.sizes["event"] == 20_000
    assert ds.event_time.values[-1] == pytest.approx(10_000 * T, rel=100 * 1e-8)


def test_rk45_energy_drift_is_reported_over_1e4_periods():
    """RK45 is not symplectic: its energy error grows linearly, and simulate reports it."""
    i = P003
    T = float(engine.evaluate(i["alpha"], i["calE"], i["h"], i["Lz"]).period)
    ds = simulate(i["alpha"], i["calE"], i["h"], i["Lz"], periods=10_000,
                         method="rk45", rtol=1e-8, dt_out=0.77 * T)  # fmt: skip
    assert ds.E_drift.attrs["units"] == "J"
    dec = _deciles(ds.E_drift.values / ds.attrs["E0"])
    print("rk45 |dE/E| per decile of 10^4 periods:", dec)
    assert dec[-1] > 5 * dec[0]  # secular growth, visible in the output
    # the drift stays within the sum of the local error bounds
    assert dec[-1] <= ds.attrs["n_steps"] * 1e-8


# ------------------------------------------------------------------------------ the batch kernel
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
    assert integrate(esc, "rk45")["status"] == itg.NOT_BOUNDED
    r = integrate(c, "rk45", max_steps=10)
    assert r["status"] == itg.MAX_STEPS and math.isnan(r["period"])
    r = integrate(c, "symplectic", max_steps=10)
    assert r["status"] == itg.MAX_STEPS


def test_symplectic_refuses_dissipative_scenes():
    c = dict(HARD["M_1e3"], scene=Scene(M=1e3, c_rr=1e-3))
    with pytest.raises(ValueError, match="symplectic.*rolling_resistance"):
        integrate(c, "symplectic")
    with pytest.raises(ValueError, match="symplectic.*attitude"):
        integrate(dict(c, scene=Scene(attitude=True)), "symplectic")
    # the kernel itself answers with a status code
    out_f, out_n, out_s = np.empty((5, 1)), np.empty(1, np.int64), np.empty(1, np.int8)
    arr = [np.array([c[k]]) for k in ("alpha", "energy", "h", "Lz")]
    integrate_points(*arr, scene_params(c["scene"]), itg.SYMPLECTIC, 1, RTOL, 1000, out_f, out_n,
                     out_s)  # fmt: skip
    assert out_s[0] == itg.UNSUPPORTED


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


def test_dop853_takes_fewer_steps_at_tight_tolerance():
    c = HARD["spin_dominated_hLz>0"]
    n45 = integrate(c, "rk45", rtol=1e-12)["n_steps"]
    n853 = integrate(c, "dop853", rtol=1e-12)["n_steps"]
    print(f"rtol 1e-12: rk45 {n45} steps, dop853 {n853} steps per period")
    assert n853 < n45 / 3


@pytest.mark.parametrize("bad", [0.0, 1e-15, 1e-2, -1e-10, "x", math.nan])
def test_rtol_is_validated(bad):
    c = HARD["M_1e3"]
    with pytest.raises(ValueError, match="rtol"):
        integrate(c, "rk45", rtol=bad)


def test_method_and_shapes_are_validated():
    c = HARD["M_1e3"]
    with pytest.raises(ValueError, match="method must be one of"):
        integrate(c, "euler")
    with pytest.raises(ValueError, match="energy has length 2"):
        evaluate_integrated(np.ones(1), np.ones(2), np.ones(1), np.ones(1), Scene(), "rk45")
    empty = evaluate_integrated(*[np.empty(0)] * 4, Scene(), "rk45")
    assert empty["period"].shape == (0,) and empty["status"].dtype == np.int8

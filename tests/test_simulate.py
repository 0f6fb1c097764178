"""engine.simulate: the single-trajectory API, its events and effects, and its validation."""

import math

import numpy as np
import pytest
from cases import HARD, P003, RTOL, closed_form, kappa

import engine
from engine.simulate import simulate

A3, E3, H3, L3 = P003["alpha"], P003["calE"], P003["h"], P003["Lz"]
EX = engine.evaluate(A3, E3, H3, L3)
R1, R2, T3 = float(EX.r_min), float(EX.r_max), float(EX.period)
METHODS = ("rk45", "dop853", "symplectic")


@pytest.fixture(scope="module")
def ds3():
    return simulate(A3, E3, H3, L3, periods=3)


def test_dataset_contract(ds3):
    ds = ds3
    assert set(ds.dims) == {"time", "event"}
    for name in ("r", "theta", "u", "v", "w", "x", "y", "z", "E_drift", "Lz_drift", "h_drift"):
        assert ds[name].dims == ("time",)
    for name in ("event_time", "event_kind", "event_r", "event_theta"):
        assert ds[name].dims == ("event",)
    for name in [*ds.data_vars, "time"]:
        assert ds[name].attrs.get("long_name"), name
        assert "units" in ds[name].attrs or name == "event_kind", name
    kind = ds.event_kind
    assert kind.dtype == np.int8 and kind.attrs["flag_values"].dtype == np.int8
    assert kind.attrs["flag_meanings"] == (
        "pericentre apocentre spill slip rest vertex horizon failed"
    )
    s, c = math.sin(A3), math.cos(A3)
    np.testing.assert_allclose(ds.x, ds.r * s * np.cos(ds.theta), rtol=1e-15)
    np.testing.assert_allclose(ds.y, ds.r * s * np.sin(ds.theta), rtol=1e-15)
    np.testing.assert_allclose(ds.z, ds.r * c, rtol=1e-15)
    assert np.all(np.diff(ds.time) > 0) and ds.time[0] == 0
    assert ds.r[0] == pytest.approx(R1, rel=1e-14) and ds.u[0] == 0 and ds.theta[0] == 0
    assert ds.attrs["status"] == 0 and ds.attrs["method"] == "rk45"
    assert ds.attrs["n_steps"] == ds.sizes["time"] - 1
    for v in ds.data_vars.values():
        if v.dtype.kind == "f":
            assert np.all(np.isfinite(v)), v.name


def test_periods_end_at_the_2n_th_apsis_and_match_the_closed_form(ds3):
    ev = ds3.event_time.values
    assert ds3.sizes["event"] == 6 and ds3.time.values[-1] == ev[-1]
    np.testing.assert_allclose(ev[1::2], T3 * np.arange(1, 4), rtol=100 * RTOL)
    psi = float(EX.apsidal_angle)
    th = np.abs(ds3.event_theta.values)
    np.testing.assert_allclose(th[0::2], psi + 2 * psi * np.arange(3), rtol=100 * RTOL)


@pytest.mark.parametrize("method", METHODS)
def test_t_end_and_sampling(method):
    ds = simulate(A3, E3, H3, L3, t_end=1.3 * T3, method=method, dt_out=0.01)
    t = ds.time.values
    assert t[-1] == pytest.approx(1.3 * T3, rel=1e-15)
    np.testing.assert_allclose(np.diff(t[:-1]), 0.01, rtol=1e-9)
    # samples on the dense output agree with a tighter run at the same times
    tight = simulate(A3, E3, H3, L3, t_end=1.3 * T3, method="dop853", rtol=1e-13, dt_out=0.01)
    np.testing.assert_allclose(ds.r, tight.r, rtol=1e3 * RTOL)
    np.testing.assert_allclose(ds.theta, tight.theta, rtol=1e3 * RTOL, atol=1e3 * RTOL)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("name", ["Lz_1e-7_grazes_axis", "free_fall_e_0.999", "alpha_1e-3"])
def test_hard_cases_trajectory(name, method):
    """The whole trajectory is finite and its events give the closed-form period and angle."""
    c = HARD[name]
    T, psi = closed_form(c)
    ds = simulate(c["alpha"], c["energy"], c["h"], c["Lz"], c["scene"], periods=2, method=method)
    for v in ("r", "theta", "u", "v", "w", "E_drift"):
        assert np.all(np.isfinite(ds[v])), v
    kinds = ds.event_kind.values
    np.testing.assert_array_equal(kinds, [1, 0, 1, 0])
    assert ds.event_time.values[1] == pytest.approx(T, rel=100 * RTOL * kappa(c))
    assert abs(ds.event_theta.values[0]) == pytest.approx(psi, rel=100 * RTOL)
    assert np.all(ds.r >= 0.999999 * float(ds.event_r[1]))


def test_long_run_records_every_step():
    """More steps than the first buffer guess (4096): the buffers grow, nothing is lost."""
    ds = simulate(A3, E3, H3, L3, periods=40)
    assert ds.sizes["time"] == ds.attrs["n_steps"] + 1 > 4096
    assert ds.sizes["event"] == 80
    assert np.all(np.diff(ds.time) > 0)


# ------------------------------------------------------------------------------ effects
@pytest.mark.parametrize("method", ["rk45"])
def test_rolling_resistance_makes_the_orbit_decay(method):
    # a rim and a friction limit out of reach: the effect set the fate tests compile too
    sc = engine.Scene(c_rr=2e-3, rim=1e6, mu=1e6)
    ds = simulate(A3, E3, H3, L3, sc, periods=4, method=method)
    dE = ds.E_drift.values
    E0 = abs(ds.attrs["E0"])
    assert np.all(np.diff(dE) <= 1e-12 * E0)  # monotone (up to rounding)
    assert dE[-1] < -1e-4 * E0
    assert np.all(np.abs(ds.Lz.values if "Lz" in ds else ds.Lz_drift.values + ds.attrs["Lz0"])
                  <= abs(ds.attrs["Lz0"]) * (1 + 1e-12))  # fmt: skip
    r_apo = ds.event_r.values[ds.event_kind.values == 1]
    assert np.all(np.diff(r_apo) < 0)  # apocentres shrink


# The rim and slip tests share one effect set (rim + slip check, the other one out of reach) and
# leave DOP853 out: the effects are the same code for every tableau, and each (method, effect
# set) pair is a separate compilation.
FAR = 1e6


@pytest.mark.parametrize("method", ["rk45", "symplectic"])
def test_rim_event_fires_at_the_rim(method):
    # the rim is the real cone's slant length; the centre reaches it at rim - a cot(alpha)
    r_rim = 0.5 * (R1 + R2)
    sc = engine.Scene(rim=r_rim + 0.01 / math.tan(A3), mu=FAR)
    ds = simulate(A3, E3, H3, L3, sc, periods=2, method=method)
    assert ds.attrs["status_message"].startswith("spilled")
    assert ds.event_kind.values[-1] == 2 and ds.sizes["event"] == 1
    assert float(ds.event_r[-1]) == pytest.approx(r_rim, rel=1e-12)
    assert ds.time.values[-1] == ds.event_time.values[-1]
    assert float(ds.r.max()) <= r_rim * (1 + 1e-12)
    # a rim beyond r_max never fires
    far = simulate(A3, E3, H3, L3, engine.Scene(rim=1.01 * R2 + 0.01 / math.tan(A3), mu=FAR),
                   periods=2, method=method)  # fmt: skip
    assert far.attrs["status"] == 0 and 2 not in far.event_kind.values


@pytest.mark.parametrize("method", ["rk45", "symplectic"])
def test_slip_event_against_the_closed_form_requirement(method):
    """mu below max |F|/N over the orbit (closed form) -> a slip event where |F|/N = mu;
    above it -> rolls through three periods."""
    mu_req = float(EX.mu_required)
    ds = simulate(A3, E3, H3, L3, engine.Scene(mu=0.97 * mu_req, rim=FAR), periods=3, method=method)
    assert ds.event_kind.values[-1] == 3
    assert ds.attrs["status_message"].startswith("slipped")
    assert float(ds.friction_ratio[-1]) == pytest.approx(0.97 * mu_req, rel=1e-9)
    assert float(ds.friction_ratio.max()) <= 0.97 * mu_req * (1 + 1e-9)
    ok = simulate(A3, E3, H3, L3, engine.Scene(mu=1.03 * mu_req, rim=FAR), periods=3, method=method)
    assert ok.attrs["status"] == 0 and 3 not in ok.event_kind.values
    # sampled at the steps only, |F|/N stays below its maximum over the orbit and comes close
    assert 0.9 * mu_req <= float(ok.friction_ratio.max()) <= mu_req * (1 + 1e-9)


@pytest.mark.parametrize("method", ["rk45"])
def test_attitude_stays_unit_and_rolls_without_slipping(method):
    sc = engine.Scene(attitude=True, a=0.05)
    ds = simulate(A3, E3, H3, L3, sc, t_end=T3, method=method)
    n = ds.attrs["n_steps"]
    speed = float(np.hypot(ds.u, ds.v).max())
    # each step adds at most ~rtol to |q| (the RMS error norm bounds every component by 3 rtol)
    assert float(np.abs(ds.quat_norm_error).max()) <= 3 * n * RTOL
    # at the steps omega = 2 qdot q* comes from the rates: rolling to rounding
    assert float(ds.contact_speed.max()) <= 1e-12 * speed
    # between steps, from the derivative of the dense output: O(rtol^(p/(p+1))) with p = 4
    sampled = simulate(A3, E3, H3, L3, sc, t_end=T3, method=method, dt_out=T3 / 200)
    assert float(sampled.contact_speed.max()) <= 10 * RTOL**0.8 * speed
    for q in ("quat_w", "quat_x", "quat_y", "quat_z"):
        assert ds[q].attrs["units"] == "1"
    assert ds.quat_w[0] == 1.0


# ------------------------------------------------------------------------------ validation
def _call(**kw):
    args = {"alpha": A3, "energy": E3, "h": H3, "Lz": L3, "periods": 1}
    args.update(kw)
    return simulate(**args)


@pytest.mark.parametrize(
    "kw,match",
    [
        ({"alpha": 0.0}, r"alpha .*\(0, pi/2\); got 0\.0"),
        ({"alpha": 2.0}, r"alpha .*got 2\.0"),
        ({"alpha": "x"}, r"alpha must be a real number; got 'x'"),
        ({"energy": math.nan}, r"energy must be finite; got nan"),
        ({"h": math.inf}, r"h must be finite; got inf"),
        ({"Lz": 0.0}, r"Lz must be nonzero"),
        ({"t_end": 1.0}, r"exactly one of t_end and periods; got t_end=1\.0, periods=1"),
        ({"periods": None}, r"exactly one of t_end and periods"),
        ({"periods": 0}, r"periods must be a positive integer; got 0"),
        ({"periods": 1.5}, r"periods must be a positive integer; got 1\.5"),
        ({"periods": None, "t_end": -1.0}, r"t_end must be > 0; got -1\.0"),
        ({"method": "euler"}, r"method must be one of rk45, dop853, symplectic; got 'euler'"),
        ({"rtol": 0.0}, r"rtol must lie in \[1e-14, 1e-3\]; got 0\.0"),
        ({"dt_out": 0.0}, r"dt_out must be > 0; got 0\.0"),
        ({"max_steps": 0}, r"max_steps must be >= 1; got 0"),
        ({"energy": 0.0}, r"energy=0\.0.*forbidden"),
        ({"scene": "cone"}, r"scene must be an engine.Scene; got 'cone'"),
    ],
)
def test_bad_inputs_name_the_argument(kw, match):
    with pytest.raises(ValueError, match=match):
        _call(**kw)


def test_symplectic_refuses_attitude_and_rolling_resistance():
    with pytest.raises(ValueError, match="symplectic.*attitude"):
        _call(scene=engine.Scene(attitude=True), method="symplectic")
    with pytest.raises(ValueError, match="symplectic.*rolling_resistance"):
        _call(scene=engine.Scene(c_rr=0.01), method="symplectic")


def test_escaping_free_fall_orbit_runs_with_t_end_only():
    c = HARD["free_fall_e_0.999"]
    sc = c["scene"]
    with pytest.raises(ValueError, match="escapes.*give t_end"):
        simulate(c["alpha"], 0.5, c["h"], c["Lz"], sc, periods=1)
    ds = simulate(c["alpha"], 0.5, c["h"], c["Lz"], sc, t_end=10.0)
    assert ds.attrs["orbit_class"] == "hyperbolic" and ds.sizes["event"] == 1  # the horizon
    assert ds.event_kind.attrs["flag_meanings"].split()[int(ds.event_kind[0])] == "horizon"
    assert float(ds.event_time[0]) == 10.0 and float(ds.event_r[0]) == float(ds.r[-1])
    assert np.all(np.diff(ds.r) > 0)
    assert np.abs(ds.E_drift).max() <= 1e-8 * abs(ds.attrs["E0"])


def test_circular_orbit_needs_t_end():
    v = float(np.asarray(engine.minimum_energy(A3, H3, L3)).reshape(-1)[0])
    with pytest.raises(ValueError, match="circular minimum.*give t_end"):
        _call(energy=v)
    ds = _call(energy=v, periods=None, t_end=T3)
    assert ds.attrs["orbit_class"] == "circular"
    rc = float(EX.r_circ)
    np.testing.assert_allclose(ds.r, rc, rtol=1e-6)


def test_step_budget_ends_the_trajectory_with_a_failed_event():
    ds = _call(max_steps=5)
    assert ds.attrs["status_message"] == "maximum number of steps reached"
    assert ds.event_kind.attrs["flag_meanings"].split()[int(ds.event_kind[-1])] == "failed"
    assert ds.sizes["time"] >= 2

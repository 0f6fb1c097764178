"""engine.simulate: the single-trajectory API, its events and effects, and its validation."""

import functools
import math

import numpy as np
import pytest
from cases import HARD, P003, RTOL, closed_form, kappa

import engine
from engine.simulate import simulate

A3, E3, H3, L3 = P003["alpha"], P003["calE"], P003["h"], P003["Lz"]


@functools.cache
def p003():
    """P003's closed form and (r_min, r_max, period): computed on first use, not at import
    (both xdist workers import every test file: each would compile the closed form's kernel)."""
    ex = engine.evaluate(A3, E3, H3, L3)
    return ex, float(ex.r_min), float(ex.r_max), float(ex.period)


METHODS = ("rk45", "dop853", "symplectic")


@pytest.fixture(scope="module")
def ds3():
    return simulate(A3, E3, H3, L3, periods=3)


def test_dataset_contract(ds3):
    EX, R1, R2, T3 = p003()
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
        "pericentre apocentre spill slip rest vertex horizon failed liftoff"
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
    EX, R1, R2, T3 = p003()
    ev = ds3.event_time.values
    assert ds3.sizes["event"] == 6 and ds3.time.values[-1] == ev[-1]
    np.testing.assert_allclose(ev[1::2], T3 * np.arange(1, 4), rtol=100 * RTOL)
    psi = float(EX.apsidal_angle)
    th = np.abs(ds3.event_theta.values)
    np.testing.assert_allclose(th[0::2], psi + 2 * psi * np.arange(3), rtol=100 * RTOL)


@pytest.mark.parametrize("method", METHODS)
def test_t_end_and_sampling(method):
    EX, R1, R2, T3 = p003()
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
    EX, R1, R2, T3 = p003()
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
    EX, R1, R2, T3 = p003()
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
    EX, R1, R2, T3 = p003()
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
        ({"alpha": 0.0}, r"alpha .*\(0, pi/2\) \[radian\]; got 0\.0"),
        ({"alpha": 2.0}, r"alpha .*got 2\.0"),
        ({"alpha": "x"}, r"alpha must hold real numbers, not text; got 'x'"),
        ({"energy": math.nan}, r"energy must be finite; got nan"),
        ({"h": math.inf}, r"h must be finite; got inf"),
        ({"Lz": 0.0}, r"Lz must be nonzero \(a radial orbit through the axis\); got 0\.0"),
        ({"t_end": 1.0}, r"exactly one of t_end and periods; got t_end=1\.0, periods=1"),
        ({"periods": None}, r"exactly one of t_end and periods"),
        ({"periods": 0}, r"periods must be a positive integer; got 0"),
        ({"periods": 1.5}, r"periods must be a positive integer; got 1\.5"),
        ({"periods": None, "t_end": -1.0}, r"t_end must be > 0; got -1\.0"),
        (
            {"method": "euler"},
            r"method must be one of exact, rk45, dop853, symplectic; got 'euler'",
        ),
        ({"method": "rk54"}, r"one of exact, rk45, dop853, symplectic \(did you mean 'rk45'\?\)"),
        ({"method": "exact"}, r"method must be an integrator, one of rk45, dop853, symplectic"),
        ({"rtol": 0.0}, r"rtol must lie in the open interval \(0, 1\); got 0\.0"),
        ({"rtol": 0.5}, r"rtol must lie in \[1e-14, 0\.001\] for the integrator rk45; got 0\.5"),
        ({"dt_out": 0.0}, r"dt_out must be > 0; got 0\.0"),
        ({"max_steps": 0}, r"max_steps must be a positive integer; got 0"),
        ({"energy": 0.0}, r"energy=0\.0.*forbidden"),
        ({"scene": "cone"}, r"scene must be an engine.Scene; got 'cone'"),
    ],
)
def test_bad_inputs_name_the_argument(kw, match):
    with pytest.raises(ValueError, match=match):
        _call(**kw)


def test_symplectic_refuses_attitude_rolling_resistance_and_sliding():
    with pytest.raises(ValueError, match="symplectic.*attitude"):
        _call(scene=engine.Scene(attitude=True), method="symplectic")
    with pytest.raises(ValueError, match="symplectic.*rolling_resistance"):
        _call(scene=engine.Scene(c_rr=0.01), method="symplectic")
    # the sliding model (mu_k, c_spin): refused with the reason, naming the methods that can
    sliding = engine.Scene(mu=0.5, mu_k=0.4, c_spin=0.01)
    reason = dict(engine.methods.get_method("symplectic").lacks)["sliding contact"]
    with pytest.raises(ValueError, match=rf"symplectic.*sliding.*{reason}.*can: rk45, dop853$"):
        _call(scene=sliding, method="symplectic")


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
    EX, R1, R2, T3 = p003()
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


# ------------------------------------------------------------------------------ sliding (mu_k)
#: (alpha, scene keywords, r, v, w of a point on the rolling orbit, u0, slip_u, slip_v): a
#: thrown ball that rolls and whose spin friction stops, releases and stops the spin again; a
#: backspin throw that rolls again; a rolling ball that never slips; a rolling ball that slips,
#: slides and rolls again.
HYBRID_CASES = {
    "spin stick": (0.25, dict(mu=0.6, mu_k=0.5, c_spin=0.2), 0.3, 0.8, 0.3, 0.5, 0.5, 0.0),
    "backspin": (0.6, dict(mu=0.6, mu_k=0.5), 0.3, 0.6, 0.5, 1.0, 2.5, 0.0),
    "rolls on": (1.0, dict(mu=0.05, mu_k=0.04), 0.2, 0.9, -1.5, 0.0, 0.0, 0.0),
    "slips": (0.6, dict(mu=0.05, mu_k=0.04), 0.2, 0.9, -1.5, 0.0, 0.0, 0.0),
}
HYBRID_KINDS = {
    "spin stick": ["roll", "spin_stop", "spin_go", "spin_stop", "horizon"],
    "backspin": ["roll", "horizon"],
    "rolls on": ["horizon"],
    "slips": ["slip", "roll", "horizon"],
}


@pytest.mark.parametrize("name", list(HYBRID_CASES))
def test_hybrid_trajectory_follows_the_story(name):
    """On a scene with mu_k, simulate lists the mode changes of engine.story on the same launch
    and samples each stretch in its mode. The events come from the same story kernel, started
    from the state simulate reports at t = 0 (rounding apart): the roll is located where the
    slip speed falls to 10 rtol x the speed scale, so rounding of the start moves it by about
    rtol x (speed / slip rate) ~ 1e-11 s at rtol 1e-11; 1e-8 s leaves a margin for the event
    locator. The samples are a second integration of each stretch from the story's state at
    its start (rtol 1e-11): the end state agrees with the story's to 1e-9 relative, and the
    energy balance E + W - E0 (the three works integrated beside the state) to 1e-9 of E0."""
    from engine.launch import invariants
    from engine.simulate_hybrid import HYBRID_EVENT_KINDS
    from engine.story import story

    alpha, kw, r, v, w, u0, su, sv = HYBRID_CASES[name]
    sc = engine.Scene(M=1.0, a=0.01, k=0.4, rim=1.0, **kw)
    inv = invariants(alpha, r, 0.0, v, w, sc)
    ds = simulate(alpha, float(inv["energy"]), float(inv["h"]), float(inv["Lz"]), sc,
                  t_end=0.5, method="dop853", rtol=1e-11, u0=u0, slip_u=su, slip_v=sv)  # fmt: skip
    kinds = [HYBRID_EVENT_KINDS[k] for k in ds.event_kind.values]
    assert kinds == HYBRID_KINDS[name]
    assert ds.event_kind.attrs["flag_meanings"].split() == list(HYBRID_EVENT_KINDS)
    out = story(alpha, float(ds.r[0]), float(ds.v[0]), float(ds.w[0]), u0=u0, slip_u=su,
                slip_v=sv, scene=sc, rtol=1e-11, horizon_time=0.5)  # fmt: skip
    assert [e["kind"] for e in out["events"]] == kinds[:-1] and out["fate"] == ds.attrs["fate"]
    for e, t, r_ev in zip(out["events"], ds.event_time.values, ds.event_r.values, strict=False):
        assert t == pytest.approx(e["t"], abs=1e-8), e["kind"]
        assert r_ev == pytest.approx(e["state"]["r"], rel=1e-8), e["kind"]
    assert float(ds.r[-1]) == pytest.approx(out["fate_r"], rel=1e-9)
    assert float(ds.theta[-1]) == pytest.approx(out["fate_theta"], rel=1e-9)
    # the start: the launch; time increasing; the end at the horizon
    assert ds.u[0] == u0 and float(ds.slip_speed[0]) == pytest.approx(math.hypot(su, sv))
    assert np.all(np.diff(ds.time) > 0) and ds.time[-1] == 0.5 == ds.event_time[-1]
    # the mode: sliding from the throw or a slip to the roll, rolling otherwise (no slip speed
    # while rolling); a sample at a mode change is the new stretch's start
    t_roll = ds.event_time.values[kinds.index("roll")] if "roll" in kinds else 0.0
    mode = ds.mode.values
    expected = np.full(mode.shape, 1 if (su, sv) != (0.0, 0.0) else 0)
    for kind, t in zip(kinds, ds.event_time.values, strict=True):
        if kind in ("slip", "roll"):
            expected[ds.time.values >= t] = 1 if kind == "slip" else 0
    np.testing.assert_array_equal(mode, expected)
    speed = float(np.hypot(ds.u, ds.v).max())
    assert float(ds.slip_speed.values[mode == 0].max()) <= 1e-12 * speed
    if t_roll:
        assert float(ds.slip_speed.values[mode == 1][1:].min()) > 0.0
    # the spin stuck between spin_stop and spin_go: w = 0 exactly there
    if "spin_go" in kinds:
        t_stop, t_go = ds.event_time.values[[kinds.index("spin_stop"), kinds.index("spin_go")]]
        assert np.all(ds.w.values[(ds.time >= t_stop) & (ds.time < t_go)] == 0.0)
    E0 = ds.attrs["E0"]
    assert float(np.abs(ds.balance_drift).max()) <= 1e-9 * E0
    assert np.all(np.diff(ds.energy) <= 1e-9 * E0)  # E never rises
    if t_roll or "spin_stop" in kinds:  # the roll and the spin's stop cost energy
        assert float(ds.E_drift[-1]) < -1e-6 * E0


def test_hybrid_trajectory_samples_match_the_rigid_body_model():
    """The samples themselves, not only the story's events, against the independent model of
    tests/hybrid_oracle.py (scipy DOP853 at rtol 1e-12), run from simulate's start to each
    sample time: the backspin throw sliding (0.03 s; 0.05 s, 12 us before the roll, where the
    steps meet the slip's kink at s = 0) and rolling again (0.1 s, 0.2 s). Place, speed and
    slip speed to 1e-7 of their scale, as the story's events in tests/test_hybrid_oracle.py."""
    from hybrid_oracle import Oracle, polar, start_state

    from engine.launch import invariants

    alpha, kw, r, v, w, u0, su, sv = HYBRID_CASES["backspin"]
    sc = engine.Scene(M=1.0, a=0.01, k=0.4, rim=1.0, **kw)
    inv = invariants(alpha, r, 0.0, v, w, sc)
    ds = simulate(alpha, float(inv["energy"]), float(inv["h"]), float(inv["Lz"]), sc,
                  t_end=0.2, method="dop853", rtol=1e-11, u0=u0, slip_u=su, slip_v=sv,
                  dt_out=0.01)  # fmt: skip
    oracle = Oracle(alpha, 1.0, sc.g, sc.a, sc.k, sc.mu, sc.mu_k,
                    rim_centre=1.0 - sc.a / math.tan(alpha))  # fmt: skip
    y0 = start_state(alpha, float(ds.r[0]), u0, float(ds.v[0]), float(ds.w[0]), su, sv, sc.a)
    speed = max(abs(u0), abs(float(ds.v[0])), abs(float(ds.w[0])), abs(su), abs(sv))
    for t in (0.03, 0.05, 0.1, 0.2):
        i = int(np.argmin(np.abs(ds.time.values - t)))
        assert ds.time.values[i] == pytest.approx(t, abs=1e-12)
        _, y, mode = oracle.run(y0, "sliding", t, speed)
        assert ds.mode.values[i] == (1 if mode == "sliding" else 0), t
        r_o, th_o = polar(y, alpha)
        assert float(ds.r[i]) == pytest.approx(r_o, rel=1e-7), t
        assert abs((float(ds.theta[i]) - th_o + math.pi) % (2 * math.pi) - math.pi) < 1e-7, t
        assert math.hypot(ds.u[i], ds.v[i]) == pytest.approx(np.linalg.norm(y[3:6]),
                                                            abs=1e-7 * speed), t  # fmt: skip
        slip = np.linalg.norm(oracle.slip(y[0:3], y[3:6], y[6:9]))
        assert float(ds.slip_speed[i]) == pytest.approx(slip, abs=1e-7 * speed), t


def test_hybrid_trajectory_samples_on_dt_out_agree_with_a_tighter_run():
    alpha, kw, r, v, w, u0, su, sv = HYBRID_CASES["spin stick"]
    sc = engine.Scene(M=1.0, a=0.01, k=0.4, rim=1.0, **kw)
    from engine.launch import invariants

    inv = invariants(alpha, r, 0.0, v, w, sc)
    args = (alpha, float(inv["energy"]), float(inv["h"]), float(inv["Lz"]), sc)
    kw = dict(t_end=0.5, method="dop853", u0=u0, slip_u=su, slip_v=sv, dt_out=0.01)
    ds = simulate(*args, rtol=1e-8, **kw)
    tight = simulate(*args, rtol=1e-11, **kw)
    on_grid = np.isclose(ds.time.values / 0.01, np.round(ds.time.values / 0.01), atol=1e-9)
    assert on_grid.sum() == 51 and ds.sizes["time"] == 51 + ds.sizes["event"] - 1
    # the samples of a run at rtol 1e-8 against rtol 1e-11 at the grid's times: the spin's
    # stop and release move by ~rtol x their time scale, so the states agree to ~1e3 rtol
    g, gt = ds.time.values[on_grid], tight.time.values
    mask = np.isin(np.round(gt / 0.01, 6), np.round(g / 0.01, 6))
    np.testing.assert_allclose(ds.r.values[on_grid], tight.r.values[mask], rtol=1e-5)
    np.testing.assert_allclose(ds.theta.values[on_grid], tight.theta.values[mask], atol=1e-5)


def test_hybrid_launch_keys_need_mu_k_and_t_end():
    with pytest.raises(ValueError, match=r"u0 must be 0 without Scene\.mu_k: .*; got 0\.5"):
        _call(u0=0.5)
    with pytest.raises(ValueError, match=r"slip_v must be finite; got nan"):
        _call(slip_v=math.nan)
    with pytest.raises(ValueError, match=r"periods=1: a scene with mu_k .*give t_end"):
        _call(scene=engine.Scene(mu=0.5, mu_k=0.4))


def test_a_launch_at_its_apocentre_starts_there():
    """``r0``: a ball released at rest radially at r0 = 2 m slower than circular starts at its
    apocentre (the closed form's r_max is r0); on the ideal cone its path is the one from r_min
    half a closed-form period later."""
    sc = engine.Scene()
    inv = engine.invariants(0.5, 2.0, 0.0, 1.0, 0.3, sc)
    E, h, L = float(inv["energy"]), float(inv["h"]), float(inv["Lz"])
    ev = engine.evaluate(0.5, E, h, L, sc)
    T = float(ev.period)
    assert float(ev.r_max) == pytest.approx(2.0, rel=1e-12)
    a = engine.simulate(0.5, E, h, L, sc, t_end=2 * T, dt_out=T / 200, r0=2.0, method="dop853",
                        rtol=1e-11)  # fmt: skip
    b = engine.simulate(0.5, E, h, L, sc, t_end=3 * T, dt_out=T / 200, method="dop853",
                        rtol=1e-11)  # fmt: skip
    assert a.r.values[0] == 2.0 and a.u.values[0] == 0.0
    np.testing.assert_allclose(a.r.min(), ev.r_min, rtol=1e-9)
    shifted = np.interp(a.time.values + T / 2, b.time.values, b.r.values)
    np.testing.assert_allclose(a.r.values, shifted, rtol=0, atol=1e-8)
    with pytest.raises(ValueError, match="r0=3.0 is not on the orbit"):
        engine.simulate(0.5, E, h, L, sc, t_end=T, r0=3.0)

"""The ball's whole story (engine.hybrid, engine.story, engine.kernels.hybrid): the flat limit
and spin friction through the engine, the energy balance of the three losses, the anti-
chattering rule, and a scene that never slips giving today's fate map bit for bit."""

import math

import numpy as np
import pytest
from hybrid_oracle import Oracle, start_state

from engine import launch
from engine.fates import Horizon, fates
from engine.hybrid import hybrid_fates
from engine.kernels.hybrid import HYBRID_FATE_NAMES
from engine.kernels.model import CONE
from engine.kernels.sliding import hybrid_energy, hybrid_params
from engine.scene import Scene
from engine.story import launch_fates, story

FLAT = math.pi / 2 - 1e-4
G = 9.81
#: The scenes of these tests (each effect set is one compile: keep them few).
PLAIN = dict(mu=0.5, mu_k=0.25, rim=5000.0)


def _energy(scene, alpha, st):
    hp = hybrid_params(scene.params(alpha), scene.mu_k, scene.c_spin)
    return hybrid_energy.py_func(CONE, st["r"], st["u"], st["v"], st["p1"], st["p2"], st["w"], hp)


@pytest.mark.parametrize("k", [0.4, 2.0 / 3.0])
def test_flat_limit_slides_then_rolls(k):
    sc = Scene(k=k, M=1.0, **PLAIN)
    u0 = 2.0
    out = story(FLAT, 1000.0, 0.0, 0.0, u0=u0, slip_u=u0, scene=sc, horizon_time=1.0)
    kinds = [e["kind"] for e in out["events"]]
    assert kinds == ["roll"]
    t_roll = out["events"][0]["t"]
    # O(cot alpha) = 1e-4 from the slope
    assert t_roll == pytest.approx(k * u0 / ((1 + k) * sc.mu_k * G), rel=1e-3)
    assert out["events"][0]["state"]["u"] == pytest.approx(u0 / (1 + k), rel=1e-3)
    assert out["slide_time"] == t_roll
    assert out["slip_episodes"] == 1
    assert out["lost_sliding_friction"] == pytest.approx(u0**2 * k / (2 * (1 + k)), rel=1e-3)
    assert out["fate"] == "rolling"


@pytest.mark.parametrize("backspin", [1.0, 8.0])
def test_flat_limit_backspin_comes_back(backspin):
    sc = Scene(k=0.4, **PLAIN)
    u0 = 2.0
    out = story(FLAT, 1000.0, 0.0, 0.0, u0=u0, slip_u=u0 + backspin, scene=sc, horizon_time=2.0)
    roll = [e for e in out["events"] if e["kind"] == "roll"][0]
    final = (u0 - 0.4 * backspin) / 1.4
    assert roll["state"]["u"] == pytest.approx(final, rel=1e-3)
    assert (roll["state"]["u"] < 0) == (backspin > u0 / 0.4)


def test_spin_friction_alone_stops_the_spin_and_holds_it():
    k, w0, c_spin = 0.4, 3.0, 0.05
    sc = Scene(k=k, c_spin=c_spin, **PLAIN)
    out = story(FLAT, 1000.0, 0.0, w0, scene=sc, horizon_time=3.0)
    stops = [e for e in out["events"] if e["kind"] == "spin_stop"]
    assert len(stops) == 1 and not [e for e in out["events"] if e["kind"] == "spin_go"]
    assert stops[0]["t"] == pytest.approx(k * w0 / (c_spin * G), rel=1e-6)
    assert out["lost_spin_friction"] == pytest.approx(0.5 * k * w0**2, rel=1e-6)


def _random_launches(n, seed):
    rng = np.random.default_rng(seed)
    alpha = rng.choice([0.2, 0.5, 0.9, 1.3], n)
    r0 = rng.uniform(0.05, 0.5, n)
    v0 = rng.uniform(0.1, 1.5, n) * rng.choice([-1, 1], n)
    w0 = rng.uniform(-2, 2, n)
    u0 = rng.uniform(-1, 1, n)
    slip_u = rng.choice([0.0, 1.0], n) * rng.uniform(-2, 2, n)
    slip_v = rng.choice([0.0, 1.0], n) * rng.uniform(-2, 2, n)
    return alpha, r0, v0, w0, u0, slip_u, slip_v


def test_losses_add_up_to_the_energy_drop_and_energy_never_increases():
    sc = Scene(mu=0.3, mu_k=0.2, c_spin=0.02, c_rr=0.01, rim=1.0)
    alpha, r0, v0, w0, u0, su, sv = _random_launches(40, 16)
    res = launch_fates(alpha, r0, v0, w0, u0=u0, slip_u=su, slip_v=sv, scene=sc, rtol=1e-11,
                       horizon_time=2.0)  # fmt: skip
    assert not (res["fate_name"] == "failed").any(), res["fate_name"]
    losses = res["lost_effects"] + res["lost_sliding_friction"]
    losses = losses + res["lost_spin_friction"]
    inv = launch.invariants(alpha, r0, u0, v0, w0, sc)
    scale = np.abs(inv["E"]) + 0.5 * (u0**2 + v0**2 + w0**2 + su**2 + sv**2)
    assert np.all(np.abs(losses - res["energy_lost"]) <= 1e-9 * scale)
    assert (res["slip_episodes"] >= 1).sum() >= 10  # the launches do slide
    for i in range(0, 40, 4):
        out = story(alpha[i], r0[i], v0[i], w0[i], u0=u0[i], slip_u=su[i], slip_v=sv[i],
                    scene=sc, rtol=1e-11, horizon_time=2.0)  # fmt: skip
        energies = [_energy(sc, alpha[i], e["state"]) for e in out["events"]]
        assert all(b <= a + 1e-10 * scale[i] for a, b in zip(energies, energies[1:], strict=False))


def test_no_chattering_when_kinetic_equals_static_friction():
    """mu_k = mu: at the slip the slip speed grows only at second order. The return to rolling
    is armed only once |s| exceeded twice the threshold, so the story cannot switch back and
    forth within a step; it ends normally with a few episodes."""
    sc = Scene(mu=0.05, mu_k=0.05, rim=1.0)
    out = story(0.5, 0.1, 0.8, 0.5, scene=sc, rtol=1e-10, horizon_time=1.0)
    assert out["fate"] != "failed"
    ev = out["events"]
    assert out["slip_episodes"] >= 1
    assert out["slip_episodes"] < 20
    times = [e["t"] for e in ev if e["kind"] in ("slip", "roll")]
    assert all(b > a for a, b in zip(times, times[1:], strict=False))


#: Launches (alpha, r0, v0, w0) with each fate a never-slipping scene has within 1.5 s: rolling
#: (narrow and wide), spilled (narrow and wide), vertex (no L_z; with spin), rolling slowly
#: near the vertex, and beyond the rim (no_orbit).
EVERY_FATE = [(0.294, 0.365, 0.493, -1.219), (1.081, 0.367, 1.985, -1.755),
              (0.304, 0.759, 2.507, 1.657), (1.225, 0.78, 2.482, 1.245), (0.6, 0.3, 0.0, 0.0),
              (1.2, 0.2, 0.0, 1.0), (0.5, 0.25, 0.05, -0.5), (0.8, 1.2, 0.5, 0.0)]  # fmt: skip


def test_never_slipping_map_equals_todays_fate_map_bit_for_bit():
    rolling = Scene(mu=50.0, rim=1.0)
    sliding = Scene(mu=50.0, mu_k=0.3, rim=1.0)
    alpha, r0, v0, w0 = (np.array(x) for x in zip(*EVERY_FATE, strict=True))
    inv = launch.invariants(alpha, r0, 0.0, v0, w0, rolling)
    args = (alpha, inv["energy"], inv["h"], inv["Lz"], r0)
    today = fates(*args, rolling, "dop853", 1e-10, Horizon(time=1.5))
    mine = hybrid_fates(*args, sliding, "dop853", 1e-10, 1.5, math.inf)
    names = [HYBRID_FATE_NAMES[f] for f in today["fate"]]
    assert set(names) == {"rolling", "spilled", "vertex", "no_orbit"}, names
    for name in ("fate", "fate_time", "fate_r", "fate_theta", "revolutions", "energy_lost",
                 "invariant_drift", "n_steps"):  # fmt: skip
        np.testing.assert_array_equal(mine[name], today[name], err_msg=name)
    orbit = np.array(names) != "no_orbit"
    assert (mine["slip_episodes"][orbit] == 0).all()
    assert not np.isnan(mine["final_energy"][orbit]).any()
    assert np.isnan(mine["final_energy"][~orbit]).all()
    np.testing.assert_array_equal(mine["final_Lz"][orbit], inv["Lz"][orbit])


def test_scene_validates_mu_k_and_c_spin():
    with pytest.raises(ValueError, match="mu_k must be <= Scene.mu"):
        Scene(mu=0.1, mu_k=0.2)
    with pytest.raises(ValueError, match="needs the static coefficient"):
        Scene(mu_k=0.2)
    with pytest.raises(ValueError, match="c_spin"):
        Scene(c_spin=0.1)
    with pytest.raises(ValueError, match="k > 0"):
        Scene(mu=0.3, mu_k=0.2, k=0.0)
    assert "slipped" not in Scene(mu=0.3).effects
    assert Scene(mu=0.3, mu_k=0.2, c_spin=0.1).effects == ("slip_check", "sliding",
                                                           "spin_friction")  # fmt: skip


#: scripts/bench_slide.py's scene (rolling resistance; a slip is a transition) and launches
#: (alpha, r0, v0, w0) of its random set whose slip, on its way back to zero, once hovered at
#: a few times the stop threshold with ever shorter steps until the step budget ran out (the
#: steps went through s = 0, or could not follow the slip's turning any closer to zero).
BENCH = dict(mu=0.3, mu_k=0.25, c_rr=0.02, rim=1.0)
STALLED = {
    0.0: [(0.952074, 0.338947, 0.698355, 1.559281), (0.485933, 0.325734, 0.475267, -0.664909),
          (0.4605, 0.306741, 0.427301, 0.228249), (0.749718, 0.332471, 0.568077, 0.371401)],
    0.01: [(0.485933, 0.325734, 0.475267, -0.664909), (0.511334, 0.35663, 0.503646, -0.770138),
           (0.506418, 0.454319, 0.566247, -0.913382)],
}  # fmt: skip


@pytest.mark.parametrize("c_spin", sorted(STALLED))
def test_a_slip_friction_stops_returns_to_rolling_within_a_modest_step_budget(c_spin):
    sc = Scene(c_spin=c_spin, **BENCH)
    alpha, r0, v0, w0 = (np.array(x) for x in zip(*STALLED[c_spin], strict=True))
    inv = launch.invariants(alpha, r0, 0.0, v0, w0, sc)
    args = (alpha, inv["energy"], inv["h"], inv["Lz"], r0, sc, "dop853", 1e-10)
    lost = []
    for t_max in (1.0, 2.0, 3.0, 4.0, 5.0):
        res = hybrid_fates(*args, t_max, math.inf, max_steps=20_000)
        names = [HYBRID_FATE_NAMES[f] for f in res["fate"]]
        assert set(names) <= {"rolling", "sliding"}, names  # to the horizon, no failure
        assert (res["slip_episodes"] >= 1).all() and (res["n_steps"] < 20_000).all()
        parts = sum(res[n] for n in ("lost_effects", "lost_sliding_friction",
                                     "lost_spin_friction"))  # fmt: skip
        assert (np.abs(parts - res["energy_lost"]) <= 1e-9 * np.abs(inv["E"])).all()
        lost.append(res["energy_lost"])
    assert (np.diff(lost, axis=0) >= 0.0).all()  # E never increases


def test_the_stalled_slip_returns_to_rolling_when_the_rigid_body_model_does():
    """The launch of STALLED that slips at once: its slide time (slip to roll) and the
    invariants of the orbit it rolls on after, against tests/hybrid_oracle.py."""
    sc = Scene(**BENCH)
    al, r, v, w = STALLED[0.0][1]
    inv = launch.invariants(al, r, 0.0, v, w, sc)
    res = hybrid_fates(*(np.array([x]) for x in (al, inv["energy"], inv["h"], inv["Lz"], r)), sc,
                       "dop853", 1e-10, 0.3, math.inf, max_steps=20_000)  # fmt: skip
    oracle = Oracle(al, sc.M, sc.g, sc.a, sc.k, sc.mu, sc.mu_k, c_rr=sc.c_rr,
                    rim_centre=1.0 - sc.a / math.tan(al))  # fmt: skip
    ev, _, _ = oracle.run(start_state(al, r, 0.0, v, w, 0.0, 0.0, sc.a), "rolling", 0.3,
                          max(abs(v), abs(w)))  # fmt: skip
    assert [e[0] for e in ev] == ["slip", "roll"] and ev[0][1] == 0.0
    assert res["slip_episodes"][0] == 1 and HYBRID_FATE_NAMES[res["fate"][0]] == "rolling"
    assert res["slide_time"][0] == pytest.approx(ev[1][1], rel=1e-7)
    calE, h, Lz = oracle.invariants(ev[1][2])
    speed = max(abs(v), abs(w))
    assert res["final_energy"][0] == pytest.approx(calE, abs=1e-8 * (0.5 * speed**2 + sc.g * r))
    assert res["final_h"][0] == pytest.approx(h, abs=1e-8 * speed)
    assert res["final_Lz"][0] == pytest.approx(Lz, abs=1e-8 * speed * r)


@pytest.mark.parametrize("case", ["spin stops at rest", "slides without turning"])
def test_trajectory_at_rest_and_sliding_without_turning(case):
    """engine.simulate on the story's new ends: on the flat a rolling ball that rolling
    resistance stops (rest) while its spin goes on until spin friction stops it in place
    (spin_stop, the fate rest); a topspin throw with c_rr > mu_k whose tangential spin stops
    while it slides (a mark of the kernel's, not an event) and which slides to rest. The
    events are the story's, the samples after the centre's stop are at rest with the spin
    falling at c_spin g sin(alpha)/k, and the energy balance holds."""
    from engine.simulate import simulate
    from engine.simulate_hybrid import HYBRID_EVENT_KINDS

    if case == "spin stops at rest":
        sc = Scene(k=0.4, M=1.0, mu=0.3, mu_k=0.2, c_spin=0.02, c_rr=0.1, rim=5000.0)
        v0, w0, u0, su, kinds, fate = 0.3, 2.0, 0.0, 0.0, ["rest", "spin_stop"], "rest"
    else:  # backspin: (p1, p2) = (-v0, u0 - slip_u) stops and stays 0 before the slip does;
        # no spin friction, so the fate is `spinning` if the orbit left any spin, else `rest`
        sc = Scene(k=0.4, M=1.0, mu=0.3, mu_k=0.2, c_rr=0.25, rim=5000.0)
        v0, w0, u0, su, kinds, fate = 0.3, 0.0, 1.0, 3.0, ["roll", "rest"], None
    inv = launch.invariants(FLAT, 1000.0, 0.0, v0, w0, sc)
    ds = simulate(FLAT, float(inv["energy"]), float(inv["h"]), float(inv["Lz"]), sc, t_end=8.0,
                  method="dop853", rtol=1e-10, u0=u0, slip_u=su)  # fmt: skip
    assert [HYBRID_EVENT_KINDS[k] for k in ds.event_kind.values] == kinds
    out = story(FLAT, float(ds.r[0]), float(ds.v[0]), float(ds.w[0]), u0=u0, slip_u=su,
                scene=sc, rtol=1e-10, horizon_time=8.0)  # fmt: skip
    assert [e["kind"] for e in out["events"]] == kinds and ds.attrs["fate"] == out["fate"]
    assert (
        out["fate"] == fate
        or fate is None
        and out["fate"] == ("spinning" if out["fate_spin"] != 0.0 else "rest")
    )
    np.testing.assert_allclose(ds.event_time.values, [e["t"] for e in out["events"]], rtol=1e-12)
    assert float(ds.time[-1]) == out["fate_time"]
    E0 = ds.attrs["E0"]
    assert float(np.abs(ds.balance_drift).max()) <= 1e-9 * E0
    if case == "spin stops at rest":
        t_rest, t_stop = ds.event_time.values
        rate = 0.02 * G * math.sin(FLAT) / 0.4  # at rest N = M g sin(alpha)
        w_rest = float(ds.event_w[0])
        assert t_stop == pytest.approx(t_rest + abs(w_rest) / rate, rel=1e-12)
        at_rest = ds.time.values > t_rest
        assert at_rest.sum() >= 2 and (ds.u.values[at_rest] == 0.0).all()
        np.testing.assert_allclose(ds.w.values[at_rest],
                                   w_rest - rate * (ds.time.values[at_rest] - t_rest),
                                   atol=1e-9)  # fmt: skip
    else:  # the tangential spin stopped while it slid: p1 = p2 = 0 from there to the roll
        sliding = ds.mode.values == 1
        assert ds.p2.values[0] == -2.0 and (ds.p2.values[sliding][-3:] == 0.0).all()
        assert (ds.p1.values[sliding][-3:] == 0.0).all() and float(ds.w[-1]) == out["fate_spin"]

"""engine.story.story on a nearly flat cone where the whole story has a closed form: a ball
thrown without spin slides, rolls again, and rolling resistance (acting in both modes) brings
it to a true rest; with a spin about the normal, spin friction stops that spin first. The
scene has the effect set of tests/test_hybrid.py's energy test (one compile for both)."""

import math

import pytest

from engine.scene import Scene
from engine.story import story

G = 9.81
#: cot(alpha) = 1e-6: the slope's pull g cot(alpha) changes speeds by ~2e-5 of themselves over
#: the 2 s of the story, the bound of the closed form's error (tolerance 1e-4 relative).
ALPHA = math.pi / 2 - 1e-6
K, MU_K, C_RR, C_SPIN = 0.4, 0.2, 0.1, 0.02


@pytest.mark.parametrize("w0", [0.0, 0.5])
def test_thrown_ball_slides_rolls_and_comes_to_rest_on_a_flat_cone(w0):
    """Thrown radially at u0 without spin (slip s = u0, p2 = 0), on the flat: friction
    mu_k M g slows the centre, du/dt = -mu_k g, and spins the ball up against the rolling
    resistance's couple c_rr N a, dp2/dt = (mu_k - c_rr) g/k; the slip falls at
    g((1+k) mu_k - c_rr)/k and is gone at t1 = k u0/(g((1+k) mu_k - c_rr)), the ball then
    rolling at V1 = u0 - mu_k g t1. Rolling, the resistance slows it at c_rr g/(1+k): at rest
    after t2 = (1+k) V1/(c_rr g), and it stays (cot(alpha) <= c_rr). Sliding friction does
    mu_k M g u0 t1/2 (the slip falls linearly), the rest of M u0^2/2 goes to rolling
    resistance. A spin w0 about the normal falls at c_spin g/k (N = M g): stopped at
    k w0/(c_spin g) (1.02 s, rolling), its energy k M w0^2/2 booked to spin friction."""
    sc = Scene(k=K, M=1.0, mu=0.3, mu_k=MU_K, c_spin=C_SPIN, c_rr=C_RR, rim=5000.0)
    u0 = 2.0
    out = story(ALPHA, 1000.0, 0.0, w0, u0=u0, slip_u=u0, scene=sc, rtol=1e-10,
                horizon_time=5.0)  # fmt: skip
    t1 = K * u0 / (G * ((1 + K) * MU_K - C_RR))
    v1 = u0 - MU_K * G * t1
    t_rest = t1 + (1 + K) * v1 / (C_RR * G)
    kinds = [e["kind"] for e in out["events"]]
    assert kinds == (["roll", "spin_stop", "rest"] if w0 else ["roll", "rest"])
    roll = out["events"][0]
    assert roll["t"] == pytest.approx(t1, rel=1e-4)
    assert roll["state"]["u"] == pytest.approx(v1, rel=1e-4)
    assert out["fate"] == "rest" and out["fate_time"] == pytest.approx(t_rest, rel=1e-4)
    # at rest: a true rest (the hybrid steps stop at a threshold, 10 rtol x the speed scale,
    # and carry the stop on to zero speed, as the rolling integrators do)
    assert out["fate_speed"] == 0.0
    assert out["slide_time"] == roll["t"] and out["slip_episodes"] == 1
    if w0:
        stop = out["events"][1]
        assert stop["t"] == pytest.approx(K * w0 / (C_SPIN * G), rel=1e-6)
    lost_slide = MU_K * G * u0 * t1 / 2
    assert out["lost_sliding_friction"] == pytest.approx(lost_slide, rel=1e-4)
    assert out["lost_effects"] == pytest.approx(u0**2 / 2 - lost_slide, rel=1e-4)
    assert out["lost_spin_friction"] == pytest.approx(K * w0**2 / 2, rel=1e-6, abs=1e-15)
    assert out["energy_lost"] == pytest.approx((u0**2 + K * w0**2) / 2, rel=1e-4)


def test_still_sliding_at_the_horizon():
    """The same throw stopped at 0.2 s, before the slip is gone (t1 = 0.45 s): fate sliding,
    the centre's speed then u0 - mu_k g t, all of the time sliding, and no last rolling orbit
    (final_energy, final_h, final_Lz NaN)."""
    sc = Scene(k=K, M=1.0, mu=0.3, mu_k=MU_K, c_spin=C_SPIN, c_rr=C_RR, rim=5000.0)
    u0, t = 2.0, 0.2
    out = story(ALPHA, 1000.0, 0.0, 0.0, u0=u0, slip_u=u0, scene=sc, rtol=1e-10,
                horizon_time=t)  # fmt: skip
    assert out["fate"] == "sliding" and out["fate_time"] == t and out["slide_time"] == t
    assert [e["kind"] for e in out["events"]] == [] and out["slip_episodes"] == 1
    assert out["fate_speed"] == pytest.approx(u0 - MU_K * G * t, rel=1e-4)
    assert all(math.isnan(out[n]) for n in ("final_energy", "final_h", "final_Lz"))


# ------------------------------------------------------------------- rest: centre and spin
def test_rest_waits_for_the_spin_to_stop():
    """docs/physics.md "Using it" with w0 = 5 m/s: the centre stops at 2.0387 s with the spin
    still at 4 m/s; rest is the centre and the spin stopped, so the story goes on to the spin's
    stop. On the flat the normal force is M g sin(alpha) throughout (v = 0), so spin friction
    slows the spin at c_spin g sin(alpha)/k in both modes and at rest: it stops at
    k w0/(c_spin g sin(alpha)) = 10.19 s, and takes all of k M w0^2/2."""
    sc = Scene(k=K, M=1.0, mu=0.3, mu_k=MU_K, c_spin=C_SPIN, c_rr=C_RR, rim=5000.0)
    u0, w0 = 2.0, 5.0
    out = story(ALPHA, 1000.0, 0.0, w0, u0=u0, slip_u=u0, scene=sc, rtol=1e-10,
                horizon_time=20.0)  # fmt: skip
    t_spin = K * w0 / (C_SPIN * G * math.sin(ALPHA))
    assert [e["kind"] for e in out["events"]] == ["roll", "rest", "spin_stop"]
    rest, stop = out["events"][1:]
    assert rest["state"]["u"] == 0.0 and rest["state"]["w"] == pytest.approx(
        w0 - C_SPIN * G * rest["t"] / K, rel=1e-6
    )  # the centre at rest, the spin going on
    assert out["fate"] == "rest" and stop["t"] == pytest.approx(t_spin, rel=1e-9)
    assert out["fate_time"] == stop["t"] and out["fate_speed"] == 0.0 and out["fate_spin"] == 0.0
    assert out["final_h"] == 0.0 and out["final_Lz"] == 0.0  # the state at rest, not w0
    assert out["lost_spin_friction"] == pytest.approx(K * w0**2 / 2, rel=1e-9)
    assert out["energy_lost"] == pytest.approx((u0**2 + K * w0**2) / 2, rel=1e-4)


def test_a_ball_released_at_rest_spinning_rests_when_its_spin_stops():
    """Released at rest on the flat with a spin a omega = 0.6 m/s about the normal: the
    resistance holds the centre from the start and the spin stops after
    k w0/(c_spin g sin(alpha)) = 1.2232 s (it was `rest` at 4e-7 s, still spinning)."""
    sc = Scene(k=K, M=1.0, mu=0.3, mu_k=MU_K, c_spin=C_SPIN, c_rr=C_RR, rim=5000.0)
    out = story(ALPHA, 1000.0, 0.0, 0.6, scene=sc, rtol=1e-10, horizon_time=5.0)
    t_spin = K * 0.6 / (C_SPIN * G * math.sin(ALPHA))
    assert round(t_spin, 4) == 1.2232
    assert [(e["kind"], e["t"]) for e in out["events"]] == [("rest", 0.0), ("spin_stop", t_spin)]
    assert out["fate"] == "rest" and out["fate_time"] == t_spin and out["fate_spin"] == 0.0
    # a horizon before the spin has stopped: still turning in place (rolling), part way down
    out = story(ALPHA, 1000.0, 0.0, 0.6, scene=sc, rtol=1e-10, horizon_time=1.0)
    assert out["fate"] == "rolling" and out["fate_time"] == 1.0
    assert out["fate_spin"] == pytest.approx(0.6 - C_SPIN * G * math.sin(ALPHA) / K, rel=1e-12)


#: Without spin friction: the effect set of tests/test_hybrid.py's BENCH scene (one compile).
NO_SPIN = dict(k=K, M=1.0, mu=0.3, mu_k=MU_K, c_rr=C_RR, rim=5000.0)


def test_without_spin_friction_a_ball_at_rest_spinning_is_spinning():
    """The resistance holds the centre, nothing stops the spin about the normal: the fate
    `spinning` (not `rest`), at the centre's stop, with the spin kept in `fate_spin` and the
    last rolling state's invariants those of the ball at rest (h = w, L_z = 0)."""
    sc = Scene(**NO_SPIN)
    out = story(ALPHA, 1000.0, 0.0, 0.6, scene=sc, rtol=1e-10, horizon_time=5.0)
    assert out["fate"] == "spinning" and out["fate_time"] == 0.0
    assert out["fate_spin"] == 0.6 and out["fate_speed"] == 0.0 and out["energy_lost"] == 0.0
    assert out["final_h"] == 0.6 and out["final_Lz"] == 0.0
    assert out["final_energy"] == pytest.approx(G * 1000.0 * math.cos(ALPHA) / (1 + K),
                                                rel=1e-12)  # fmt: skip
    # thrown radially: it slides, rolls, stops (the closed form of the first test), spinning
    u0, w0 = 2.0, 0.5
    out = story(ALPHA, 1000.0, 0.0, w0, u0=u0, slip_u=u0, scene=sc, rtol=1e-10,
                horizon_time=5.0)  # fmt: skip
    t1 = K * u0 / (G * ((1 + K) * MU_K - C_RR))
    t_rest = t1 + (1 + K) * (u0 - MU_K * G * t1) / (C_RR * G)
    assert [e["kind"] for e in out["events"]] == ["roll", "rest"]
    assert out["fate"] == "spinning" and out["fate_time"] == pytest.approx(t_rest, rel=1e-4)
    assert out["fate_spin"] == w0 and out["lost_spin_friction"] == 0.0  # v = 0: w is constant


# ------------------------------------------------ rolling resistance above kinetic friction
#: c_rr > mu_k: the couple of kinetic friction, mu_k N a, cannot spin the ball up against the
#: resistance's, c_rr N a: thrown without spin it slides without turning.
STRONG = dict(k=K, M=1.0, mu=0.5, mu_k=MU_K, c_rr=0.5, rim=5000.0)


@pytest.mark.parametrize("alpha", [ALPHA, 1.2])
def test_strong_rolling_resistance_a_thrown_ball_slides_to_rest_without_turning(alpha):
    """Thrown up the generatrix at u0 without spin (slip u0): (p1, p2) stays 0 (static rolling
    resistance), so the centre slides at the deceleration g (cos(alpha) + mu_k sin(alpha))
    (N = M g sin(alpha): v = 0) and stops, slip and speed together, after
    u0/(g (cos(alpha) + mu_k sin(alpha))) (1.01936 s on the flat), where the resistance and
    friction hold it (cot(alpha) <= c_rr, mu). All the energy but the height gained goes to
    sliding friction. It crept to `failed` after 10^7 steps (the couple flipped at p = 0)."""
    sc = Scene(**STRONG)
    u0 = 2.0
    s, c = math.sin(alpha), math.cos(alpha)
    out = story(alpha, 10.0, 0.0, 0.0, u0=u0, slip_u=u0, scene=sc, rtol=1e-10, horizon_time=5.0)
    t = u0 / (G * (c + MU_K * s))
    if alpha == ALPHA:
        assert round(t, 5) == 1.01936
    assert [e["kind"] for e in out["events"]] == ["roll", "rest"]
    # to the stop thresholds (10 rtol of the speed scale, 2 m/s) over the deceleration
    assert out["fate"] == "rest" and out["fate_time"] == pytest.approx(t, rel=2e-9)
    assert out["fate_r"] == pytest.approx(10.0 + u0 * t / 2, rel=1e-9)
    # the slide ends where the slip falls to the threshold, v_rest / decel ~ 1.4 ns before
    assert t - 3e-9 < out["slide_time"] <= t and out["n_steps"] < 200
    height = G * c * u0 * t / 2
    assert out["lost_sliding_friction"] == pytest.approx(u0**2 / 2 - height, rel=1e-8)
    assert out["lost_effects"] == pytest.approx(0.0, abs=1e-12)


def test_strong_rolling_resistance_a_ball_released_at_rest_slides_to_the_vertex():
    """Released at rest on alpha = 1.2 with mu = 0.3 < cot(alpha): friction cannot hold it, it
    slips at once, and with c_rr = 0.5 > mu_k it slides down without turning at
    g (cos(alpha) - mu_k sin(alpha)), reaching the vertex region (r = a/100) at 0.7611 s."""
    sc = Scene(**{**STRONG, "mu": 0.3})
    alpha, r0 = 1.2, 0.5
    out = story(alpha, r0, 0.0, 0.0, scene=sc, rtol=1e-10, horizon_time=5.0)
    acc = G * (math.cos(alpha) - MU_K * math.sin(alpha))
    t = math.sqrt(2 * (r0 - sc.a / 100) / acc)
    assert round(t, 4) == 0.7611
    assert [(e["kind"], e["t"]) for e in out["events"]] == [
        ("slip", 0.0),
        ("vertex", out["fate_time"]),
    ]
    assert out["fate"] == "vertex" and out["fate_time"] == pytest.approx(t, rel=1e-9)
    assert out["events"][-1]["state"]["p2"] == 0.0 and out["events"][-1]["state"]["p1"] == 0.0


# ----------------------------------------------------------- a straight-line stop's time
@pytest.mark.parametrize("rtol", [1e-8, 1e-9, 1e-10])
def test_a_straight_line_stop_is_located_to_the_tolerance(rtol):
    """Rolling up the generatrix (v = w = 0) the deceleration is constant,
    g (cos(alpha) + c_rr sin(alpha))/(1+k): it stops at u0 (1+k)/(g (cos + c_rr sin)), found to
    a few rtol (it was 187 to 440 rtol late: steps carried the ball through the stop, where
    the resistance turns, and the stop was located on them). With spin friction, so the story
    runs on the hybrid steps (the effect set of the tests above)."""
    sc = Scene(mu=5.0, mu_k=4.0, c_rr=0.5, c_spin=1e-3, rim=10.0)
    alpha, u0 = 1.3, 1.0
    out = story(alpha, 0.5, 0.0, 0.0, u0=u0, scene=sc, horizon_time=20.0, rtol=rtol)
    t = u0 * (1 + K) / (G * (math.cos(alpha) + 0.5 * math.sin(alpha)))
    assert out["fate"] == "rest" and [e["kind"] for e in out["events"]] == ["rest"]
    assert abs(out["fate_time"] - t) <= 3 * rtol * t
    assert out["fate_r"] == pytest.approx(0.5 + u0 * t / 2, rel=3 * rtol)

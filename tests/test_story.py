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
    assert out["lost_rolling_resistance"] == pytest.approx(u0**2 / 2 - lost_slide, rel=1e-4)
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

"""The engine's hybrid stories against an independent rigid-body model (tests/hybrid_oracle.py:
Cartesian Newton-Euler with the contact constraint and Coulomb friction, scipy DOP853 at rtol
1e-12): the mode changes (kind, time, place), the fate, the energy lost and the invariants of
the last rolling orbit, on narrow and wide cones, thrown and rolling launches, both spin signs,
spin friction's stop and release (the spin stick) included."""

import math

import numpy as np
import pytest
from hybrid_oracle import Oracle, polar, start_state

from engine.scene import Scene
from engine.story import story

A = 0.01
HORIZON = 0.5
ALPHAS = (0.25, 0.6, 1.0, 1.35)
#: label -> (scene keywords, r0, u0, v0, w0, slip_u, slip_v)
LAUNCHES = {
    "thrown out, spin +": (dict(mu=0.6, mu_k=0.5), 0.3, 1.0, 0.5, 1.0, 1.0, 0.5),
    "thrown in, spin -": (dict(mu=0.6, mu_k=0.5), 0.4, -1.0, 0.7, -1.0, -1.0, 0.7),
    "backspin": (dict(mu=0.6, mu_k=0.5), 0.3, 1.0, 0.6, 0.5, 2.5, 0.0),
    "rolling, slips at once, spin +": (dict(mu=0.05, mu_k=0.04), 0.2, 0.0, 0.9, 1.5, 0.0, 0.0),
    "rolling, slips, spin -": (dict(mu=0.05, mu_k=0.04), 0.2, 0.0, 0.9, -1.5, 0.0, 0.0),
    "spin friction, spin +": (dict(mu=0.6, mu_k=0.5, c_spin=0.01), 0.3, 0.5, 0.8, 4.0, 0.5, 0.0),
    "spin friction, spin -": (dict(mu=0.6, mu_k=0.5, c_spin=0.01), 0.3, 0.5, 0.8, -4.0, 0.5,
                              0.0),
    "spin stick, spin +": (dict(mu=0.6, mu_k=0.5, c_spin=0.2), 0.3, 0.5, 0.8, 0.3, 0.5, 0.0),
    "spin stick, spin -": (dict(mu=0.6, mu_k=0.5, c_spin=0.2), 0.3, 0.5, 0.8, -0.3, 0.5, 0.0),
}  # fmt: skip
#: Shorter horizons where the story is told by then (the oracle's Python right-hand side is
#: the test's cost): on the narrow cone the spin stops, sticks and is released by 0.2 s, on
#: the wide one it stops and sticks by 0.1 s.
HORIZONS = {(al, f"spin stick, spin {sg}"): hz for al, hz in ((0.25, 0.2), (1.35, 0.1))
            for sg in "+-"}  # fmt: skip
COMMON = ("thrown out, spin +", "thrown in, spin -", "backspin", "rolling, slips at once, spin +")
#: (alpha, launch): every one changes mode at least once within the horizon; narrow (0.25) to
#: wide (1.35) cones. The spin-stick launches stop the spin (both signs); on the narrow cone it
#: is then released (spin_go), on the wide one it stays stuck.
SPIN_KINDS = {0.25: ["roll", "spin_stop", "spin_go"], 1.35: ["roll", "spin_stop"]}
CASES = (
    [(0.25, name) for name in COMMON + ("rolling, slips, spin -",)]
    + [(0.6, name) for name in COMMON + ("rolling, slips, spin -", "spin friction, spin -")]
    + [(al, name) for al in (1.0, 1.35) for name in COMMON + ("spin friction, spin +",
                                                              "spin friction, spin -")]
    + [(al, f"spin stick, spin {sg}") for al in SPIN_KINDS for sg in "+-"]
)  # fmt: skip


def test_enough_cases():
    assert len(CASES) >= 20


def _angle(a, b):
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


@pytest.mark.parametrize("case", CASES, ids=[f"{c[0]}-{c[1]}" for c in CASES])
def test_story_matches_the_rigid_body_model(case):
    alpha, name = case
    kw, r0, u0, v0, w0, su, sv = LAUNCHES[name]
    sc = Scene(M=1.0, a=A, k=0.4, rim=1.0, **kw)
    rim_centre = 1.0 - A / math.tan(alpha)
    horizon = HORIZONS.get(case, HORIZON)
    out = story(alpha, r0, v0, w0, u0=u0, slip_u=su, slip_v=sv, scene=sc, rtol=1e-11,
                horizon_time=horizon)  # fmt: skip
    mine = out["events"]
    if name.startswith("spin stick"):
        assert [e["kind"] for e in mine] == SPIN_KINDS[alpha]
    oracle = Oracle(alpha, 1.0, sc.g, A, 0.4, sc.mu, sc.mu_k, c_spin=sc.c_spin,
                    rim_centre=rim_centre)  # fmt: skip
    mode = "sliding" if (su, sv) != (0.0, 0.0) else "rolling"
    speed = max(abs(u0), abs(v0), abs(w0), abs(su), abs(sv))
    y0 = start_state(alpha, r0, u0, v0, w0, su, sv, A)
    ev, y_end, mode_end = oracle.run(y0, mode, horizon, speed)
    assert [e["kind"] for e in mine] == [e[0] for e in ev]
    assert len(ev) >= 1  # every case changes mode at least once
    for e, (kind, t, y) in zip(mine, ev, strict=True):
        r, th = polar(y, alpha)
        assert e["t"] == pytest.approx(t, rel=1e-7, abs=1e-9), kind
        assert e["state"]["r"] == pytest.approx(r, rel=1e-7), kind
        assert _angle(e["state"]["theta"], th) < 1e-7, kind
    # the energy lost by the end (the spin stop's remainder, k M w^2/2 at |w| = 10 rtol x the
    # speed scale, is ~1e-20 J): both integrations at rtol 1e-11..1e-12
    scale = 0.5 * speed**2 + sc.g * r0
    assert out["energy_lost"] == pytest.approx(oracle.energy(y0) - oracle.energy(y_end),
                                               abs=1e-8 * scale)  # fmt: skip
    fate = {"rolling": "rolling", "sliding": "sliding"}[mode_end]
    if ev[-1][0] == "spill":
        fate = "spilled"
    assert out["fate"] == fate
    rolls = [e for e in ev if e[0] == "roll"]
    if out["fate"] == "sliding" or not rolls and mode == "sliding":
        assert math.isnan(out["final_energy"])
    elif rolls:
        calE, h, Lz = oracle.invariants(rolls[-1][2])
        assert out["final_energy"] == pytest.approx(calE, abs=1e-8 * scale)
        assert out["final_h"] == pytest.approx(h, abs=1e-8 * speed)
        assert out["final_Lz"] == pytest.approx(Lz, abs=1e-8 * speed * r0)


def test_oracle_flat_limit():
    """The oracle itself on the textbook case (so a wrong oracle cannot agree with a wrong
    engine): thrown without spin on a nearly flat cone, it rolls after k u0/((1+k) mu_k g)."""
    al = math.pi / 2 - 1e-4
    o = Oracle(al, 1.0, 9.81, A, 0.4, 0.5, 0.25)
    ev, _, _ = o.run(start_state(al, 1000.0, 2.0, 0.0, 0.0, 2.0, 0.0, A), "sliding", 1.0, 2.0)
    assert [e[0] for e in ev] == ["roll"]
    assert ev[0][1] == pytest.approx(0.4 * 2.0 / (1.4 * 0.25 * 9.81), rel=1e-3)
    assert np.linalg.norm(ev[0][2][3:6]) == pytest.approx(2.0 / 1.4, rel=1e-3)

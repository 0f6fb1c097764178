"""Fate maps and trajectories that end (engine.fates, engine.kernels.fate, engine.simulate):
against an independent integration written here (scipy solve_ivp, rtol 1e-12, events), the
flat-cone stopping time, the work of the resistance along a trajectory, the c_rr -> 0 limit of
the closed form, and the closed form's slip onset."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import engine
from engine.kernels.fate import FATE_NAMES
from engine.kernels.geometry import CLASS_NAMES

M, G, K = 1.0, 9.81, 0.4
FATE = {name: i for i, name in enumerate(FATE_NAMES)}
CLS = {name: i for i, name in enumerate(CLASS_NAMES)}
BIG = 1e6  # a rim or mu that is never reached: one compiled effect set for every fate test


def _scipy_fate(alpha, energy, h, Lz, c_rr, rim, mu, a=0.01, t_max=50.0):
    """The same scene integrated by scipy from r_min (u = 0): (event name, t, r, theta). The
    equations and the forces are written here from docs/physics.md, not taken from engine."""
    s, c = math.sin(alpha), math.cos(alpha)
    kk = K / (1 + K)
    r1 = float(engine.evaluate(alpha, energy, h, Lz).r_min)
    v0 = Lz / (M * r1 * s)
    w0 = h + Lz * c / (M * r1 * s * s)
    r_rim = rim - a * c / s

    def forces(y):
        r, th, u, v, w = y
        kappa = c / (r * s)
        N = M * (G * s + v * v * kappa)
        F1 = kk * M * (G * c + kappa * v * w)
        speed = math.hypot(u, v)
        F1 -= c_rr * N * u / ((1 + K) * speed)
        F2 = -c_rr * N * v / ((1 + K) * speed)
        return math.hypot(F1, F2), N, speed

    def rhs(t, y):
        r, th, u, v, w = y
        kappa = c / (r * s)
        _, N, speed = forces(y)
        f = c_rr * N / (M * (1 + K) * speed)
        return [u, v / (r * s), v * v / r + kk * kappa * v * w - G * c / (1 + K) - f * u,
                -u * v / r - f * v, -kappa * u * v]  # fmt: skip

    def spill(t, y):
        return y[0] - r_rim

    def slip(t, y):
        F, N, _ = forces(y)
        return F - mu * N

    spill.terminal = slip.terminal = True
    spill.direction = slip.direction = 1
    if slip(0.0, [r1, 0.0, 1e-300, v0, w0]) > 0:
        return "slipped", 0.0, r1, 0.0
    sol = solve_ivp(rhs, (0.0, t_max), [r1, 0.0, 1e-300, v0, w0], method="DOP853", rtol=1e-12,
                    atol=1e-14, events=[spill, slip])  # fmt: skip
    for name, te, ye in (("spilled", *sol.t_events[0:1], *sol.y_events[0:1]),
                         ("slipped", *sol.t_events[1:2], *sol.y_events[1:2])):  # fmt: skip
        if len(te):
            return name, te[0], ye[0][0], ye[0][1]
    return "rolling", sol.t[-1], sol.y[0][-1], sol.y[1][-1]


def _fate(alpha, energy, h, Lz, scene, **kw):
    kw.setdefault("horizon_time", 50.0)
    ds = engine.evaluate(alpha, energy, h, Lz, scene=scene, method="rk45", rtol=1e-11, **kw)
    assert ds.attrs["map_kind"] == "fate"
    return ds


@pytest.mark.parametrize(
    "case",
    [
        dict(alpha=0.5, energy=20.0, h=1.0, Lz=0.8, c_rr=0.01, rim=3.13, mu=BIG),
        dict(alpha=1.1, energy=9.0, h=-2.0, Lz=1.2, c_rr=0.02, rim=BIG, mu=0.1),
        dict(alpha=0.9, energy=8.0, h=-3.0, Lz=0.6, c_rr=0.03, rim=1.5, mu=0.15),
    ],
)
def test_fate_time_and_place_match_an_independent_integration(case):
    scene = engine.Scene(M=M, g=G, k=K, c_rr=case["c_rr"], rim=case["rim"], mu=case["mu"])
    ds = _fate(case["alpha"], case["energy"], case["h"], case["Lz"], scene)
    name, t, r, th = _scipy_fate(**case)
    assert FATE_NAMES[int(ds.fate)] == name
    assert float(ds.fate_time) == pytest.approx(t, rel=1e-7)
    assert float(ds.fate_r) == pytest.approx(r, rel=1e-7)
    assert float(ds.fate_theta) == pytest.approx(th, rel=1e-7)
    assert float(ds.revolutions) == pytest.approx(abs(th) / (2 * math.pi), rel=1e-7)
    assert 0 < float(ds.energy_lost) and float(ds.invariant_drift) < 1e-8


def test_flat_cone_stopping_time():
    """alpha = pi/2 - 1e-3: the sphere launched at speed v0 stops after (1+k) v0 / (c_rr g)
    up to O(cot alpha), and stays at rest (cot alpha = 1e-3 <= c_rr)."""
    alpha = math.pi / 2 - 1e-3
    c_rr = 0.05
    scene = engine.Scene(M=M, g=G, k=K, c_rr=c_rr, rim=BIG, mu=BIG)
    h, Lz = 0.0, 2.0
    r0 = 3.0  # launch at r0 with v0 along the parallel (u0 = 0)
    s = math.sin(alpha)
    v0 = Lz / (M * r0 * s)
    inv = engine.invariants(alpha, r0, 0.0, v0, h + Lz * math.cos(alpha) / (M * r0 * s * s),
                            scene)  # fmt: skip
    ds = _fate(alpha, float(inv["energy"]), float(inv["h"]), float(inv["Lz"]), scene)
    assert float(ds.r_min) == pytest.approx(r0, rel=1e-6)  # the launch point is r_min
    assert FATE_NAMES[int(ds.fate)] == "rest"
    t0 = (1 + K) * v0 / (c_rr * G)
    assert float(ds.fate_time) == pytest.approx(t0, rel=5 / math.tan(alpha) + 1e-6)


def test_energy_lost_equals_the_work_of_the_resistance_along_the_trajectory():
    c_rr = 0.02
    scene = engine.Scene(M=M, g=G, k=K, c_rr=c_rr, rim=BIG, mu=BIG)
    alpha = 0.6
    tr = engine.simulate(alpha, 15.0, 1.0, 0.8, scene, t_end=4.0, dt_out=2e-4)
    s, c = math.sin(alpha), math.cos(alpha)
    r, u, v = tr.r.values, tr.u.values, tr.v.values
    power = c_rr * M * (G * s + v * v * c / (r * s)) * np.hypot(u, v)
    t = tr.time.values
    work = np.sum((power[1:] + power[:-1]) * np.diff(t)) / 2  # trapezoid, error ~ dt^2
    lost = -float(tr.E_drift[-1])
    assert lost > 0
    assert lost == pytest.approx(work, rel=1e-6)


def test_fate_map_tends_to_the_closed_form_as_c_rr_vanishes():
    """c_rr = 1e-13: a fate map over a small grid agrees with the exact classes of the same
    cone (rim, mu) and its end times: rolling <-> bounded, spilled <-> spills, slipped <->
    slips."""
    alpha = np.array([[0.4], [0.9]])
    energy = np.array([[4.0, 9.0, 25.0, 60.0]])
    h, Lz = 1.0, 0.8
    rim, mu = 3.0, 0.5
    exact = engine.evaluate(alpha, energy, h, Lz, scene=engine.Scene(rim=rim, mu=mu))
    scene = engine.Scene(rim=rim, mu=mu, c_rr=1e-13)
    fate = _fate(alpha, energy, h, Lz, scene, horizon_time=None, horizon_revolutions=30.0)
    pairs = {"bounded": "rolling", "spills": "spilled", "slips": "slipped", "forbidden": "no_orbit"}
    cls = exact.orbit_class.values
    seen = set()
    for i, j in np.ndindex(cls.shape):
        name = CLASS_NAMES[cls[i, j]]
        seen.add(name)
        assert FATE_NAMES[fate.fate.values[i, j]] == pairs[name], (i, j, name)
        if name in ("spills", "slips"):
            assert fate.fate_time.values[i, j] == pytest.approx(exact.end_time.values[i, j],
                                                                rel=1e-7)  # fmt: skip
            assert fate.fate_r.values[i, j] == pytest.approx(exact.end_r.values[i, j], rel=1e-7)
        elif name == "bounded":
            assert fate.revolutions.values[i, j] == pytest.approx(30.0, rel=1e-12)
    assert {"bounded", "spills", "slips"} <= seen, seen


def test_conservative_slip_onset_matches_the_closed_form():
    """A conservative scene with mu: the integrator's slip event is at the first radius where
    the exact |F|/N reaches mu, at the time of the radial quadrature."""
    alpha, h, Lz, mu = 0.5, 1.0, 0.8, 0.45
    vmin = float(engine.minimum_energy(alpha, h, Lz))
    energy = vmin + 1.5 * abs(vmin)
    scene = engine.Scene(mu=mu, rim=BIG)  # the rim is never reached (the compiled set of rim
    # tests is reused)
    exact = engine.evaluate(alpha, energy, h, Lz, scene=scene)
    assert int(exact.orbit_class) == CLS["slips"]
    tr = engine.simulate(alpha, energy, h, Lz, scene, t_end=10.0, rtol=1e-11)
    kinds = list(tr.event_kind.values)
    assert engine.kernels.protocol.EVENT_NAMES[kinds[-1]] == "slip"
    assert float(tr.event_r[-1]) == pytest.approx(float(exact.end_r), rel=1e-8)
    assert float(tr.event_time[-1]) == pytest.approx(float(exact.end_time), rel=1e-8)
    assert float(tr.event_theta[-1]) == pytest.approx(float(exact.end_theta), rel=1e-8)


def test_trajectories_end_they_do_not_crash():
    """The issue's reproduction: c_rr = 0.05 stopped the integration with a RuntimeError at
    35 s; now the trajectory ends with its reason."""
    scene = engine.Scene(c_rr=0.05, rim=BIG, mu=BIG)
    tr = engine.simulate(0.5, 20, 1, 0.8, scene, t_end=100)
    assert tr.attrs["status_message"].startswith("reached the vertex region")
    assert engine.kernels.protocol.EVENT_NAMES[int(tr.event_kind[-1])] == "vertex"
    assert float(tr.r[-1]) <= 0.01 * scene.a * (1 + 1e-9)
    # a failed integration returns what it computed, with a "failed" event
    short = engine.simulate(0.5, 20, 1, 0.8, scene, t_end=100, max_steps=50)
    assert short.attrs["status_message"] == "maximum number of steps reached"
    assert engine.kernels.protocol.EVENT_NAMES[int(short.event_kind[-1])] == "failed"
    assert short.sizes["time"] > 10


def test_refusals_and_horizons():
    with pytest.raises(ValueError, match="exact.*rolling_resistance.*rk45, dop853"):
        engine.evaluate(0.5, 20.0, 1.0, 0.8, scene=engine.Scene(c_rr=0.05))
    with pytest.raises(ValueError, match="exact.*attitude"):
        engine.evaluate(0.5, 20.0, 1.0, 0.8, scene=engine.Scene(attitude=True))
    with pytest.raises(ValueError, match="horizon"):
        engine.evaluate(0.5, 20.0, 1.0, 0.8, scene=engine.Scene(rim=3.0), method="rk45")
    with pytest.raises(ValueError, match="fate maps only"):
        engine.evaluate(0.5, 20.0, 1.0, 0.8, method="rk45", horizon_time=3.0)
    with pytest.raises(ValueError, match="horizon_time must be > 0"):
        engine.evaluate(0.5, 20.0, 1.0, 0.8, scene=engine.Scene(rim=3.0), method="rk45",
                        horizon_time=-1.0)  # fmt: skip


def test_fate_map_attributes_say_what_is_what():
    scene = engine.Scene(c_rr=0.01, rim=3.13, mu=BIG)
    ds = _fate(0.5, [20.0, -100.0], 1.0, 0.8, scene)
    assert "launch orbit" in ds.attrs["map_description"]
    assert ds.orbit_class.attrs["comment"].startswith("the launch orbit on the ideal")
    assert ds.fate.attrs["comment"] == "the scene, integrated"
    assert ds.fate.attrs["flag_meanings"].split() == list(FATE_NAMES)
    assert ds.fate.values[1] == FATE["no_orbit"] and np.isnan(ds.fate_time.values[1])
    assert ds.attrs["horizon_time"] == 50.0 and ds.attrs["horizon_revolutions"] == "none"

"""engine.story.story on a surface of revolution: the whole story (rolling, sliding, rolling
again, spin friction, rest, lift-off) of one launch on a bowl, a paraboloid, a funnel, held to
closed forms, to the cone's own story where the surface is a cone, and to the sliding
rigid-body model of tests/surface_slide_oracle.py.

Every story here has the effect set of tests/test_story.py's scenes (static and kinetic
friction, rolling resistance, spin friction, a rim): one compile of the surface's story kernel
serves them all."""

import math

import pytest

import engine
from engine.errortext import PlanError
from engine.scene import Scene
from engine.story import story
from engine.surfaces import Bowl, Cone, Cylinder, Funnel, Paraboloid

G = 9.81
K, MU_K, C_RR, C_SPIN = 0.4, 0.2, 0.1, 0.02


def _scene(**kw):
    base = dict(k=K, M=1.0, mu=0.3, mu_k=MU_K, c_spin=C_SPIN, c_rr=C_RR, rim=5000.0)
    return Scene(**{**base, **kw})


@pytest.mark.parametrize("w0", [0.0, 0.5])
def test_thrown_ball_on_a_nearly_flat_paraboloid(w0):
    """tests/test_story.py's flat-cone closed form on the paraboloid z = rho^2/(2R) with
    R = 10^6 m, thrown outward from rho = 1 m: the slope there, rho/R, stays below 5e-6 over
    the throw's ~4 m, so the slope's pull changes speeds by ~1e-4 of themselves at most over
    the story's 2.5 s: the closed form's tolerance. Thrown radially at u0 without spin (slip
    u0): the slip is gone at t1 = k u0/(g((1+k) mu_k - c_rr)), rolling on at V1 = u0 - mu_k g
    t1, at rest after (1+k) V1/(c_rr g) more (tan b <= c_rr: the resistance holds it); a
    spin w0 about the normal stops at k w0/(c_spin g) (N = M g cos b)."""
    u0 = 2.0
    out = story(surface=Paraboloid(1e6), rho0=1.0, v0=0.0, w0=w0, u0=u0, slip_u=u0,
                scene=_scene(), rtol=1e-10, horizon_time=5.0)  # fmt: skip
    t1 = K * u0 / (G * ((1 + K) * MU_K - C_RR))
    v1 = u0 - MU_K * G * t1
    t_rest = t1 + (1 + K) * v1 / (C_RR * G)
    kinds = [e["kind"] for e in out["events"]]
    assert kinds == (["roll", "spin_stop", "rest"] if w0 else ["roll", "rest"])
    roll = out["events"][0]
    assert roll["t"] == pytest.approx(t1, rel=1e-4)
    assert roll["state"]["u"] == pytest.approx(v1, rel=1e-4)
    assert out["fate"] == "rest" and out["fate_time"] == pytest.approx(t_rest, rel=1e-4)
    assert out["fate_speed"] == 0.0
    # where it stopped: the distance slid, then rolled (each a uniform deceleration)
    travel = (u0 + v1) / 2 * t1 + v1 / 2 * (t_rest - t1)
    assert out["fate_rho"] == pytest.approx(1.0 + travel, rel=1e-4)
    if w0:
        assert out["events"][1]["t"] == pytest.approx(K * w0 / (C_SPIN * G), rel=1e-5)
    lost_slide = MU_K * G * u0 * t1 / 2
    assert out["lost_sliding_friction"] == pytest.approx(lost_slide, rel=1e-4)
    assert out["lost_spin_friction"] == pytest.approx(K * w0**2 / 2, rel=1e-5, abs=1e-15)
    assert "final_h" not in out and "final_Lz" not in out


#: Launches on the cone alpha = 0.7 (rho0 = r0 sin(alpha): the centre's distance from the axis
#: on the centre's cone): (r0, v0, w0, u0, slip_u, slip_v).
CONE_LAUNCHES = [
    (0.6, 1.1, -0.8, 0.3, 0.9, 1.5),  # thrown with a slip: slides, rolls again, 17 events
    (0.8, 1.6, 2.0, 0.0, 0.0, 0.0),  # rolling beyond the friction limit: slips at once
    (1.0, 2.0, 1.0, 0.5, 0.5, 2.5),  # thrown along the parallel with a slip
]


@pytest.mark.parametrize("launch", CONE_LAUNCHES)
def test_a_cone_as_a_surface_tells_the_cones_story(launch):
    """The surface model's story on Cone(alpha) (its meridian, its frame, its rolling model)
    against the cone model's own story (closed-form coefficients, its frame): the same events
    in the same order at the same times, the same fate. Both at rtol 1e-11: event times agree
    to 1e-7 relative (each located to a step of the method's order within its tolerance;
    measured 1e-10). Launches that reach the vertex are not compared: the two models' inner
    ends differ (the cone's: the centre's slant below a/100; a surface's: the axis region)."""
    alpha = 0.7
    r0, v0, w0, u0, su, sv = launch
    sc = _scene(rim=3.0)
    kw = dict(u0=u0, slip_u=su, slip_v=sv, scene=sc, rtol=1e-11, horizon_time=4.0)
    cone = story(alpha, r0, v0, w0, **kw)
    surf = story(surface=Cone(alpha), rho0=r0 * math.sin(alpha), v0=v0, w0=w0, **kw)
    assert surf["fate"] == cone["fate"]
    assert [e["kind"] for e in surf["events"]] == [e["kind"] for e in cone["events"]]
    for a, b in zip(surf["events"], cone["events"], strict=True):
        assert a["t"] == pytest.approx(b["t"], rel=1e-7, abs=1e-9)
        assert a["state"]["rho"] == pytest.approx(b["state"]["r"] * math.sin(alpha), rel=1e-7)
        for name in ("u", "v", "p1", "p2", "w"):
            assert a["state"][name] == pytest.approx(b["state"][name], rel=1e-6, abs=1e-8)
    assert surf["fate_time"] == pytest.approx(cone["fate_time"], rel=1e-7)
    for name in ("lost_rolling_resistance", "lost_sliding_friction", "lost_spin_friction"):
        assert surf[name] == pytest.approx(cone[name], rel=1e-6, abs=1e-10)
    assert surf["invariant_drift"] < 1e-9


def test_surface_story_refusals():
    """Each bad launch is refused naming its field (a PlanError: exit 2 from the CLI)."""
    sc = _scene()
    hz = 1.0
    with pytest.raises(PlanError, match="alpha"):
        story(0.5, surface=Bowl(1.0), rho0=0.3, v0=0.1, w0=0.0, scene=sc, horizon_time=hz)
    with pytest.raises(PlanError, match="rho0"):
        story(surface=Bowl(1.0), v0=0.1, w0=0.0, scene=sc, horizon_time=hz)
    with pytest.raises(PlanError, match="z0"):
        story(surface=Bowl(1.0), z0=0.3, v0=0.1, w0=0.0, scene=sc, horizon_time=hz)
    with pytest.raises(PlanError, match="rho0"):
        story(surface=Cylinder(0.5), rho0=0.3, v0=0.1, w0=0.0, scene=sc, horizon_time=hz)
    with pytest.raises(PlanError, match="surface"):
        story(rho0=0.3, v0=0.1, w0=0.0, scene=sc, horizon_time=hz)
    with pytest.raises(PlanError, match="r0"):
        story(alpha=0.5, v0=0.1, w0=0.0, scene=sc, horizon_time=hz)
    with pytest.raises(PlanError, match="rho0.*not a place on the bowl"):
        story(surface=Bowl(1.0), rho0=2.0, v0=0.1, w0=0.0, scene=sc, horizon_time=hz)


def test_maps_and_trajectories_of_sliding_scenes_on_a_surface_are_refused_with_the_reason():
    """One launch's story is followed on a surface; its maps and its sampled trajectory are
    not built yet: refused, saying so, never run as if the ball rolled."""
    sc = _scene()
    with pytest.raises(ValueError, match="sliding maps: on a surface one launch's story"):
        engine.launch_survey(surface=Funnel(0.05, 0.03), rho0=[0.3], v0=[0.5], w0=[0.0],
                             scene=sc, method="dop853", horizon_time=1.0)  # fmt: skip
    with pytest.raises(ValueError, match="sliding maps"):
        engine.simulate(surface=Bowl(1.0), rho0=0.3, v0=0.5, w0=0.0, scene=sc, t_end=1.0,
                        method="dop853")  # fmt: skip

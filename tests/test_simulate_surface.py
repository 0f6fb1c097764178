"""engine.simulate on a surface of revolution (engine.simulate_surface): the trajectory against
closed forms and the exact map, and its refusals."""

import math

import numpy as np
import pytest

import engine
from engine.kernels.protocol import EVENT_NAMES
from engine.surfaces import Bowl, Cylinder, Funnel

SCENE = engine.Scene()


def test_the_cylinders_trajectory_oscillates_at_its_closed_form_rate():
    """Apsides of the height every pi / omega, omega = sqrt(k/(1+k)) v/rho (rho = R - a), and
    the azimuth swept between them pi / sqrt(k/(1+k)); the energy kept."""
    d = engine.simulate(surface=Cylinder(0.5), z0=0.0, v0=1.0, w0=0.3, scene=SCENE,
                        method="dop853", rtol=1e-11, periods=2)  # fmt: skip
    kk = SCENE.k / (1 + SCENE.k)
    omega = math.sqrt(kk) * 1.0 / (0.5 - SCENE.a)
    t = d.event_time.values[:4]
    np.testing.assert_allclose(np.diff(t), math.pi / omega, rtol=1e-9)
    th = d.event_theta.values[:4]
    np.testing.assert_allclose(np.abs(np.diff(th)), math.pi / math.sqrt(kk), rtol=1e-9)
    assert np.abs(d.E_drift.values).max() < 1e-8 * abs(d.attrs["E0"])
    np.testing.assert_allclose(d.rho.values, 0.5 - SCENE.a, rtol=1e-15)


def test_a_bowl_trajectory_meets_the_exact_map():
    """Turning points and period of a bowl orbit from its trajectory's apsides against Routh's
    reduction."""
    exact = engine.launch_survey(surface=Bowl(1.0), rho0=0.3, v0=1.0, w0=0.5, scene=SCENE)
    d = engine.simulate(surface=Bowl(1.0), rho0=0.3, v0=1.0, w0=0.5, scene=SCENE,
                        method="dop853", rtol=1e-11, periods=1)  # fmt: skip
    rho_ev = d.event_rho.values[:2]
    assert sorted(rho_ev) == pytest.approx(
        [float(exact.rho_min.values.ravel()[0]), float(exact.rho_max.values.ravel()[0])], rel=1e-9
    )
    assert d.event_time.values[1] == pytest.approx(float(exact.period.values.ravel()[0]), rel=1e-9)


def test_a_funnel_trajectory_ends_in_the_hole():
    scene = engine.Scene(rim=10.0)
    d = engine.simulate(surface=Funnel(0.05, 0.1), rho0=0.3, v0=0.3, w0=0.0, scene=scene,
                        method="dop853", rtol=1e-10, t_end=20.0)  # fmt: skip
    assert EVENT_NAMES[int(d.event_kind.values[-1])] == "vertex"
    assert d.rho.values[-1] < 0.1  # the centre, a sin(b) inside the hole's edge


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (
            dict(surface=Bowl(1.0), rho0=0.3, v0=1.0, w0=0.0, alpha=0.5),
            "alpha is the cone's orbit.*got 0.5",
        ),
        (dict(surface=Bowl(1.0), z0=0.3, v0=1.0, w0=0.0), "launch position is rho0"),
        (dict(surface=Bowl(1.0), rho0=0.3, v0=1.0), "w0 is needed"),
        (
            dict(surface=Bowl(1.0), rho0=0.3, v0=1.0, w0=0.0, method="symplectic"),
            "separable split",
        ),  # fmt: skip
        (dict(surface=Bowl(1.0), rho0=1.5, v0=1.0, w0=0.0), "not a place on the bowl"),
        (dict(rho0=0.3, v0=1.0, w0=0.0), "rho0 or z0 give a launch on a surface: name it"),
        (dict(surface="bowl", rho0=0.3, v0=1.0, w0=0.0), "must be a surface of engine.surfaces"),
    ],
)
def test_bad_surface_trajectories_are_refused(kwargs, words):
    with pytest.raises(ValueError, match=words):
        engine.simulate(scene=SCENE, t_end=1.0, **kwargs)


def test_a_trajectory_that_lifts_off_the_funnel_ends_there():
    """A nearly radial fall into a funnel: the run ends with the event ``liftoff`` and the
    status ``lifted_off`` where the normal force reaches zero, at the time the independent
    rigid-body model (tests/surface_oracle.py) finds (within 1e-8 relative at rtol 1e-11)."""
    from dataclasses import replace

    from surface_cases import BY_ID

    case = replace(BY_ID["funnel-1"], rho0=0.3, v0=0.05, w0=0.0)
    o = case.oracle()
    ref = o.run(o.launch(0.3, 0.05, 0.0), 10.0)
    assert ref.fate == "left_surface"
    scene = engine.Scene(M=case.M, g=case.g, a=case.a, k=case.k)
    d = engine.simulate(surface=Funnel(0.05, 0.02), rho0=0.3, v0=0.05, w0=0.0, scene=scene,
                        method="dop853", rtol=1e-11, t_end=10.0)  # fmt: skip
    assert EVENT_NAMES[int(d.event_kind.values[-1])] == "liftoff"
    assert d.attrs["status_message"].startswith("lifted off")
    assert float(d.event_time.values[-1]) == pytest.approx(ref.fate_time, rel=1e-8)
    assert float(d.time.values[-1]) == pytest.approx(ref.fate_time, rel=1e-8)

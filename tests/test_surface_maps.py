"""Integrated maps on surfaces of revolution (engine.surface_maps, the surface model through the
shared kernels), against closed forms the engine does not compute this way: the cone's closed
form through the general meridian, and the cylinder's harmonic height oscillation."""

import math

import numpy as np
import pytest

import engine
from engine.methods import METHODS
from engine.surface_maps import (
    surface_params,
    surface_period,
    surface_period_scalar,
    surface_points,
)
from engine.surfaces import Bowl, Cone, Cylinder, Funnel, Paraboloid

SCENE = engine.Scene(M=1.0, g=9.81, a=0.01, k=0.4)
RTOL = 1e-10


def _period(surface, position, v0, w0, method="dop853", scalar=False):
    n = len(position)
    s1, s2 = surface.shape
    X = surface_points(np.full(n, s1), np.full(n, s2), np.asarray(position, float),
                       np.asarray(v0, float), np.asarray(w0, float))  # fmt: skip
    run = surface_period_scalar if scalar else surface_period
    return run(X, surface_params(SCENE, surface), SCENE, METHODS[method], RTOL, 100_000)


@pytest.mark.parametrize("method", ["rk45", "dop853"])
def test_the_cone_through_the_general_meridian_is_the_cones_closed_form(method):
    """A launch at rho0 on Cone(alpha) (the centre's distance from the axis) is the cone's
    launch at r0 = rho0 / sin(alpha); period and apsidal angle within 100 rtol of the closed
    form (the integrators' stated accuracy, tests/cases.py)."""
    alpha = 0.7
    rho0 = np.array([0.3, 0.5, 0.8, 1.5])
    v0 = np.array([0.9, 1.0, 1.2, 2.5])
    w0 = np.array([0.0, 1.0, -2.0, 0.5])
    got = _period(Cone(alpha), rho0, v0, w0, method)
    assert np.all(got["status"] == 0)
    want = engine.launch_survey(alpha=[alpha], r0=rho0 / math.sin(alpha), v0=v0, w0=w0,
                                scene=SCENE)  # fmt: skip
    i = np.arange(rho0.size)
    for name in ("period", "apsidal_angle"):
        ref = want[name].values[0][i, i, i]  # launch i: (r0[i], v0[i], w0[i])
        np.testing.assert_allclose(got[name], ref, rtol=100 * RTOL)


def test_the_cylinders_height_oscillates_harmonically():
    """On a vertical cylinder (radius R, the centre at rho = R - a) the height obeys
    d2u/dt2 = -k' (v/rho)^2 u: a harmonic oscillation at omega = sqrt(k/(1+k)) v/rho whatever
    its amplitude, so the period is 2 pi / omega and the azimuth swept between a lowest and a
    highest point pi / sqrt(k/(1+k)) (docs/physics.md "Any surface of revolution")."""
    R = 0.5
    z0 = np.array([0.0, 0.3, -1.0])
    v0 = np.array([1.0, 2.0, 0.7])
    w0 = np.array([0.0, 3.0, -1.0])
    got = _period(Cylinder(R), z0, v0, w0)
    assert np.all(got["status"] == 0)
    kk = SCENE.k / (1 + SCENE.k)
    omega = math.sqrt(kk) * v0 / (R - SCENE.a)
    np.testing.assert_allclose(got["period"], 2 * math.pi / omega, rtol=100 * RTOL)
    np.testing.assert_allclose(got["apsidal_angle"], math.pi / math.sqrt(kk), rtol=100 * RTOL)


@pytest.mark.parametrize(
    "surface, rho0, v0",
    [(Paraboloid(1.0), 0.4, 1.3), (Bowl(1.0), 0.5, 1.0), (Funnel(0.1, 0.02), 0.25, 0.6)],
)
def test_energy_is_conserved_and_the_pairs_agree(surface, rho0, v0):
    """The rolling equations on a curved meridian conserve E (the drift at the integrators'
    tolerance), and rk45 and dop853 give the same period and apsidal angle."""
    a = _period(surface, [rho0], [v0], [0.7], "rk45")
    b = _period(surface, [rho0], [v0], [0.7], "dop853")
    assert a["status"][0] == 0 and b["status"][0] == 0
    assert a["energy_drift"][0] < 1e3 * RTOL and b["energy_drift"][0] < 1e3 * RTOL
    for name in ("period", "apsidal_angle"):
        assert a[name][0] == pytest.approx(b[name][0], rel=300 * RTOL)


def test_lanes_equal_one_orbit_per_thread_bit_for_bit():
    """The surface model on the SIMD lanes gives the scalar kernel's numbers bit for bit."""
    rng = np.random.default_rng(5)
    rho0 = rng.uniform(0.2, 0.8, 24)
    v0 = rng.uniform(0.5, 2.0, 24)
    w0 = rng.uniform(-2.0, 2.0, 24)
    lanes = _period(Bowl(1.0), rho0, v0, w0, "rk45")
    scalar = _period(Bowl(1.0), rho0, v0, w0, "rk45", scalar=True)
    for name, values in lanes.items():
        np.testing.assert_array_equal(values, scalar[name], err_msg=name)

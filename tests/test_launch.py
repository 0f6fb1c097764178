"""Launch states and invariants (engine.launch) against the plain statements of
tests/model_oracle.py, round trips, and errors."""

import math

import numpy as np
import pytest
from model_oracle import invariants as oracle_invariants
from model_oracle import state_from_invariants

import engine


def test_invariants_of_a_state():
    scene = engine.Scene(M=2.0, g=9.81, k=0.4)
    alpha, r, u, v, w = 0.7, 1.3, -0.4, 1.1, 0.25
    got = engine.invariants(alpha, r, u, v, w, scene)
    E, Lz, h = oracle_invariants(r, u, v, w, alpha, 2.0, 9.81, 0.4)
    assert float(got["E"]) == pytest.approx(E, rel=1e-15)
    assert float(got["Lz"]) == pytest.approx(Lz, rel=1e-15)
    assert float(got["h"]) == pytest.approx(h, rel=1e-14)
    calE = E / 1.4 - 0.4 / 2.8 * 2.0 * h * h
    assert float(got["energy"]) == pytest.approx(calE, rel=1e-14)


def test_launch_state_inverts_invariants_and_broadcasts():
    alpha = np.array([[0.3], [1.2]])
    r = np.array([0.5, 2.0, 4.0])
    u, v, w = 0.7, 1.5, -0.3
    inv = engine.invariants(alpha, r, u, v, w)
    assert inv["energy"].shape == (2, 3)
    back = engine.launch_state(alpha, inv["energy"], inv["h"], inv["Lz"], r)
    np.testing.assert_allclose(back["u"], u, rtol=1e-9)
    np.testing.assert_allclose(back["v"], v, rtol=1e-14)
    np.testing.assert_allclose(back["w"], w, rtol=1e-13)
    inward = engine.launch_state(0.3, inv["energy"][0, 0], inv["h"][0, 0], inv["Lz"][0, 0], 0.5,
                                 outward=False)  # fmt: skip
    assert float(inward["u"]) == pytest.approx(-u, rel=1e-9)
    # against the oracle's state on an orbit
    ref = state_from_invariants(0.5, float(inv["energy"][0, 0]), float(inv["h"][0, 0]),
                                float(inv["Lz"][0, 0]), 0.3, 1.0, 9.81, 0.4, True)  # fmt: skip
    np.testing.assert_allclose([float(inward["v"]), float(inward["w"])], ref[1:], rtol=1e-13)


def test_launch_state_where_the_orbit_does_not_reach():
    alpha, h, Lz = 0.6, 0.5, 0.8
    vmin = float(engine.minimum_energy(alpha, h, Lz))
    out = engine.launch_state(alpha, vmin + 0.1 * abs(vmin), h, Lz, [1e-3, 100.0])
    assert np.isnan(out["u"]).all()
    assert np.isfinite(out["v"]).all()


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(alpha=0.0), "alpha must lie in the open interval"),
        (dict(alpha=math.pi / 2), "alpha must lie in the open interval"),
        (dict(r=0.0), "r must be > 0"),
        (dict(u=math.nan), "u must be finite"),
        (dict(v="1.0"), "v must hold real numbers, not text"),
        (dict(w=True), "w must hold real numbers, not booleans"),
    ],
)
def test_bad_launch_inputs_name_the_argument(kwargs, match):
    args = dict(alpha=0.5, r=1.0, u=0.0, v=1.0, w=0.0) | kwargs
    with pytest.raises(ValueError, match=match):
        engine.invariants(**args)


def test_launch_survey_stores_the_invariants_and_starts_fates_at_the_launch():
    alpha, r0, v0, w0 = [0.5, 1.0], [0.6, 1.2], [2.5, 4.0], [0.0, 0.4]
    ds = engine.launch_survey(alpha, r0, v0, w0)
    assert ds.orbit_class.dims == ("alpha", "r0", "v0", "w0")
    assert ds.attrs["grid"].startswith("launch states")
    a, r, v, w = np.meshgrid(alpha, r0, v0, w0, indexing="ij")
    inv = engine.invariants(a, r, 0.0, v, w)
    for name in ("energy", "h", "Lz"):
        np.testing.assert_array_equal(ds[name].values, inv[name])
    ref = engine.evaluate(a, inv["energy"], inv["h"], inv["Lz"])
    np.testing.assert_array_equal(ds.orbit_class.values, ref.orbit_class.values)
    # fast launches start at their r_min (u = 0 there, moving out): the fate of the launch
    # equals the fate map over the same invariants, which starts at r_min
    scene = engine.Scene(c_rr=0.02, rim=2.5, mu=1e6)
    kw = dict(method="rk45", rtol=1e-10, horizon_time=20.0)
    fl = engine.launch_survey(alpha, r0, v0, w0, scene, **kw)
    fi = engine.evaluate(a, inv["energy"], inv["h"], inv["Lz"], scene=scene, **kw)
    at_rmin = np.isclose(fi.r_min.values, r, rtol=1e-9)
    assert at_rmin.sum() >= 4
    np.testing.assert_array_equal(fl.fate.values[at_rmin], fi.fate.values[at_rmin])
    np.testing.assert_allclose(fl.fate_time.values[at_rmin], fi.fate_time.values[at_rmin],
                               rtol=1e-7)  # fmt: skip

"""engine.evaluate / engine.survey: broadcasting, metadata, errors, agreement with the kernel."""

import math

import numpy as np
import pytest
import xarray as xr

import engine
from engine.kernels.geometry import ideal_orbit, scene_params
from engine.schema import result_variables

VARS = ("r_min", "r_max", "r_circ", "period", "apsidal_angle", "precession_rate", "mu_required")


def test_evaluate_broadcasts_like_numpy():
    ds = engine.evaluate(0.5, np.linspace(1, 40, 5), 1.0, [[0.5], [1.0]])
    assert ds.orbit_class.shape == (2, 5) and ds.orbit_class.dtype == np.int8
    assert ds.alpha.shape == (2, 5)
    for v in VARS:
        assert ds[v].dtype == np.float64 and "units" in ds[v].attrs and "long_name" in ds[v].attrs
    want = ideal_orbit(0.5, ds.energy.values[1, 3], 1.0, 1.0, scene_params(1.0, 9.81, 0.4), 1e-12)
    assert ds.period.values[1, 3] == want[4]


def test_evaluate_scalar_and_dataarray_inputs():
    ds = engine.evaluate(0.5, 10.0, 1.0, 1.0)
    assert ds.orbit_class.shape == ()
    e = xr.DataArray(np.linspace(5, 10, 3), dims="energy")
    lz = xr.DataArray([0.5, 1.0], dims="Lz")
    ds2 = engine.evaluate(0.5, e, 1.0, lz)
    assert ds2.orbit_class.dims == ("energy", "Lz")
    assert ds2.energy.dims == ("energy",) and ds2.Lz.dims == ("Lz",)
    assert ds2.sel(Lz=1.0).orbit_class.shape == (3,)  # 1-D inputs are index coordinates


def test_class_flags_follow_cf():
    ds = engine.evaluate(0.5, 10.0, 1.0, 1.0)
    a = ds.orbit_class.attrs
    assert a["flag_values"].dtype == np.int8
    assert list(a["flag_values"]) == list(range(9))
    assert a["flag_meanings"] == (
        "forbidden bounded circular hyperbolic radial spills slips off_cone out_of_range"
    )


@pytest.mark.parametrize(
    "kwargs,name",
    [
        (dict(alpha=0.0), "alpha"),
        (dict(alpha=math.pi / 2), "alpha"),
        (dict(alpha=-0.2), "alpha"),
        (dict(energy=math.nan), "energy"),
        (dict(h=math.inf), "h"),
        (dict(Lz=[1.0, math.nan]), "Lz"),
    ],
)
def test_bad_inputs_name_the_argument(kwargs, name):
    args = dict(alpha=0.5, energy=10.0, h=1.0, Lz=1.0)
    args.update(kwargs)
    with pytest.raises(ValueError, match=rf"^{name} must"):
        engine.evaluate(**args)


def test_bad_method_and_tolerance():
    with pytest.raises(ValueError, match="method"):
        engine.evaluate(0.5, 10.0, 1.0, 1.0, method="euler")
    with pytest.raises(ValueError, match="circular_tol"):
        engine.evaluate(0.5, 10.0, 1.0, 1.0, circular_tol=-1.0)


def test_survey_outer_product_matches_evaluate():
    a, e, h, lz = [0.3, 0.9], [-1.0, 5.0, 30.0], [-1.0, 0.0, 2.0], [0.0, 0.4, 1.1]
    calls = []
    ds = engine.survey(a, e, h, lz, progress=lambda d, t: calls.append((d, t)), chunk_points=7)
    assert ds.orbit_class.dims == ("alpha", "energy", "h", "Lz")
    assert ds.orbit_class.shape == (2, 3, 3, 3)
    assert calls[-1] == (54, 54)
    A, E, H, L = np.meshgrid(a, e, h, lz, indexing="ij")
    pts = engine.evaluate(A, E, H, L)
    for v in ("orbit_class", *VARS):
        got = ds[v].broadcast_like(ds.orbit_class).transpose(*ds.orbit_class.dims).values
        if v == "r_circ":  # the family's, on (alpha, h, Lz): each point's where it has one
            assert ds.r_circ.dims == ("alpha", "h", "Lz")
            got = np.where(np.isnan(pts.r_circ.values), np.nan, got)
        np.testing.assert_array_equal(got, pts[v].values)
    for name in ("alpha", "energy", "h", "Lz"):
        assert "units" in ds[name].attrs


def test_survey_energy_relative_to_minimum():
    a, off, h, lz = [0.4, 1.0], [0.0, 1e-6, 1.0], [-1.0, 1.0], [0.5]
    ds = engine.survey(a, off, h, lz, energy_relative=True)
    assert ds.energy.attrs["units"] == "1"
    cls = ds.orbit_class.values
    assert (cls[:, 0] == 2).all()  # offset 0: circular
    assert (cls[:, 1:] == 1).all()
    vmin = engine.minimum_energy(0.4, -1.0, 0.5)
    # V_min is stored once per (alpha, h, Lz); the absolute energy is the accessor's
    assert ds.V_min.dims == ("alpha", "h", "Lz") and "energy_absolute" not in ds
    assert ds.V_min.values[0, 0, 0] == vmin and ds.r_circ.dims == ("alpha", "h", "Lz")
    assert ds.cone.energy_absolute().values[0, 2, 0, 0] == vmin + 1.0 * abs(vmin)


def test_survey_relative_energy_undefined_without_minimum():
    # free fall with B >= 0 (h Lz > 0): V has no minimum
    ds = engine.survey([0.5], [0.5], [1.0], [1.0], engine.Scene(g=0.0), energy_relative=True)
    assert ds.orbit_class.values.item() == 0 and np.isnan(ds.cone.energy_absolute()).all()


def test_minimum_energy_is_the_potential_minimum():
    vmin = engine.minimum_energy(0.7, 1.0, 0.8)
    ds = engine.evaluate(0.7, vmin * (1 - 1e-9) if vmin > 0 else vmin * (1 + 1e-9), 1.0, 0.8)
    assert int(ds.orbit_class) == 0


def test_radial_energy_conversion():
    s = engine.Scene(M=2.0, k=0.4)
    assert engine.radial_energy(14.0, 1.0, s) == pytest.approx(14.0 / 1.4 - 0.4 / 2.8 * 2.0)


def test_simulate_is_the_function_even_after_importing_its_module():
    import engine.simulate  # noqa: F401  (binds the submodule on first import)

    assert callable(engine.simulate) and engine.simulate.__name__ == "simulate"


def test_integrator_method_outputs_and_status_flags():
    ds = engine.evaluate(0.6, [0.5, 20.0], 1.0, 0.8, method="rk45", rtol=1e-10)
    exact = engine.evaluate(0.6, [0.5, 20.0], 1.0, 0.8)
    assert list(ds.orbit_class.values) == [0, 1]
    assert ds.status.attrs["flag_values"].dtype == np.int8
    assert ds.status.attrs["flag_meanings"].split()[0] == "ok"
    assert ds.status.values[1] == 0 and ds.n_steps.values[1] > 0
    assert np.isnan(ds.period.values[0])  # forbidden: not integrated, and the status says so
    assert ds.status.attrs["flag_meanings"].split()[ds.status.values[0]] == "not_bounded"
    assert ds.apsidal_angle.values[1] == pytest.approx(exact.apsidal_angle.values[1], rel=1e-8)


def test_evaluate_orders_variables_as_a_survey_file_does():
    """evaluate's Dataset lists its variables in the order a survey file stores them."""
    scene = engine.Scene(rim=3.0, mu=0.5)
    ds = engine.evaluate(0.6, 20.0, 1.0, 0.8, scene=scene)
    assert list(ds.data_vars) == list(result_variables("exact", scene))

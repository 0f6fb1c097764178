"""engine.accessor: the ``ds.cone`` helpers on survey and evaluate results."""

import math

import matplotlib
import numpy as np
import pytest
import xarray as xr

import engine
import engine.accessor  # noqa: F401  (registers ds.cone)
from engine.kernels.geometry import CLASS_NAMES

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def grid() -> xr.Dataset:
    """Gravity survey with forbidden (L_z = 0), bounded and circular points, and a rim."""
    return engine.survey(
        alpha=np.radians([20.0, 30.0, 45.0]),
        energy=np.array([0.0, 1e-3, 0.1, 1.0, 10.0]),
        h=np.array([-1.0, 0.0, 2.0]),
        Lz=np.array([0.0, 0.5, 1.0, 2.0]),
        scene=engine.Scene(rim=3.0),
        energy_relative=True,
    )


@pytest.fixture(scope="module")
def free_fall() -> xr.Dataset:
    """Free-fall map over (energy, h): forbidden, bounded and hyperbolic points."""
    e = xr.DataArray(np.linspace(-1.0, 1.0, 21), dims="energy")
    h = xr.DataArray(np.linspace(-10.0, 10.0, 11), dims="h")
    return engine.evaluate(0.5, e, h, 1.0, engine.Scene(g=0.0))


def test_class_names_come_from_flag_meanings(grid):
    assert grid.cone.class_names == CLASS_NAMES
    ds = grid.copy()
    ds["orbit_class"] = ds.orbit_class.copy()
    ds.orbit_class.attrs["flag_meanings"] = "a b c d e f g h i"
    assert ds.cone.class_names == tuple("abcdefghi")
    assert ds.cone.class_fractions().class_name.values.tolist() == list("abcdefghi")


def test_class_fractions_sum_to_one_and_match_bincount(grid):
    frac = grid.cone.class_fractions()
    assert frac.dims == ("class_name",)
    assert frac.sum().item() == pytest.approx(1.0, abs=1e-15)
    counts = np.bincount(grid.orbit_class.values.ravel(), minlength=len(CLASS_NAMES))
    np.testing.assert_allclose(frac.values, counts / grid.orbit_class.size, rtol=0, atol=0)
    # The grid exercises several classes, not just one.
    assert (counts > 0).sum() >= 3


def test_class_fractions_along_dims(grid):
    frac = grid.cone.class_fractions(dim=["energy", "h", "Lz"])
    assert set(frac.dims) == {"class_name", "alpha"}
    np.testing.assert_allclose(frac.sum("class_name").values, 1.0, rtol=0, atol=1e-15)
    for i in range(grid.sizes["alpha"]):
        sub = grid.orbit_class.isel(alpha=i).values.ravel()
        want = np.bincount(sub, minlength=len(CLASS_NAMES)) / sub.size
        np.testing.assert_array_equal(frac.isel(alpha=i).values, want)


def test_where_class_keeps_exactly_the_class_points(grid):
    b = grid.cone.where_class("bounded")
    code = grid.cone.class_codes["bounded"]
    keep = grid.orbit_class.values == code
    assert keep.any() and not keep.all()
    np.testing.assert_array_equal(np.isfinite(b.orbit_class.values), keep)
    np.testing.assert_array_equal(b.orbit_class.values[keep], code)
    np.testing.assert_array_equal(b.period.values[keep], grid.period.values[keep])
    assert np.isnan(b.period.values[~keep]).all()
    assert b.orbit_class.attrs["flag_meanings"] == grid.orbit_class.attrs["flag_meanings"]
    # Fractions of the masked Dataset count only the kept points.
    assert b.cone.class_fractions().sel(class_name="bounded").item() == 1.0


def test_where_class_several_classes_and_drop(grid):
    two = grid.cone.where_class("bounded", "spills")
    want = np.isin(grid.orbit_class.values, [1, 5])
    np.testing.assert_array_equal(np.isfinite(two.orbit_class.values), want)
    dropped = grid.cone.where_class("forbidden", drop=True)
    # Only L_z = 0 is forbidden here (energy offsets >= 0 from V_min).
    assert dropped.sizes["Lz"] == 1 and dropped.Lz.item() == 0.0
    with pytest.raises(ValueError, match="unknown class"):
        grid.cone.where_class("elliptic")


def test_precession_per_revolution_degrees_and_radians(grid):
    rad = grid.cone.precession_per_revolution(units="radian")
    deg = grid.cone.precession_per_revolution()
    assert rad.attrs["units"] == "radian" and deg.attrs["units"] == "degree"
    np.testing.assert_allclose(deg.values, rad.values * 180.0 / math.pi, rtol=1e-15)
    ok = np.isin(grid.orbit_class.values, [1, 2, 5])
    np.testing.assert_array_equal(np.isfinite(rad.values), ok)
    np.testing.assert_allclose(
        rad.values[ok], 2.0 * grid.apsidal_angle.values[ok] - 2.0 * math.pi, rtol=0, atol=0
    )
    # Consistent with the engine's rate: per revolution = rate * T_r.
    np.testing.assert_allclose(
        rad.values[ok], (grid.precession_rate * grid.period).values[ok], rtol=1e-12
    )
    with pytest.raises(ValueError, match="units"):
        grid.cone.precession_per_revolution(units="grad")


def test_precession_masks_hyperbolic_sweeps(free_fall):
    cls = free_fall.orbit_class.values
    assert (cls == 3).any() and (cls == 1).any()
    deg = free_fall.cone.precession_per_revolution().values
    assert np.isnan(deg[cls == 3]).all()
    # Free fall: psi = pi/Omega for every bounded orbit.
    omega = math.sqrt((math.sin(0.5) ** 2 + 0.4) / 1.4)
    np.testing.assert_allclose(deg[cls == 1], (2 * math.pi / omega - 2 * math.pi) * 180 / math.pi)


def test_fractions_after_netcdf_round_trip(grid, tmp_path):
    path = tmp_path / "grid.nc"
    grid.to_netcdf(path)
    with xr.open_dataset(path) as back:
        np.testing.assert_array_equal(
            back.cone.class_fractions().values, grid.cone.class_fractions().values
        )
        assert back.cone.class_codes == {n: i for i, n in enumerate(CLASS_NAMES)}


def test_class_map_writes_png(grid, free_fall, tmp_path):
    import matplotlib.pyplot as plt

    ax = grid.cone.class_map(x="Lz", y="energy", alpha=math.radians(30), h=2.0)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert set(labels) <= set(CLASS_NAMES) and "bounded" in labels
    assert "Lz [kg m2 s-1]" == ax.get_xlabel()
    out = tmp_path / "map.png"
    ax.figure.savefig(out, dpi=60)
    plt.close(ax.figure)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 1000

    fig, ax2 = plt.subplots()
    assert free_fall.cone.class_map(x="h", y="energy", ax=ax2) is ax2
    labels = {t.get_text() for t in ax2.get_legend().get_texts()}
    assert labels == {"forbidden", "bounded", "hyperbolic"}
    fig.savefig(tmp_path / "ff.png", dpi=60)
    plt.close(fig)
    with pytest.raises(ValueError, match="2-D"):
        grid.cone.class_map(x="Lz", y="energy")


def test_summary_mentions_classes_and_method(grid):
    text = grid.cone.summary()
    assert "method exact" in text and "bounded" in text and "forbidden" in text
    assert len(text.splitlines()) <= 6


def test_class_fractions_of_any_flag_variable_over_a_dim():
    """``class_fractions("fate", dim=...)``: the share of each fate along the other axes,
    counted here with numpy from the fate codes; an axis given first is still a dim."""
    ds = engine.launch_survey(
        alpha=[0.6, 1.5], r0=np.linspace(0.5, 2.5, 4), v0=np.linspace(0.2, 6.0, 5), w0=0.0,
        scene=engine.Scene(c_rr=0.1, rim=3.0, mu=0.5), method="rk45", horizon_time=20.0,
    )  # fmt: skip
    frac = ds.cone.class_fractions("fate", dim=["r0", "v0", "w0"])
    names = ds.fate.attrs["flag_meanings"].split()
    codes = np.atleast_1d(ds.fate.attrs["flag_values"])
    assert frac.class_name.values.tolist() == names and frac.dims == ("class_name", "alpha")
    for a in range(2):
        f = ds.fate.isel(alpha=a).values.ravel()
        for name, code in zip(names, codes, strict=True):
            assert frac.sel(class_name=name).isel(alpha=a).item() == (f == code).sum() / f.size
    assert len(set(ds.fate.values.ravel().tolist())) >= 2  # more than one fate is counted
    counts = ds.cone.class_counts("fate")
    assert int(counts.sum()) == ds.fate.size
    by_alpha = ds.cone.class_fractions("alpha")  # the older call: the first argument a dim
    assert by_alpha.dims == ("class_name", "r0", "v0", "w0")
    with pytest.raises(ValueError, match="not a flag variable"):
        ds.cone.class_fractions("fate_time")

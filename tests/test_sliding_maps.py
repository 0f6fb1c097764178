"""Survey maps of the sliding model (``Scene.mu_k``): the API's ``survey`` and ``launch_survey``
on a scene where a slip is a transition. The scenes and horizons are those of
tests/test_hybrid.py (each effect set is one compile of the hybrid kernels: keep them few)."""

import math
import os
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import engine
from engine import cli
from engine.scene import Scene
from engine.story import launch_fates, story

FLAT = math.pi / 2 - 1e-4
G = 9.81
ROLLING = Scene(mu=50.0, rim=1.0)
NEVER_SLIPS = Scene(mu=50.0, mu_k=0.3, rim=1.0)
#: The variables a rolling fate map and a sliding one share (closed form and fate).
SHARED = ("orbit_class", "r_min", "r_max", "r_circ", "period", "apsidal_angle",
          "precession_rate", "mu_required", "fate", "fate_time", "fate_r", "fate_theta",
          "revolutions", "energy_lost", "invariant_drift", "n_steps")  # fmt: skip
LOSSES = ("lost_effects", "lost_sliding_friction", "lost_spin_friction")


def test_a_scene_that_never_slips_maps_as_today_bit_for_bit():
    """mu large enough never to slip: the sliding map's fate and shared variables equal the
    rolling fate map's, on a grid of invariants (each orbit starts at r_min) and of launches."""
    kw = dict(method="dop853", horizon_time=1.5)
    axes = ([0.4, 1.1], [0.05, 0.3], [-1.0, 0.5], [0.002, 0.01])
    today = engine.survey(*axes, scene=ROLLING, **kw)
    mine = engine.survey(*axes, scene=NEVER_SLIPS, **kw)
    assert mine.attrs["map_kind"] == "sliding fate" and today.attrs["map_kind"] == "fate"
    fates = today.cone.flag_counts("fate")
    assert fates["rolling"] + fates["spilled"] + fates["vertex"] > 0, fates  # orbits were run
    for name in SHARED:
        np.testing.assert_array_equal(mine[name].values, today[name].values, err_msg=name)
    has_orbit = today["fate"].values != 0
    assert (mine["slip_episodes"].values[has_orbit] == 0).all()
    assert (mine["slide_time"].values[has_orbit] == 0.0).all()
    launches = ([0.5, 1.2], [0.1, 0.4], [0.3, 1.2], [-1.0, 0.5])
    today = engine.launch_survey(*launches, scene=ROLLING, **kw)
    mine = engine.launch_survey(*launches, scene=NEVER_SLIPS, **kw)
    assert mine["fate"].dims == today["fate"].dims == ("alpha", "r0", "v0", "w0")
    for name in (*SHARED, "energy", "h", "Lz"):
        np.testing.assert_array_equal(mine[name].values, today[name].values, err_msg=name)
    # rolling from the launch and never slipping: the last rolling orbit is the launch's own
    for name, inv in (("final_energy", "energy"), ("final_h", "h"), ("final_Lz", "Lz")):
        np.testing.assert_array_equal(mine[name].values, mine[inv].values, err_msg=name)


def test_without_mu_k_a_slip_stays_an_end():
    low = Scene(mu=0.05, rim=1.0)
    ds = engine.launch_survey([0.5, 1.2], [0.1, 0.4], [0.3, 1.2], [-1.0, 0.5], scene=low,
                              method="dop853", horizon_time=1.5)  # fmt: skip
    assert ds["fate"].dims == ("alpha", "r0", "v0", "w0")
    assert ds.attrs["map_kind"] == "fate"
    assert ds["fate"].attrs["flag_meanings"].split() == list(engine.FATE_NAMES)
    assert ds.cone.flag_counts("fate")["slipped"] > 0
    assert "slide_time" not in ds and "u0" not in ds.coords


@pytest.mark.parametrize(
    "kw, name",
    [(dict(u0=0.5), "u0"), (dict(slip_u=[0.0, 1.0]), "slip_u"), (dict(slip_v=-0.2), "slip_v")],
)
def test_a_launch_that_is_not_rolling_needs_mu_k(kw, name):
    with pytest.raises(ValueError, match=rf"^{name} must be 0 without Scene\.mu_k: .*; got "):
        engine.launch_survey([0.5], [0.3], [1.0], [0.0], scene=ROLLING, method="dop853",
                             horizon_time=1.0, **kw)  # fmt: skip


@pytest.mark.parametrize("method", ["exact", "symplectic"])
def test_closed_form_and_symplectic_refuse_the_sliding_model_with_their_reason(method):
    reason = dict(engine.methods.get_method(method).lacks)["sliding contact"]
    with pytest.raises(ValueError, match=rf"{method}.*sliding.*{reason[:30]}"):
        engine.launch_survey([0.5], [0.3], [1.0], [0.0], scene=NEVER_SLIPS, method=method)
    with pytest.raises(ValueError, match=rf"{method}.*sliding"):
        engine.survey([0.5], [0.1], [0.0], [0.01], scene=NEVER_SLIPS, method=method)


def test_flat_limit_slide_time_over_a_speed_and_backspin_grid():
    """On a nearly flat cone far from the vertex a ball released with slip s along the
    generatrix slides for k s / ((1+k) mu_k g) (solid sphere k = 0.4) whatever its speed: the
    map's slide_time over u0 x slip_u, within O(cot alpha)."""
    sc = Scene(k=0.4, mu=0.5, mu_k=0.25, rim=5000.0)
    u0, slip = np.array([1.0, 2.0]), np.array([2.0, 3.0, 6.0])
    ds = engine.launch_survey(FLAT, 1000.0, 0.0, 0.0, scene=sc, method="dop853",
                              horizon_time=2.0, u0=u0, slip_u=slip)  # fmt: skip
    assert ds["slide_time"].dims == ("alpha", "r0", "v0", "w0", "u0", "slip_u")
    t = ds["slide_time"].values[0, 0, 0, 0, :, :]
    expected = 0.4 * slip / (1.4 * 0.25 * G)
    np.testing.assert_allclose(t, np.broadcast_to(expected, t.shape), rtol=1e-3)
    assert (ds["slip_episodes"].values == 1).all()
    # rolling speed after the slide: (u0 - k a omega0)/(1+k), a omega0 = slip_u - u0 (backspin),
    # changed by the slope's pull g cot(alpha) over the 2 s to the horizon
    speed = np.abs(u0[:, None] - 0.4 * (slip[None, :] - u0[:, None])) / 1.4
    rolling = ds["fate"].values[0, 0, 0, 0, :, :] == engine.FATE_NAMES.index("rolling")
    np.testing.assert_allclose(ds["fate_speed"].values[0, 0, 0, 0, :, :][rolling],
                               speed[rolling], atol=G * 2.0 / math.tan(FLAT))  # fmt: skip


def test_sliding_launch_map_invariants_and_wiring():
    """A launch map over u0 and slip_u (and a slip_v) with every loss: each point equals the
    launch's own story (engine.story.launch_fates: the axes wired in order); slide_time >= 0;
    slip_episodes >= 0 where there is an orbit; final_* NaN iff the last mode is sliding; the
    three losses add up to the energy lost."""
    sc = Scene(mu=0.3, mu_k=0.2, c_spin=0.02, c_rr=0.01, rim=1.0)
    axes = dict(alpha=[0.5, 1.3], r0=[0.2], v0=[0.4, -1.0], w0=[0.5], u0=[-0.5, 0.0, 0.8],
                slip_u=[0.0, 1.5], slip_v=[0.3])  # fmt: skip
    ds = engine.launch_survey(axes["alpha"], axes["r0"], axes["v0"], axes["w0"], scene=sc,
                              method="dop853", rtol=1e-11, horizon_time=2.0, u0=axes["u0"],
                              slip_u=axes["slip_u"], slip_v=[0.3])  # fmt: skip
    grids = np.meshgrid(*axes.values(), indexing="ij")
    ref = launch_fates(*grids[:4], u0=grids[4], slip_u=grids[5], slip_v=grids[6], scene=sc,
                       rtol=1e-11, horizon_time=2.0)  # fmt: skip
    for name in ("fate", "fate_time", "slide_time", "slip_episodes", "final_energy", *LOSSES):
        np.testing.assert_array_equal(ds[name].values, ref[name], err_msg=name)
    names = dict(zip(ds["fate"].attrs["flag_values"].tolist(),
                     ds["fate"].attrs["flag_meanings"].split(), strict=True))  # fmt: skip
    assert "slipped" not in names.values() and names[7] == "sliding"
    fate = np.vectorize(names.get)(ds["fate"].values)
    assert "failed" not in fate and "no_orbit" not in fate
    assert (ds["slide_time"].values >= 0.0).all()
    ep = ds["slip_episodes"].values
    assert ep.dtype.kind == "i" and (ep >= 0).all()
    assert (ep[(grids[5] != 0) | (grids[6] != 0)] >= 1).all()  # a sliding launch counts one
    nan = np.isnan(ds["final_energy"].values)
    for name in ("final_h", "final_Lz"):
        np.testing.assert_array_equal(np.isnan(ds[name].values), nan, err_msg=name)
    assert nan[fate == "sliding"].all() and not nan[fate == "rolling"].any()
    for i in np.ndindex(ds["fate"].shape):  # the last mode, from the story's mode changes
        g = [x[i] for x in grids]
        out = story(*g[:4], u0=g[4], slip_u=g[5], slip_v=g[6], scene=sc, rtol=1e-11,
                    horizon_time=2.0)  # fmt: skip
        sliding = g[5] != 0 or g[6] != 0
        for e in out["events"]:
            sliding = {"slip": True, "roll": False}.get(e["kind"], sliding)
        assert nan[i] == sliding, (i, out["events"])
    lost = sum(ds[n].values for n in LOSSES)
    scale = np.abs(ds["energy"].values) + 0.5 * (grids[4] ** 2 + 1.5**2 + 0.3**2 + 1.0 + 0.25)
    assert (np.abs(lost - ds["energy_lost"].values) <= 1e-9 * scale).all()
    assert (ds["energy_lost"].values >= 0.0).all()


SURVEY = """
title = "slide and roll, tiny"
method = "dop853"
[scene]
mu = 50.0
mu_k = 0.3
rim = 1.0
[horizon]
time = 1.5
[axes.alpha]
values = [0.5, 1.2]
[axes.r0]
values = [0.1, 0.4]
[axes.v0]
values = [0.3, 1.2]
[axes.w0]
values = [-1.0]
[axes.u0]
values = [0.0]
"""


def test_survey_file_round_trip_validate_run_and_open(tmp_path, monkeypatch, capsys):
    """The survey file's scene keys mu_k and the launch axes u0, slip_u, slip_v: validate
    and run it to netCDF; the file opens with xarray and holds the API's map."""
    monkeypatch.chdir(tmp_path)
    Path("slide.toml").write_text(SURVEY)
    assert cli.main(["validate", "slide.toml"]) == 0
    out = capsys.readouterr().out
    assert "sliding fate" in out and "slide_time" in out
    assert cli.main(["run", "slide.toml", "-o", "slide.nc", "-q"]) == 0
    with xr.open_dataset("slide.nc") as ds:
        assert ds["fate"].dims == ("alpha", "r0", "v0", "w0", "u0")  # the file's axes
        assert ds.attrs["map_kind"] == "sliding fate"
        api = engine.launch_survey([0.5, 1.2], [0.1, 0.4], [0.3, 1.2], [-1.0], scene=NEVER_SLIPS,
                                   method="dop853", horizon_time=1.5, u0=[0.0])  # fmt: skip
        for name in api.data_vars:
            np.testing.assert_array_equal(ds[name].values, api[name].values, err_msg=name)
        assert ds["slip_episodes"].dtype == np.int32
        assert ds["fate"].attrs["flag_meanings"] == api["fate"].attrs["flag_meanings"]
    assert cli.main(["info", "slide.nc"]) == 0
    assert "sliding" in capsys.readouterr().out


@pytest.mark.parametrize(
    "change, key, value",
    [
        (("mu_k = 0.3\n", ""), "axes.u0", "0.5"),  # a release axis without mu_k
        (("mu_k = 0.3", "mu_k = 60.0"), "scene.mu_k", "60.0"),  # mu_k > mu
        (("mu_k = 0.3", "mu_k = 0.3\nc_spin = -1.0"), "scene.c_spin", "-1.0"),
        (('method = "dop853"', 'method = "symplectic"'), "method", "sliding"),
        (("values = [0.0]", "values = [0.0, nan]"), "axes.u0.values[1]", "nan"),
    ],
)
def test_bad_sliding_survey_files_exit_2_naming_key_and_value(tmp_path, monkeypatch, capsys,
                                                              change, key, value):  # fmt: skip
    monkeypatch.chdir(tmp_path)
    text = SURVEY.replace(*change).replace("values = [0.0]", "values = [0.5]")
    if key == "axes.u0.values[1]":
        text = SURVEY.replace(*change)
    Path("bad.toml").write_text(text)
    for command in (["validate", "bad.toml"], ["run", "bad.toml", "-o", "bad.nc"]):
        assert cli.main(command) == 2
        err = capsys.readouterr().err
        assert key in err and value in err, err
    assert sorted(os.listdir()) == ["bad.toml"]


def test_launch_maps_keep_the_dims_the_user_asked_for():
    """A release value (u0, slip_u, slip_v) is an axis only where it was given as one: none
    given, the map is (alpha, r0, v0, w0) as on a rolling scene (it was 7-D, three length-1
    axes); a number is no axis but the same for every launch (a scalar coordinate where it
    is not 0), wired as the launch's own story says (engine.story.launch_fates)."""
    kw = dict(scene=NEVER_SLIPS, method="dop853", horizon_time=1.5)
    axes = ([0.5, 1.2], [0.1, 0.4], [0.3], [-1.0, 0.5])
    plain = engine.launch_survey(*axes, **kw)
    assert plain["fate"].dims == ("alpha", "r0", "v0", "w0")
    assert not {"u0", "slip_u", "slip_v"} & set(plain.coords)
    ds = engine.launch_survey(*axes, u0=0.5, slip_u=[0.0, 1.0], **kw)
    assert ds["fate"].dims == ("alpha", "r0", "v0", "w0", "slip_u")
    assert ds["u0"].dims == () and float(ds["u0"]) == 0.5 and ds["u0"].attrs["units"] == "m s-1"
    assert "slip_v" not in ds.coords
    grids = np.meshgrid(*axes, [0.0, 1.0], indexing="ij")
    ref = launch_fates(*grids[:4], u0=0.5, slip_u=grids[4], scene=NEVER_SLIPS, rtol=1e-10,
                       horizon_time=1.5)  # fmt: skip
    for name in ("fate", "fate_time", "slide_time", "energy_lost"):
        np.testing.assert_array_equal(ds[name].values, ref[name], err_msg=name)
    assert (ds["slip_episodes"].values[..., 1] == 1).all()  # thrown: each slides


def test_a_survey_file_has_the_release_axes_it_names(tmp_path):
    """A survey file naming only [axes.slip_u] has that one release axis (the others are 0)."""
    from engine.surveyfile import load_survey

    text = SURVEY.replace("[axes.u0]", "[axes.slip_u]")
    (tmp_path / "s.toml").write_text(text)
    s = load_survey(tmp_path / "s.toml")
    assert s.dims == ("alpha", "r0", "v0", "w0", "slip_u") and s.u0 is None
    assert s.plan.dims == s.dims


def test_backspin_is_an_axis_a_speed_by_backspin_map_is_a_rectangle():
    """``backspin`` = slip_u - u0 as a launch axis: the map over u0 x backspin is the launches'
    own stories at slip_u = u0 + backspin (launch_fates, bit for bit), and in the flat limit
    each slides for k (u0 + b) / ((1+k) mu_k g) and rolls on at (u0 - k b)/(1+k) (the closed
    forms of docs/physics.md "Checks")."""
    sc = Scene(k=0.4, mu=0.5, mu_k=0.25, rim=5000.0)
    u0, b = np.array([1.0, 2.0]), np.array([-0.5, 0.0, 1.0, 4.0])
    ds = engine.launch_survey(FLAT, 1000.0, 0.0, 0.0, scene=sc, method="dop853",
                              horizon_time=2.0, u0=u0, backspin=b)  # fmt: skip
    assert ds["fate"].dims == ("alpha", "r0", "v0", "w0", "u0", "backspin")
    assert ds["backspin"].attrs["units"] == "m s-1" and "slip_u - u0" in ds["backspin"].attrs[
        "long_name"]  # fmt: skip
    U, B = np.meshgrid(u0, b, indexing="ij")
    ref = launch_fates(FLAT, 1000.0, 0.0, 0.0, u0=U, slip_u=U + B, scene=sc, method="dop853",
                       horizon_time=2.0)  # fmt: skip
    for name in ("fate", "slide_time", "fate_speed", "slip_episodes", "final_energy"):
        np.testing.assert_array_equal(ds[name].values[0, 0, 0, 0], ref[name], name)
    t = ds["slide_time"].values[0, 0, 0, 0]
    np.testing.assert_allclose(t, 0.4 * (U + B) / (1.4 * 0.25 * G), rtol=1e-3)
    speed = np.abs(U - 0.4 * B) / 1.4
    rolling = ds["fate"].values[0, 0, 0, 0] == engine.FATE_NAMES.index("rolling")
    assert rolling.sum() >= 6
    np.testing.assert_allclose(ds["fate_speed"].values[0, 0, 0, 0][rolling],
                               speed[rolling], atol=G * 2.0 / math.tan(FLAT))  # fmt: skip
    with pytest.raises(ValueError, match="slip_u or backspin"):
        engine.launch_survey(FLAT, 1000.0, 0.0, 0.0, scene=sc, method="dop853",
                             horizon_time=2.0, u0=u0, slip_u=[1.0, 2.0], backspin=b)  # fmt: skip
    with pytest.raises(ValueError, match=r"^backspin must be 0 without Scene\.mu_k"):
        engine.launch_survey([0.5], [0.3], [1.0], [0.0], scene=ROLLING, method="dop853",
                             horizon_time=1.0, backspin=[0.0, 1.0])  # fmt: skip


def test_a_survey_file_spans_backspin(tmp_path, monkeypatch, capsys):
    """[axes.backspin] in a survey file: the same map as the API's; with slip_u too, or on a
    scene without mu_k, refused naming the key (exit 2, nothing written)."""
    monkeypatch.chdir(tmp_path)
    text = SURVEY + "[axes.backspin]\nvalues = [0.0]\n"
    Path("spin.toml").write_text(text)
    assert cli.main(["run", "spin.toml", "-o", "spin.nc", "-q"]) == 0
    with xr.open_dataset("spin.nc") as ds:
        assert ds["fate"].dims == ("alpha", "r0", "v0", "w0", "u0", "backspin")
        api = engine.launch_survey([0.5, 1.2], [0.1, 0.4], [0.3, 1.2], [-1.0], scene=NEVER_SLIPS,
                                   method="dop853", horizon_time=1.5, u0=[0.0],
                                   backspin=[0.0])  # fmt: skip
        for name in api.data_vars:
            np.testing.assert_array_equal(ds[name].values, api[name].values, err_msg=name)
    both = text + "[axes.slip_u]\nvalues = [0.0]\n"
    Path("both.toml").write_text(both)
    assert cli.main(["validate", "both.toml"]) == 2
    assert "axes.backspin: give slip_u or backspin" in capsys.readouterr().err
    rolling = text.replace("mu_k = 0.3\n", "").replace(
        "[axes.backspin]\nvalues = [0.0]", "[axes.backspin]\nvalues = [0.5]"
    )
    Path("rolling.toml").write_text(rolling)
    assert cli.main(["validate", "rolling.toml"]) == 2
    err = capsys.readouterr().err
    assert "axes.backspin" in err and "0.5" in err and "mu_k" in err
    assert sorted(os.listdir()) == ["both.toml", "rolling.toml", "spin.nc", "spin.toml"]

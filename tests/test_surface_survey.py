"""Maps on surfaces of revolution through the API and survey files (engine.api.launch_survey with
a surface, engine.surveysurface, engine.surface_eval): the integrated maps against Routh's
reduction at 40 digits (tests/surface_cases.py, computed without the engine), the exact and
integrated maps against each other, the fate maps against the 40-digit fates, and the survey
file's refusals."""

import math
from dataclasses import replace

import numpy as np
import pytest
from surface_cases import BY_ID, stored

import engine
from engine.kernels.routh import CLASS_NAMES, MAY_LIFT
from engine.kernels.surface_starts import set_point
from engine.routh import surface_table
from engine.surface_maps import surface_params, surface_points
from engine.surfaces import Bowl, Cone, Funnel, Paraboloid, PowerLaw, Profile
from engine.surveyfile import SurveyError, parse_survey

ENGINE = {
    "bowl": Bowl(1.0),
    "paraboloid": Paraboloid(0.5),
    "funnel": Funnel(0.05, 0.02),
    "deep_funnel": Funnel(0.05, 0.1),
    "power3": PowerLaw(0.5, 3.0),
    "power1.5": PowerLaw(1.0, 1.5),
    "cone": Cone(0.6),
}
#: The 40-digit cases launched at a turning point (u0 = 0) on the engine's own surfaces.
TURNING = ("bowl-1", "bowl-2", "bowl-3", "bowl-4", "bowl-6", "paraboloid-1", "paraboloid-2",
           "paraboloid-3", "paraboloid-5", "funnel-1", "funnel-2", "funnel-3", "funnel-5",
           "power3-1", "power1.5-1", "cone-1")  # fmt: skip
RTOL = 1e-11


def _scene(case, **extra):
    return engine.Scene(M=case.M, g=case.g, a=case.a, k=case.k, **extra)


def _one(ds, name):
    return float(ds[name].values.reshape(-1)[0])


@pytest.mark.parametrize("cid", TURNING)
def test_integrated_periods_meet_the_40_digit_reduction(cid):
    """dop853's one-period map from each launch: period and apsidal angle within 100 rtol of
    Routh's reduction at 40 digits (the integrators' stated accuracy), the turning points (the
    exact map's) within 1e-12."""
    case = BY_ID[cid]
    ref = stored(cid)
    ds = engine.launch_survey(surface=ENGINE[case.surface], rho0=case.rho0, v0=case.v0,
                              w0=case.w0, scene=_scene(case), method="dop853",
                              rtol=RTOL)  # fmt: skip
    assert ds.cone.names("orbit_class").values.reshape(-1)[0] == "bounded"
    assert int(ds.status.values.reshape(-1)[0]) == 0
    assert _one(ds, "period") == pytest.approx(float(ref["period"]), rel=100 * RTOL)
    psi = abs(float(ref["apsidal_angle"]))
    assert _one(ds, "apsidal_angle") == pytest.approx(psi, rel=100 * RTOL)
    for name in ("rho_min", "rho_max"):
        assert _one(ds, name) == pytest.approx(float(ref[name]), rel=1e-12)


def test_exact_and_integrated_maps_agree_on_a_grid():
    """On a bowl and a funnel, every bounded launch's period and apsidal angle by Routh's
    reduction and by rk45 agree within 100 rtol; every other class has no integrated period."""
    for surface, rho0 in ((Bowl(0.5), [0.1, 0.25, 0.4]), (Funnel(0.05, 0.02), [0.05, 0.1, 0.2])):
        kw = dict(surface=surface, rho0=rho0, v0=[0.3, 0.8, 1.6], w0=[-1.0, 0.0, 2.0])
        exact = engine.launch_survey(**kw)
        rk = engine.launch_survey(**kw, method="rk45", rtol=1e-10)
        bounded = exact.orbit_class.values == 1
        assert bounded.sum() >= 10
        np.testing.assert_array_equal(rk.orbit_class.values, exact.orbit_class.values)
        for name in ("period", "apsidal_angle"):
            np.testing.assert_allclose(rk[name].values[bounded], exact[name].values[bounded],
                                       rtol=1e-8)  # fmt: skip
            assert np.isnan(rk[name].values[~bounded]).all()


@pytest.mark.parametrize(
    "cid, extra, fate",
    [
        ("rim", {"rim": 0.35}, "spilled"),  # the bowl's edge 0.35 m from the axis
        ("hole", {"rim": 10.0}, "vertex"),  # the funnel's hole: its inner end
        ("slip", {"mu": 0.165}, "slipped"),
    ],
)
def test_fates_meet_the_40_digit_reduction(cid, extra, fate):
    """The fate map follows each launch to the rim, the hole or the friction limit: the fate,
    its time and azimuth within 1e-8 relative of the 40-digit fate (rtol 1e-11)."""
    case = BY_ID[cid]
    ref = stored(cid)
    ds = engine.launch_survey(surface=ENGINE[case.surface], rho0=case.rho0, v0=case.v0,
                              w0=case.w0, scene=_scene(case, **extra), method="dop853",
                              rtol=RTOL, horizon_time=100.0)  # fmt: skip
    assert ds.cone.names("fate").values.reshape(-1)[0] == fate
    assert _one(ds, "fate_time") == pytest.approx(float(ref["fate_time"]), rel=1e-8)
    assert abs(_one(ds, "fate_theta")) == pytest.approx(abs(float(ref["fate_azimuth"])), rel=1e-8)
    assert _one(ds, "invariant_drift") < 1e-8


def test_a_profile_of_a_paraboloid_is_the_paraboloid():
    """A measured meridian sampled from z = rho^2/(2R) (its Chebyshev fit is exact) maps as the
    paraboloid does."""
    rho = np.linspace(0.0, 0.8, 30)
    profile = Profile(tuple(rho), tuple(rho**2 / 1.0))
    a = engine.launch_survey(surface=profile, rho0=[0.2, 0.4], v0=[0.6, 1.2], w0=[0.0])
    b = engine.launch_survey(surface=Paraboloid(0.5), rho0=[0.2, 0.4], v0=[0.6, 1.2], w0=[0.0])
    for name in ("rho_min", "rho_max", "period", "apsidal_angle"):
        np.testing.assert_allclose(a[name].values, b[name].values, rtol=1e-11)


def test_a_profile_too_rough_for_its_curvature_is_refused():
    rho = np.linspace(0.0, 0.5, 60)
    z = rho**2 + 1e-3 * np.random.default_rng(0).standard_normal(rho.size)
    with pytest.raises(ValueError, match="no smooth meridian"):
        Profile(tuple(rho), tuple(z))


def test_symplectic_is_refused_on_a_surface_with_its_reason():
    with pytest.raises(ValueError, match="separable split") as err:
        engine.launch_survey(surface=Bowl(0.5), rho0=0.2, v0=1.0, w0=0.0, method="symplectic")
    assert "exact, rk45, dop853" in str(err.value)


SURVEY = """
title = "a bowl"
[surface]
kind = "bowl"
radius = 0.5
[axes.rho0]
values = [0.1, 0.3]
[axes.v0]
values = [0.5, 1.0]
[axes.w0]
values = [0.0]
"""


def test_a_surface_survey_file_is_the_apis_map():
    ds = parse_survey(SURVEY).run()
    api = engine.launch_survey(surface=Bowl(0.5), rho0=[0.1, 0.3], v0=[0.5, 1.0], w0=[0.0])
    assert ds.attrs["surface_kind"] == "bowl" and ds.attrs["surface_radius"] == 0.5
    assert ds.attrs["map_kind"] == "surface exact"
    for name in ("orbit_class", "rho_min", "rho_max", "period", "apsidal_angle"):
        np.testing.assert_array_equal(ds[name].values, api[name].values)


def test_a_swept_surface_parameter_is_an_axis():
    text = SURVEY.replace("radius = 0.5\n", "") + "[axes.radius]\nvalues = [0.5, 0.8]\n"
    ds = parse_survey(text).run()
    assert ds.orbit_class.dims == ("radius", "rho0", "v0", "w0")
    one = engine.launch_survey(surface=Bowl(0.8), rho0=[0.1, 0.3], v0=[0.5, 1.0], w0=[0.0])
    np.testing.assert_array_equal(ds.period.values[1], one.period.values)


@pytest.mark.parametrize(
    "edit, key, words",
    [
        (('kind = "bowl"', 'kind = "bowel"'), "surface.kind", "did you mean 'bowl'"),
        (("radius = 0.5\n", ""), "surface.radius", "missing"),
        (("radius = 0.5", "radius = -0.5"), "surface", "Bowl.radius must be a finite number > 0"),
        (("radius = 0.5", "radius = 0.5\nscale = 1.0"), "surface.scale", "unknown"),
        (("[axes.rho0]", "[axes.z0]"), "axes.z0", ""),
        (("values = [0.1, 0.3]", "values = [0.1, -0.3]"), "axes.rho0.values[1]", "> 0"),
    ],
)
def test_a_bad_surface_survey_names_its_key(edit, key, words):
    with pytest.raises(SurveyError) as err:
        parse_survey(SURVEY.replace(*edit))
    assert err.value.key == key and words in err.value.problem


def test_a_profile_survey_reads_its_file(tmp_path):
    rho = np.linspace(0.0, 0.8, 30)
    (tmp_path / "meridian.csv").write_text("\n".join(f"{float(r)!r},{float(r * r)!r}" for r in rho))
    text = SURVEY.replace(
        'kind = "bowl"\nradius = 0.5', 'kind = "profile"\nprofile = "meridian.csv"'
    )
    (tmp_path / "p.toml").write_text(text)
    ds = engine.surveyfile.load_survey(tmp_path / "p.toml").run()
    want = engine.launch_survey(surface=Paraboloid(0.5), rho0=[0.1, 0.3], v0=[0.5, 1.0], w0=[0.0])
    np.testing.assert_allclose(ds.period.values, want.period.values, rtol=1e-11)
    with pytest.raises(SurveyError, match="cannot read"):
        parse_survey(text)  # no file beside a string


def test_the_surface_math_is_the_cones_on_a_cone():
    """A cone given as a surface (the general path: Routh's reduction) maps as the cone's
    closed form (engine.launch_survey over alpha, r0 = rho0 / sin(alpha))."""
    alpha = 0.6
    s = engine.launch_survey(surface=Cone(alpha), rho0=[0.2, 0.5], v0=[0.8, 1.5], w0=[0.0, 1.0])
    c = engine.launch_survey(alpha=[alpha], r0=np.array([0.2, 0.5]) / math.sin(alpha),
                             v0=[0.8, 1.5], w0=[0.0, 1.0])  # fmt: skip
    for name in ("period", "apsidal_angle", "precession_rate"):
        np.testing.assert_allclose(s[name].values, c[name].values[0], rtol=1e-12)


def test_a_profile_trough_too_sharp_for_the_ball_is_refused():
    """A gutter z = (rho - 0.3)^2 / (2 r) of radius of curvature r = 5 mm refuses a 1 cm ball,
    naming where; a 2 mm ball fits."""
    rho = np.linspace(0.25, 0.35, 40)
    gutter = Profile(tuple(rho), tuple((rho - 0.3) ** 2 / 0.01))
    with pytest.raises(ValueError, match=r"does not fit in the profile's trough at rho = 0\.29"):
        engine.launch_survey(surface=gutter, rho0=0.32, v0=0.2, w0=0.0, scene=engine.Scene(a=0.01))
    assert gutter.trough(0.002) is None


#: Launches on the funnel from a turning point: nearly radial ones (v0 0.05 m/s) fall in fast
#: enough that the convex meridian (kappa < 0) takes their normal force to zero; the others roll.
LIFT_RHO0 = (0.1, 0.3, 1.0)
LIFT_V0 = (0.05, 0.5)


def test_a_ball_that_leaves_the_funnel_is_lifted_off_where_the_rigid_body_model_says():
    """The fate map ends a run where the normal force falls to zero (``lifted_off``), at the
    time and azimuth where the independent rigid-body model (tests/surface_oracle.py: Newton
    and Euler in Cartesian form, N = M (g n_z - dn/dt . V), scipy at rtol 1e-12) has N reach
    zero, within 1e-8 relative (dop853 at rtol 1e-11, as the other fates); the launches the
    model keeps on the surface roll to the horizon, and the exact map calls exactly the
    lifted ones ``lifts_off``."""
    case = BY_ID["funnel-1"]  # M, g, a, k of the funnel cases
    kw = dict(surface=ENGINE["funnel"], rho0=list(LIFT_RHO0), v0=list(LIFT_V0), w0=0.0)
    ds = engine.launch_survey(**kw, scene=_scene(case, rim=3.0), method="dop853", rtol=RTOL,
                              horizon_time=10.0)  # fmt: skip
    exact = engine.launch_survey(**kw, scene=_scene(case, rim=3.0))
    fates = ds.cone.names("fate").values.reshape(len(LIFT_RHO0), len(LIFT_V0))
    classes = exact.cone.names("orbit_class").values.reshape(fates.shape)
    lifted = 0
    for i, rho0 in enumerate(LIFT_RHO0):
        for j, v0 in enumerate(LIFT_V0):
            o = replace(case, rho0=rho0, v0=v0, w0=0.0).oracle()
            r = o.run(o.launch(rho0, v0, 0.0), 10.0)
            point = dict(rho0=rho0, v0=v0)
            if r.fate == "left_surface":
                lifted += 1
                assert fates[i, j] == "lifted_off" and classes[i, j] == "lifts_off", point
                at = ds.sel(**point, w0=0.0)
                assert float(at.fate_time) == pytest.approx(r.fate_time, rel=1e-8)
                assert abs(float(at.fate_theta)) == pytest.approx(abs(r.fate_state[9]), rel=1e-8)
                assert float(at.invariant_drift) < 1e-8
            else:
                assert (r.fate, fates[i, j], classes[i, j]) == ("rolling", "rolling", "bounded")
    assert lifted == len(LIFT_RHO0)  # every nearly radial launch


def test_a_one_period_map_says_where_the_ball_lifts_off():
    """Without a scene's end (a one-period map) a launch that lifts off has the status
    ``lifted_off`` and no period, not the period of an orbit it cannot roll."""
    ds = engine.launch_survey(surface=ENGINE["funnel"], rho0=0.3, v0=[0.05, 0.5], w0=0.0,
                              method="rk45", rtol=1e-10)  # fmt: skip
    status = ds.cone.names("status").values.reshape(-1)
    assert list(status) == ["lifted_off", "ok"]
    period = ds.period.values.reshape(-1)
    assert np.isnan(period[0]) and np.isfinite(period[1])


def test_only_a_meridian_that_curves_away_or_overhangs_is_scanned_for_lift_off():
    """The exact map looks for lift-off where the surface allows it (kappa < 0 or cos b <= 0
    somewhere): funnel, a power law with 0 < n < 1, a profile with a convex stretch (the
    log well z = 0.1 log(1 + (rho/0.3)^2), convex beyond rho = 0.3); not on a bowl, paraboloid,
    power law with n > 1, cylinder or cone (there N >= M g cos b > 0)."""
    rho = np.linspace(0.0, 1.0, 80)
    well = Profile(tuple(rho), tuple(0.1 * np.log1p((rho / 0.3) ** 2)))
    cases = {Funnel(0.05, 0.02): 1, PowerLaw(0.5, 0.5): 1, well: 1, Bowl(1.0): 0,
             Paraboloid(0.5): 0, PowerLaw(0.5, 3.0): 0, Cone(0.6): 0}  # fmt: skip
    for surface, expected in cases.items():
        p = surface_params(engine.Scene(), surface)
        s1, s2 = surface.shape
        set_point(p, surface_points(*(np.array([x]) for x in (s1, s2, 0.3, 1.0, 0.0))), 0)
        assert surface_table(p).meta[MAY_LIFT] == expected, surface


def _contact_rho(f1, rho0, a):
    """The contact point's distance from the axis of a ball whose centre is rho0 from it, on
    the graph z = f(rho) with slope f1: rho_c - a sin b(rho_c) = rho0 (fixed point)."""
    rc = rho0
    for _ in range(60):
        rc = rho0 + a * f1(rc) / math.sqrt(1 + f1(rc) ** 2)
    return rc


def test_a_ball_fast_along_a_wall_that_falls_outward_lifts_off():
    """In a ring-shaped gutter z = (rho - 0.5)^2 the wall inside the lowest circle falls away
    outward (sin b < 0): there N/M = g cos b + (sin b/rho) v^2 at a turning point, negative for a
    ball fast enough along the parallel (computed here from the graph, independently of the
    engine). The exact map calls that launch lifts_off, the fate map ends it lifted_off at its
    start; a slower launch keeps N > 0 there and is neither."""
    rho = np.linspace(0.05, 1.2, 80)
    gutter = Profile(tuple(rho), tuple((rho - 0.5) ** 2))
    scene = engine.Scene(a=0.01, rim=1.1)
    f1 = lambda r: 2 * (r - 0.5)  # noqa: E731
    for v0, lifts in ((1.2, True), (0.3, False)):
        rc = _contact_rho(f1, 0.1, scene.a)
        cb, sb = 1 / math.sqrt(1 + f1(rc) ** 2), f1(rc) / math.sqrt(1 + f1(rc) ** 2)
        n = scene.g * cb + sb * v0**2 / 0.1
        assert (n < 0) == lifts, (v0, n)
        exact = engine.launch_survey(surface=gutter, rho0=0.1, v0=v0, w0=0.0, scene=scene)
        fate = engine.launch_survey(surface=gutter, rho0=0.1, v0=v0, w0=0.0, scene=scene,
                                    method="dop853", rtol=1e-10, horizon_time=1.0)  # fmt: skip
        cls = exact.cone.names("orbit_class").values.reshape(-1)[0]
        end = fate.cone.names("fate").values.reshape(-1)[0]
        if lifts:
            assert (cls, end, _one(fate, "fate_time")) == ("lifts_off", "lifted_off", 0.0)
        else:
            assert cls != "lifts_off" and end != "lifted_off", (cls, end)


def test_a_radial_throw_through_the_axis_that_lifts_off_on_its_way_is_lifts_off():
    """Thrown inward (u0 = -8 m/s, no speed along the parallel) from rho0 = 0.8 m in the log
    well z = 0.1 log(1 + (rho/0.3)^2): through the axis and out over the rim, but the wall
    there curves away from the ball (kappa < 0 beyond rho = 0.3), and N/M = g cos b +
    kappa u^2 < 0 already at the launch (from the graph, independently of the engine). The
    exact map's through-the-axis escape is scanned too: lifts_off, not spills."""
    from engine.routh import exact_map

    rho = np.linspace(0.0, 1.0, 80)
    well = Profile(tuple(rho), tuple(0.1 * np.log1p((rho / 0.3) ** 2)))
    scene = engine.Scene(a=0.01, rim=0.95)
    f1 = lambda r: 0.2 * r / (0.09 + r * r)  # noqa: E731
    f2 = lambda r: 0.2 * (0.09 - r * r) / (0.09 + r * r) ** 2  # noqa: E731
    rc = _contact_rho(f1, 0.8, scene.a)
    kc = f2(rc) / (1 + f1(rc) ** 2) ** 1.5
    kappa = kc / (1 - scene.a * kc)  # the centre's meridian, a parallel curve
    assert scene.g / math.sqrt(1 + f1(rc) ** 2) + kappa * 8.0**2 < 0
    p = surface_params(scene, well)
    s1, s2 = well.shape
    X = surface_points(*(np.array([x]) for x in (s1, s2, 0.8, 0.0, 0.0)), u0=np.array([-8.0]))
    assert int(exact_map(p, X)["orbit_class"][0]) == CLASS_NAMES.index("lifts_off")

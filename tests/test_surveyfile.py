"""Survey definitions: parsing, the shipped surveys, and every validation error."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest

import engine
from engine.surveyfile import Survey, SurveyError, load_survey, parse_survey

SURVEYS = Path(__file__).resolve().parent.parent / "surveys"

BASE = {
    "title": "test survey",
    "method": "exact",
    "rtol": 1e-9,
    "circular_tol": 1e-11,
    "scene": {"M": 2.0, "g": 9.81, "a": 0.02, "k": 0.4, "rim": 50.0},
    "axes": {
        "alpha": {"values": [0.3, 0.6]},
        "energy": {
            "start": 1e-6,
            "stop": 10.0,
            "num": 8,
            "scale": "log",
            "relative_to": "V_min",
        },
        "h": {"values": [-2.0, 0, 2.0]},
        "Lz": {"start": 0.1, "stop": 1, "num": 10},
    },
}


def toml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


def to_toml(doc: dict, prefix: str = "") -> str:
    """A minimal TOML writer: scalars and arrays first, then [tables]."""
    lines = [f"{k} = {toml_value(v)}" for k, v in doc.items() if not isinstance(v, dict)]
    for k, v in doc.items():
        if isinstance(v, dict):
            name = f"{prefix}{k}"
            lines.append(f"\n[{name}]")
            lines.append(to_toml(v, name + "."))
    return "\n".join(lines) + "\n"


def mutated(path: str, value: object = None, *, delete: bool = False) -> str:
    """BASE as TOML with the dotted key ``path`` set to ``value`` (or deleted)."""
    doc = copy.deepcopy(BASE)
    *parents, last = path.split(".")
    node = doc
    for p in parents:
        node = node[p]
    if delete:
        del node[last]
    else:
        node[last] = value
    return to_toml(doc)


# --- valid definitions ------------------------------------------------------------------------


def test_parse_base_definition():
    text = to_toml(BASE)
    s = parse_survey(text)
    assert isinstance(s, Survey)
    assert s.title == "test survey"
    assert s.method == "exact"
    assert s.rtol == 1e-9 and s.circular_tol == 1e-11
    assert s.scene == engine.Scene(M=2.0, g=9.81, a=0.02, k=0.4, rim=50.0)
    np.testing.assert_array_equal(s.alpha, [0.3, 0.6])
    np.testing.assert_array_equal(s.h, [-2.0, 0.0, 2.0])
    np.testing.assert_allclose(s.Lz, np.linspace(0.1, 1.0, 10), rtol=1e-15)
    assert s.energy_relative is True
    assert s.shape == (2, 8, 3, 10) and s.size == 480
    assert s.source_text == text
    for name in ("alpha", "energy", "h", "Lz"):
        arr = getattr(s, name)
        assert arr.dtype == np.float64 and arr.ndim == 1
        assert not arr.flags.writeable


def test_log_scale_is_geometric_with_exact_end_points():
    e = parse_survey(to_toml(BASE)).energy
    assert e[0] == 1e-6 and e[-1] == 10.0
    ratios = e[1:] / e[:-1]
    np.testing.assert_allclose(ratios, ratios[0], rtol=1e-12)


def test_linear_scale_is_the_default_and_includes_stop():
    s = parse_survey(mutated("axes.Lz", {"start": -1.0, "stop": 1, "num": 5}))
    np.testing.assert_array_equal(s.Lz, [-1.0, -0.5, 0.0, 0.5, 1.0])


def test_defaults_when_optional_keys_are_absent():
    doc = {"axes": copy.deepcopy(BASE["axes"])}
    del doc["axes"]["energy"]["relative_to"]
    s = parse_survey(to_toml(doc))
    assert s.method == "exact"
    assert s.rtol == 1e-10 and s.circular_tol == 1e-12
    assert s.scene == engine.Scene()
    assert s.scene.rim is None
    assert s.energy_relative is False
    assert isinstance(s.title, str) and s.title


def test_integers_are_numbers_and_num_one_with_equal_ends():
    s = parse_survey(mutated("axes.h", {"start": 2, "stop": 2, "num": 1}))
    np.testing.assert_array_equal(s.h, [2.0])
    assert s.h.dtype == np.float64


def test_scene_boolean_field():
    doc = copy.deepcopy(BASE)
    doc["method"] = "rk45"  # the closed form cannot follow the attitude (issue 9): it refuses
    doc["horizon"] = {"time": 10.0}  # the rim makes an integrator's map a fate map
    doc.setdefault("scene", {})["attitude"] = True
    s = parse_survey(to_toml(doc))
    assert s.scene.attitude is True
    with pytest.raises(SurveyError, match="exact.*attitude"):
        parse_survey(mutated("scene.attitude", True))


def test_load_survey_reads_file_and_names_it_in_errors(tmp_path):
    p = tmp_path / "mine.toml"
    p.write_text(to_toml(BASE), encoding="utf-8")
    assert load_survey(p).size == 480
    p.write_text(mutated("scene.M", -1.0), encoding="utf-8")
    with pytest.raises(SurveyError) as info:
        load_survey(p)
    assert str(info.value).startswith(f"{p}: scene.M:")


def test_load_survey_missing_file_is_os_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_survey(tmp_path / "absent.toml")


def test_load_survey_rejects_non_utf8(tmp_path):
    p = tmp_path / "latin1.toml"
    p.write_bytes('title = "caf\u00e9"\n'.encode("latin-1"))
    with pytest.raises(SurveyError, match="UTF-8"):
        load_survey(p)


def test_run_matches_engine_survey():
    s = parse_survey(mutated("axes.Lz", {"values": [0.2, 0.5]}).replace("num = 8", "num = 3"))
    ds = s.run()
    ref = engine.survey(
        s.alpha,
        s.energy,
        s.h,
        s.Lz,
        scene=s.scene,
        method=s.method,
        energy_relative=True,
        circular_tol=s.circular_tol,
        rtol=s.rtol,
    )
    assert ds.sizes == ref.sizes
    for name in ref.data_vars:
        np.testing.assert_array_equal(ds[name].values, ref[name].values)


# --- shipped surveys --------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["freefall_classes.toml", "gravity_precession.toml"])
def test_shipped_surveys_parse_and_are_a_few_seconds_of_work(name):
    s = load_survey(SURVEYS / name)
    assert 1e5 <= s.size <= 1e6


def test_freefall_survey_spans_both_signs():
    s = load_survey(SURVEYS / "freefall_classes.toml")
    assert s.scene.g == 0.0
    assert not s.energy_relative
    assert s.energy.min() < 0 < s.energy.max()
    hl = np.multiply.outer(s.h, s.Lz)
    assert (hl < 0).any() and (hl > 0).any()  # B < 0 and B > 0 both occur


def test_gravity_survey_has_log_relative_energies():
    s = load_survey(SURVEYS / "gravity_precession.toml")
    assert s.scene.g == 9.81
    assert s.energy_relative
    assert s.energy[0] == 1e-6 and s.energy[-1] == 10.0
    np.testing.assert_allclose(s.energy[1:] / s.energy[:-1], (1e7) ** (1 / (s.energy.size - 1)))
    assert s.alpha.size >= 2 and s.h.size >= 2 and s.Lz.size >= 2


def test_the_slide_and_roll_survey_is_a_launch_map_of_throw_speed_against_slip():
    """The shipped hybrid survey (README figure): its scene makes a slip a transition (mu_k),
    with spin friction; the launch axes u0 and slip_u span a throw without spin (slip_u = u0)
    with backspin above it and topspin below it."""
    s = load_survey(SURVEYS / "slide_and_roll.toml")
    assert s.launch and s.dims == ("alpha", "r0", "v0", "w0", "u0", "slip_u", "slip_v")
    assert (s.scene.mu, s.scene.mu_k, s.scene.c_spin) == (0.4, 0.3, 0.005)
    assert s.method == "dop853" and s.horizon.time == 5.0
    assert s.shape == (1, 1, 1, 1, 60, 70, 1) and s.size == 4200
    assert s.slip_u.min() < s.u0.min() and s.slip_u.max() > s.u0.max()


# --- errors -----------------------------------------------------------------------------------

PI_2 = math.pi / 2

ERRORS = [
    # (text, key path, fragments the message must contain)
    (mutated("axes.alpha.values", [0.3, True]), "axes.alpha.values[1]", ["number", "true"]),
    (mutated("axes.alpha.values", [0.3, 1.6]), "axes.alpha.values[1]", ["1.6", "(0, pi/2)"]),
    (mutated("axes.alpha.values", [0.0]), "axes.alpha.values[0]", ["0.0", "(0, pi/2)"]),
    (mutated("axes.alpha.values", [0.2, PI_2]), "axes.alpha.values[1]", [repr(PI_2)]),
    (mutated("axes.alpha", {"start": 0, "stop": 1, "num": 3}), "axes.alpha.start", ["0"]),
    (mutated("axes.alpha", {"start": 0.1, "stop": 2, "num": 3}), "axes.alpha.stop", ["2"]),
    (mutated("axes.h.values", [float("nan")]), "axes.h.values[0]", ["finite", "nan"]),
    (mutated("axes.h.values", [1.0, float("-inf")]), "axes.h.values[1]", ["finite", "-inf"]),
    (mutated("axes.h.values", []), "axes.h.values", ["empty"]),
    (mutated("axes.h.values", [1.0, 0.0, 1]), "axes.h.values[2]", ["duplicate"]),
    (mutated("axes.h.values", 1.0), "axes.h.values", ["array", "1.0"]),
    (mutated("axes.h.values", ["1.0"]), "axes.h.values[0]", ["number", "string", '"1.0"']),
    (mutated("axes.Lz.num", 0), "axes.Lz.num", ["positive integer", "0"]),
    (mutated("axes.Lz.num", -3), "axes.Lz.num", ["positive integer", "-3"]),
    (mutated("axes.Lz.num", 2.5), "axes.Lz.num", ["positive integer", "2.5"]),
    (mutated("axes.Lz.num", True), "axes.Lz.num", ["positive integer", "true"]),
    (mutated("axes.Lz.num", 1), "axes.Lz.num", ["start != stop"]),
    (mutated("axes.Lz.stop", 0.1), "axes.Lz.stop", ["differ"]),
    (mutated("axes.Lz.num", delete=True), "axes.Lz.num", ["missing"]),
    (mutated("axes.Lz.start", float("inf")), "axes.Lz.start", ["finite", "inf"]),
    (mutated("axes.energy.start", -1e-3), "axes.energy.start", ["log", "-0.001"]),
    (mutated("axes.energy.stop", 0), "axes.energy.stop", ["log", "0"]),
    (mutated("axes.energy.scale", "logarithmic"), "axes.energy.scale", ['"logarithmic"']),
    (mutated("axes.energy.values", [1.0]), "axes.energy.start", ["values", "not both"]),
    (mutated("axes.energy.relative_to", "V_max"), "axes.energy.relative_to", ['"V_max"']),
    (mutated("axes.h.relative_to", "V_min"), "axes.h.relative_to", ["only", "axes.energy"]),
    (mutated("axes.h", {}), "axes.h", ["values", "start"]),
    (mutated("axes.h", [1.0, 2.0]), "axes.h", ["table", "array"]),
    (mutated("axes.Lz", delete=True), "axes.Lz", ["missing"]),
    (mutated("axes", delete=True), "axes", ["missing"]),
    (mutated("axes.lz", {"values": [1.0]}), "axes.lz", ["unknown", "'Lz'"]),
    (mutated("axes.h.stpo", 1.0), "axes.h.stpo", ["unknown", "'stop'"]),
    (mutated("methd", "exact"), "methd", ["unknown", "'method'"]),
    (mutated("method", "rk4"), "method", ['"rk4"', "rk45"]),
    (mutated("method", 4), "method", ["string", "4"]),
    (mutated("title", 5), "title", ["string", "5"]),
    (mutated("rtol", 0.0), "rtol", ["(0, 1)", "0.0"]),
    (mutated("rtol", True), "rtol", ["number", "true"]),
    (mutated("circular_tol", -1e-3), "circular_tol", [">= 0", "-0.001"]),
    (mutated("scene.G", 9.81), "scene.G", ["unknown", "'g'"]),
    (mutated("scene.M", -1.0), "scene.M", ["> 0", "-1"]),
    (mutated("scene.M", 0), "scene.M", ["> 0", "0"]),
    (mutated("scene.g", -9.81), "scene.g", [">= 0", "-9.81"]),
    (mutated("scene.rim", 0.0), "scene.rim", ["> 0", "0"]),
    (mutated("scene.k", "0.4"), "scene.k", ["number", "string"]),
    (mutated("scene.k", float("nan")), "scene.k", ["finite", "nan"]),
    (mutated("scene.attitude", 1), "scene.attitude", ["true or false", "1"]),
    (mutated("scene", 3), "scene", ["table", "integer"]),
]


@pytest.mark.parametrize(("text", "key", "fragments"), ERRORS, ids=[e[1] for e in ERRORS])
def test_invalid_definitions_name_key_and_value(text, key, fragments):
    with pytest.raises(SurveyError) as info:
        parse_survey(text, origin="bad.toml")
    err = info.value
    assert isinstance(err, ValueError)
    assert err.key == key
    assert err.origin == "bad.toml"
    assert str(err).startswith(f"bad.toml: {key}: ")
    for fragment in fragments:
        assert fragment in err.problem, (fragment, str(err))


def test_malformed_toml_reports_line_and_column():
    text = 'title = "x"\n\n[scene]\nM = = 1\n'
    with pytest.raises(SurveyError) as info:
        parse_survey(text, origin="broken.toml")
    msg = str(info.value)
    assert msg.startswith("broken.toml: malformed TOML")
    assert "line 4" in msg and "column" in msg


def test_unknown_key_without_close_match_lists_the_choices():
    with pytest.raises(SurveyError) as info:
        parse_survey(mutated("zzzz", 1))
    assert "expected one of" in str(info.value) and "axes" in str(info.value)


LAUNCH = """\
method = "rk45"
[scene]
c_rr = 0.02
rim = 1.0
[horizon]
time = 30.0
[axes.alpha]
values = [0.6]
[axes.r0]
start = 0.1
stop = 0.9
num = 5
[axes.v0]
values = [0.5, 1.0]
[axes.w0]
values = [0.0]
"""


def test_launch_state_axes_and_horizon():
    s = parse_survey(LAUNCH)
    assert s.dims == ("alpha", "r0", "v0", "w0") and s.shape == (1, 5, 2, 1)
    assert s.launch and s.energy is None
    assert s.horizon.time == 30.0 and s.horizon.revolutions is None
    assert {"energy", "h", "Lz", "fate"} <= set(s.variables())
    assert s.attrs()["horizon_time"] == 30.0


@pytest.mark.parametrize(
    "text,key,words",
    [
        (LAUNCH.replace("[horizon]\ntime = 30.0\n", ""), "horizon", "horizon"),
        (LAUNCH.replace("time = 30.0", "time = -1.0"), "horizon.time", "must be > 0"),
        (LAUNCH.replace("time = 30.0", "days = 3"), "horizon.days", "unknown key"),
        (LAUNCH.replace("start = 0.1", "start = 0.0"), "axes.r0.start", "must be > 0"),
        (LAUNCH.replace("[axes.w0]", "[axes.h]"), "axes", "launch states"),
        (
            LAUNCH.replace('method = "rk45"', 'method = "exact"').replace("c_rr = 0.02", ""),
            "horizon",
            "fate maps only",
        ),
    ],
)
def test_bad_horizons_and_launch_axes_are_named(text, key, words):
    with pytest.raises(SurveyError) as info:
        parse_survey(text)
    assert info.value.key.startswith(key) and words in str(info.value), str(info.value)


def test_release_axes_need_a_sliding_scene_naming_key_and_value():
    """u0, slip_u and slip_v (a launch that is not rolling) need scene.mu_k: refused with the
    key and the value by the one validation ``run`` and ``validate`` share."""
    text = """
method = "rk45"
[scene]
mu = 0.4
[horizon]
time = 5.0
[axes.alpha]
values = [0.6]
[axes.r0]
values = [0.5]
[axes.v0]
values = [1.0]
[axes.w0]
values = [0.0]
[axes.slip_u]
values = [0.0, 1.5]
"""
    with pytest.raises(SurveyError, match=r"must be 0 without Scene\.mu_k.*got 1\.5") as info:
        parse_survey(text)
    assert info.value.key == "axes.slip_u"
    sliding = parse_survey(text.replace("mu = 0.4", "mu = 0.4\nmu_k = 0.3"))
    assert sliding.dims == ("alpha", "r0", "v0", "w0", "slip_u")  # the release axes it names
    assert sliding.shape == (1, 1, 1, 1, 2)
    assert sliding.u0 is None and sliding.slip_u.tolist() == [0.0, 1.5]

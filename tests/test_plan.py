"""The run plan (engine.plan): one validated plan whatever the entry point, each input checked
by its one function (engine.checks), the same problem text from the API, a survey file and
the command line. Nothing here evaluates a map: the plans are caught before any kernel runs."""

from __future__ import annotations

import dataclasses
import pickle
import traceback

import numpy as np
import pytest
import runs

import engine
import engine.api
import engine.checks
import engine.fates
import engine.runner
import engine.story
import engine.surveydef
from engine.checks import PlanError
from engine.fates import Horizon
from engine.plan import RunPlan, plan_from_survey, survey_plan
from engine.schema import DIMS, LAUNCH_DIMS
from engine.surveyfile import SurveyError, parse_survey

INVARIANTS = """\
title = "plan"
method = "exact"
circular_tol = 1e-11
precision = "single"

[scene]
g = 9.81
rim = 4.0

[axes.alpha]
values = [0.3, 0.6]

[axes.energy]
start = 1e-6
stop = 10.0
num = 5
scale = "log"
relative_to = "V_min"

[axes.h]
values = [-1.0, 1.0]

[axes.Lz]
start = 0.1
stop = 1.0
num = 3
"""

LAUNCH = """\
title = "launch"
method = "dop853"
rtol = 1e-9

[scene]
c_rr = 0.002

[horizon]
time = 30.0
revolutions = 12

[axes.alpha]
values = [0.5]

[axes.r0]
values = [1.0, 2.0]

[axes.v0]
values = [0.5, 1.0, 1.5]

[axes.w0]
values = [0.0]
"""

API_INVARIANTS = dict(
    alpha=[0.3, 0.6],
    energy=np.geomspace(1e-6, 10.0, 5),
    h=[-1.0, 1.0],
    Lz=np.linspace(0.1, 1.0, 3),
    scene=engine.Scene(g=9.81, rim=4.0),
    method="exact",
    energy_relative=True,
    circular_tol=1e-11,
)
API_LAUNCH = dict(
    alpha=[0.5],
    r0=[1.0, 2.0],
    v0=[0.5, 1.0, 1.5],
    w0=[0.0],
    scene=engine.Scene(c_rr=0.002),
    method="dop853",
    rtol=1e-9,
    horizon_time=30.0,
    horizon_revolutions=12,
)


class _Caught(Exception):
    pass


def _plan_of(monkeypatch, module, call) -> RunPlan:
    """The plan ``call`` hands to ``module.run_plan`` (caught there: nothing is evaluated)."""
    seen = []

    def catch(plan, progress=None):
        seen.append(plan)
        raise _Caught

    monkeypatch.setattr(module, "run_plan", catch)
    with pytest.raises(_Caught):
        call()
    return seen[0]


@pytest.mark.parametrize(
    ("text", "api", "kwargs"),
    [
        (INVARIANTS, engine.survey, API_INVARIANTS),
        (LAUNCH, engine.launch_survey, API_LAUNCH),
    ],
    ids=["invariants", "launch"],
)
def test_the_survey_file_and_the_api_make_the_same_plan(monkeypatch, text, api, kwargs):
    survey = parse_survey(text)
    from_file = _plan_of(monkeypatch, engine.surveydef, survey.run)
    from_api = _plan_of(monkeypatch, engine.api, lambda: api(**kwargs))
    assert from_file == plan_from_survey(survey)
    single = text is INVARIANTS  # the file asks for float32 results; the API has no such key
    output = dataclasses.replace(from_api.output, precision="single" if single else "double")
    variables = {
        n: np.dtype(np.float32) if single and dt.kind == "f" else dt
        for n, dt in from_api.variables.items()
    }
    provenance = dict(title=survey.title, source_text=text)  # a file's own; the API has none
    assert (from_api.title, from_api.source_text) == ("conesurvey survey", "")
    assert from_file == dataclasses.replace(from_api, output=output, variables=variables,
                                            **provenance)  # fmt: skip
    # what the plan holds, read from the inputs above (not from the code under test)
    launch = text is LAUNCH
    assert from_file.dims == (LAUNCH_DIMS if launch else DIMS)
    assert from_file.method is engine.METHODS["dop853" if launch else "exact"]
    assert from_file.map_kind == ("fate" if launch else "closed form")
    assert from_file.rtol == (1e-9 if launch else 1e-10)
    assert from_file.circular_tol == (1e-12 if launch else 1e-11)
    assert from_file.energy_relative is (not launch)
    assert from_file.shape == ((1, 2, 3, 1) if launch else (2, 5, 2, 3))
    if launch:
        assert (from_file.horizon.time, from_file.horizon.revolutions) == (30.0, 12)
        assert "fate" in from_file.variables and "energy" in from_file.variables
    else:
        assert from_file.horizon is None and from_file.variables["r_min"] == np.float32
    for axis in from_file.axes:  # frozen: a block cannot change the plan another one reads
        assert not axis.flags.writeable
    assert pickle.loads(pickle.dumps(from_file)) == from_file  # dask ships it whole


def test_a_streamed_run_evaluates_the_plan_of_its_survey(monkeypatch, tmp_path):
    """run_survey builds the plan once (with its output settings) and hands it to the
    evaluation; caught at the first (compile) block, before anything is written."""
    survey = parse_survey(INVARIANTS)
    seen = []

    def catch(plan, slices):
        seen.append(plan)
        raise _Caught

    monkeypatch.setattr(engine.runner, "evaluate_block", catch)
    with pytest.raises(_Caught):
        engine.runner.run_survey(survey, tmp_path / "out.nc", block_points=7, compression="none")
    plan = seen[0]
    assert plan == plan_from_survey(survey, tmp_path / "out.nc", block_points=7, compression="none")
    assert (plan.output.path, plan.output.format.name) == (tmp_path / "out.nc", "netcdf")
    assert (plan.output.block_points, plan.output.compression) == (7, "none")
    assert plan.output.precision == "single"
    assert not (tmp_path / "out.nc").exists() and not (tmp_path / "out.nc.parts").exists()


# --- each bad input: one check, the same problem everywhere --------------------------------

FREE = runs.free_fall_survey("bad")
RIM = FREE.replace("g = 0.0", "g = 0.0\nrim = 3.0")
GOOD_API = dict(alpha=[0.5, 1.0], energy=[-0.3, 0.3], h=[-2.0, 2.0], Lz=[-0.5, 0.5])

#: (id, API keywords, survey text, key path in the file, the check, the problem text)
BAD = [
    (
        "rtol",
        dict(method="rk45", rtol=0.01),
        FREE.replace('title = "bad"', 'title = "bad"\nmethod = "rk45"\nrtol = 0.01'),
        "rtol",
        "check_rtol",
        "must lie in [1e-14, 0.001] for the integrator rk45",
    ),
    (
        "rtol_open",
        dict(rtol=1.5),
        FREE.replace('title = "bad"', 'title = "bad"\nrtol = 1.5'),
        "rtol",
        "check_rtol",
        "must lie in the open interval (0, 1)",
    ),
    (
        "circular_tol",
        dict(circular_tol=-0.001),
        FREE.replace('title = "bad"', 'title = "bad"\ncircular_tol = -0.001'),
        "circular_tol",
        "check_circular_tol",
        "must be finite and >= 0",
    ),
    (
        "horizon_time",
        dict(scene=engine.Scene(g=0.0, rim=3.0), method="rk45", horizon_time=-1.0),
        RIM.replace('title = "bad"', 'title = "bad"\nmethod = "rk45"\n[horizon]\ntime = -1.0\n'),
        "horizon.time",
        "check_horizon",
        "must be > 0",
    ),
    (
        "horizon_not_a_fate_map",
        dict(horizon_time=3.0),
        FREE.replace('title = "bad"', 'title = "bad"\n[horizon]\ntime = 3.0\n'),
        "horizon",
        "check_horizon",
        "applies to fate maps only",
    ),
    (
        "method_for_the_scene",
        dict(scene=engine.Scene(g=0.0, c_rr=0.001)),
        FREE.replace("g = 0.0", "g = 0.0\nc_rr = 0.001"),
        "method",
        "check_method",
        "method 'exact' cannot honour the scene's rolling_resistance",
    ),
    (
        "alpha",
        dict(alpha=[0.5, 1.6]),
        FREE.replace("values = [0.5, 1.0]", "values = [0.5, 1.6]"),
        "axes.alpha.values[1]",
        "check_values",
        "must lie in the open interval (0, pi/2) [radian]",
    ),
]


def _frames(exc: BaseException) -> list[str]:
    return [f.name for f in traceback.extract_tb(exc.__traceback__)]


@pytest.mark.parametrize(("kwargs", "text", "key", "check", "problem"),
                         [b[1:] for b in BAD], ids=[b[0] for b in BAD])  # fmt: skip
def test_a_bad_input_gets_one_message_from_api_file_and_cli(
    tmp_path, capsys, kwargs, text, key, check, problem
):
    with pytest.raises(PlanError) as api:
        engine.survey(**{**GOOD_API, **kwargs})
    assert problem in api.value.problem
    assert check in _frames(api.value), _frames(api.value)  # raised by the one check
    with pytest.raises(SurveyError) as file:
        parse_survey(text, origin="bad.toml")
    assert file.value.key == key
    assert file.value.problem.startswith(api.value.problem), (file.value, api.value)
    if key != "axes.alpha.values[1]":  # a file's axis values are read by engine.surveyaxes
        cause = file.value.__context__  # ... with the API's problem text (axis_problem)
        assert isinstance(cause, PlanError) and check in _frames(cause)
    (tmp_path / "bad.toml").write_text(text)
    for command in ("validate", "run"):
        proc = runs.here(tmp_path, capsys, command, "bad.toml")
        assert proc.returncode == 2, proc
        assert f"bad.toml: {key}: {api.value.problem}" in proc.stderr
    assert runs.listing(tmp_path) == ["bad.toml"]  # nothing written


def test_a_missing_horizon_is_asked_for_in_each_entry_points_words(tmp_path, capsys):
    """The one check decides that a fate map needs a horizon; the API names its keywords, a
    survey file its [horizon] table (a file's user has no horizon_time= to give)."""
    kwargs = dict(scene=engine.Scene(g=0.0, rim=3.0), method="rk45")
    text = RIM.replace('title = "bad"', 'title = "bad"\nmethod = "rk45"')
    with pytest.raises(PlanError) as api:
        engine.survey(**{**GOOD_API, **kwargs})
    assert "check_horizon" in _frames(api.value)
    assert "is required: a fate map follows each orbit" in api.value.problem
    assert "horizon_time=" in api.value.problem and "[horizon]" not in api.value.problem
    # the API's other ways to a fate map (engine.fates.fates, engine.story.launch_fates) ask
    # the same check, in the same words (they had a wording of their own)
    point = [np.array([x]) for x in (0.5, 1.0, 0.0, 1.0, 1.0)]
    sliding = engine.Scene(mu=0.5, mu_k=0.3)
    for call in (lambda: engine.fates.fates(*point, kwargs["scene"], "rk45", 1e-9, None),
                 lambda: engine.fates.fates(*point, kwargs["scene"], "rk45", 1e-9, Horizon()),
                 lambda: engine.story.launch_fates(0.5, 1.0, 0.5, 0.0, scene=sliding)):  # fmt: skip
        with pytest.raises(PlanError) as other:
            call()
        assert "check_horizon" in _frames(other.value), _frames(other.value)
        assert str(other.value) == str(api.value)
    with pytest.raises(SurveyError) as file:
        parse_survey(text, origin="bad.toml")
    assert file.value.key == "horizon"
    assert "[horizon] table with time = SECONDS" in file.value.problem
    assert "horizon_time" not in file.value.problem
    cause = file.value.__context__  # decided by the same check, not by a pre-check of its own
    assert isinstance(cause, PlanError) and "check_horizon" in _frames(cause), cause
    same = "is required: a fate map follows each orbit to its first terminal event"
    assert api.value.problem.startswith(same) and file.value.problem.startswith(same)
    (tmp_path / "bad.toml").write_text(text)
    for command in ("validate", "run"):
        proc = runs.here(tmp_path, capsys, command, "bad.toml")
        assert proc.returncode == 2, proc
        assert f"bad.toml: horizon: {file.value.problem}" in proc.stderr
    assert runs.listing(tmp_path) == ["bad.toml"]  # nothing written


def test_bad_block_points_get_one_message_from_api_and_cli(tmp_path, capsys):
    """Block points are no key of a survey file: the API's keyword and ``--block-points``."""
    with pytest.raises(PlanError) as api:
        engine.survey(**GOOD_API, block_points=0)
    assert api.value.problem == "must be a positive integer"
    assert "check_block_points" in _frames(api.value)
    (tmp_path / "s.toml").write_text(FREE)
    for command in (("run", "s.toml", "--block-points", "0"),
                    ("run", "s.toml", "--block-points", "1.5")):  # fmt: skip
        with pytest.raises(SystemExit) as info:
            runs.here(tmp_path, capsys, *command)
        assert info.value.code == 2
        assert f"must be a positive integer, got {command[-1]!r}" in capsys.readouterr().err
    # too many blocks for a run (10^12 points in blocks of one 2^16-point chunk): known from
    # the shape alone, by the same check
    axes = [np.linspace(0.1, 1.4, 1000), np.geomspace(1e-3, 1.0, 1000),
            np.linspace(-2, 2, 1000), np.linspace(0.05, 1.0, 1000)]  # fmt: skip
    with pytest.raises(PlanError) as api:
        engine.survey(*axes, energy_relative=True, block_points=1)
    assert "check_block_points" in _frames(api.value)
    assert "blocks of 65,536 points: a run lists at most 4,194,304; give --block-points" in (
        api.value.problem
    )
    text = "".join(
        f"[axes.{name}]\nstart = {float(x[0])!r}\nstop = {float(x[-1])!r}\nnum = 1000\n"
        + ('scale = "log"\nrelative_to = "V_min"\n' if name == "energy" else "")
        for name, x in zip(DIMS, axes, strict=True)
    )
    (tmp_path / "s.toml").write_text(text)
    proc = runs.here(tmp_path, capsys, "run", "s.toml", "-q", "--block-points", "1")
    assert proc.returncode == 2 and api.value.problem in proc.stderr, proc
    assert runs.listing(tmp_path) == ["s.toml"]


def test_the_plan_refuses_axes_by_name():
    with pytest.raises(PlanError, match=r"^r0 must be > 0 \[m\]; got 0.0$"):
        survey_plan(LAUNCH_DIMS, dict(alpha=[0.5], r0=[1.0, 0.0], v0=[1.0], w0=[0.0]))
    with pytest.raises(SurveyError) as file:
        parse_survey(LAUNCH.replace("values = [1.0, 2.0]", "values = [1.0, 0.0]"))
    assert (file.value.key, file.value.problem) == ("axes.r0.values[1]", "must be > 0 [m], got 0.0")
    with pytest.raises(PlanError, match=r"^Lz must be a non-empty 1-D sequence"):
        survey_plan(DIMS, dict(alpha=[0.5], energy=[1.0], h=[0.0], Lz=[]))
    with pytest.raises(PlanError, match=r"^energy must be finite; got nan$"):
        survey_plan(DIMS, dict(alpha=[0.5], energy=[np.nan], h=[0.0], Lz=[1.0]))


def _check_calls(call) -> dict[str, int]:
    """How many times ``call`` runs each function of engine.checks (and the grid-size rule)."""
    import collections
    import sys

    import engine.checks
    import engine.grid

    mine = [(n, f) for n, f in vars(engine.checks).items() if hasattr(f, "__code__")]
    codes = {f.__code__: n for n, f in mine if f.__module__ == "engine.checks"}
    codes[engine.grid.grid_too_large.__code__] = "grid_too_large"
    counts: collections.Counter = collections.Counter()

    def profile(frame, event, arg):
        if event == "call" and frame.f_code in codes:
            counts[codes[frame.f_code]] += 1

    sys.setprofile(profile)
    try:
        call()
    finally:
        sys.setprofile(None)
    return dict(counts)


def test_a_survey_file_checks_each_value_once(tmp_path):
    """The way of ``conesurvey run`` (read the file, the command's plan, the runner's plan to
    a file, the variables and attributes): every value of the file is checked once, by its
    one function, while the file is read; the plans built later check only the output."""

    def run_way():
        survey = parse_survey(LAUNCH)
        plan_from_survey(survey)
        plan_from_survey(survey, tmp_path / "o.nc")
        survey.variables(), survey.attrs()

    calls = _check_calls(run_way)
    once = ("check_scene", "check_method", "check_rtol", "check_circular_tol", "check_horizon",
            "check_precision", "grid_too_large")  # fmt: skip
    assert {n: calls.get(n) for n in once} == dict.fromkeys(once, 1), calls
    assert calls["axis_problem"] == 7  # alpha 1 + r0 2 + v0 3 + w0 1 values, each once
    # the API's whole-array checks are not run again on axes the file's reader checked
    assert not {"check_axes", "check_values", "check_numbers", "check_energy_relative"} & set(
        calls
    ), calls
    # the output's inputs, no key of a file: once per plan with an output (memory, o.nc)
    assert (calls["check_output"], calls["check_block_points"]) == (2, 2), calls
    # a Survey made in Python has the API's checks, once, and keeps the plan
    made = dataclasses.replace(parse_survey(LAUNCH), rtol=1e-8)
    calls = _check_calls(lambda: (plan_from_survey(made), made.variables(), made.plan))
    assert (calls["check_rtol"], calls["check_axes"]) == (1, 1), calls
    assert made.plan.rtol == 1e-8


@pytest.mark.parametrize("bad", [-1.0, 0.0, float("inf"), float("nan"), "3", True])
def test_a_horizon_value_is_refused_in_the_same_words_everywhere(bad):
    """One rule for a horizon value (a finite number > 0): a Horizon made by hand, the plan's
    check and the launch fates (engine.story) refuse the same value with the same message.
    An infinite horizon used to pass Horizon (and the launch fates) but not the plan."""
    messages = set()
    for refuse in (
        lambda: Horizon(time=bad),
        lambda: engine.checks.check_horizon("fate", bad, None),
        lambda: engine.story.launch_fates(
            0.8, 1.0, 1.0, 0.0, scene=engine.Scene(mu=0.3, mu_k=0.2), horizon_time=bad
        ),
    ):
        with pytest.raises(PlanError) as err:
            refuse()
        messages.add(str(err.value))
    assert len(messages) == 1, messages
    assert messages.pop().startswith("horizon_time must be")

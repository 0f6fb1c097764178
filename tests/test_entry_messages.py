"""One validation path: each bad input driven through every entry point that takes it gets the
same refusal, raised by the one check of that input in engine/checks.py (or its rule in
engine/bounds.py and engine/horizon.py): the same field, problem and value from the API's
functions, the same problem under the key path from a survey file, and from the command line
with exit status 2.

Before this, ``simulate(rtol=0.5)`` and ``evaluate(rtol=0.5)`` worded the refusal differently,
only ``evaluate`` suggested a fix for a misspelt method, ``fates`` took rtol = 0.5, ``story``
took a NaN radial speed, and ``story(r0=-1)`` named a field ``r``. Nothing here runs a kernel:
every call is refused first. (``evaluate_integrated`` and ``fates`` take their points
unchecked, by contract: a bad point gets its status; their other inputs are checked.)
"""

from __future__ import annotations

import math
import traceback
from collections.abc import Callable

import numpy as np
import pytest
import runs

import engine
from engine.checks import PlanError
from engine.errortext import toml_repr
from engine.fates import Horizon, fates
from engine.integrated import evaluate_integrated
from engine.story import launch_fates, story
from engine.surveyfile import SurveyError, parse_survey

SLIDING = engine.Scene(mu=0.5, mu_k=0.3)
FATE = engine.Scene(c_rr=0.01)


def _arr(x: float) -> np.ndarray:
    return np.array([x])


def evaluate(**kw):
    return engine.evaluate(**{"alpha": 0.5, "energy": 20.0, "h": 1.0, "Lz": 0.8, **kw})


def survey(**kw):
    axes = {"alpha": [0.5], "energy": [20.0], "h": [1.0], "Lz": [0.8]}
    return engine.survey(**{**axes, **{k: [v] if k in axes else v for k, v in kw.items()}})


def launch_survey(**kw):
    axes = {"alpha": [0.5], "r0": [1.0], "v0": [1.0], "w0": [0.0]}
    return engine.launch_survey(**{**axes, **{k: [v] if k in axes else v for k, v in kw.items()}})


def simulate(**kw):
    return engine.simulate(**{"alpha": 0.5, "energy": 20.0, "h": 1.0, "Lz": 0.8, "t_end": 1.0,
                              **kw})  # fmt: skip


def story_(**kw):
    return story(**{"alpha": 0.5, "r0": 1.0, "v0": 1.0, "w0": 0.0, "scene": SLIDING,
                    "horizon_time": 1.0, **kw})  # fmt: skip


def launch_fates_(**kw):
    return launch_fates(**{"alpha": 0.5, "r0": 1.0, "v0": 1.0, "w0": 0.0, "scene": SLIDING,
                           "horizon_time": 1.0, **kw})  # fmt: skip


def evaluate_integrated_(**kw):
    point = {n: _arr(x) for n, x in (("alpha", 0.5), ("energy", 20.0), ("h", 1.0), ("Lz", 0.8))}
    return evaluate_integrated(**{**point, "scene": engine.Scene(), "method": "rk45", **kw})


def fates_(**kw):
    names = ("alpha", "energy", "h", "Lz", "r_start")
    point = {n: _arr(x) for n, x in zip(names, (0.5, 20.0, 1.0, 0.8, 1.0), strict=True)}
    return fates(**{**point, "scene": FATE, "method": "rk45", "rtol": 1e-8,
                    "horizon": Horizon(10.0), **kw})  # fmt: skip


def invariants(**kw):
    return engine.invariants(**{"alpha": 0.5, "r": 1.0, "u": 0.0, "v": 1.0, "w": 0.0, **kw})


def launch_state(**kw):
    return engine.launch_state(**{"alpha": 0.5, "energy": 20.0, "h": 1.0, "Lz": 0.8, "r": 1.0,
                                  **kw})  # fmt: skip


def minimum_energy(**kw):
    return engine.minimum_energy(**{"alpha": 0.5, "h": 1.0, "Lz": 0.8, **kw})


INVARIANT_FILE = {"alpha": 0.5, "energy": 20.0, "h": 1.0, "Lz": 0.8}
LAUNCH_FILE = {"alpha": 0.5, "r0": 1.0, "v0": 1.0, "w0": 0.0}


def survey_text(axes: dict, top: str = "", scene: str = "", horizon: str = "") -> str:
    text = f'title = "bad"\n{top}\n'
    if scene:
        text += f"[scene]\n{scene}\n"
    if horizon:
        text += f"[horizon]\n{horizon}\n"
    for name, value in axes.items():
        text += f"[axes.{name}]\nvalues = [{toml_repr(value)}]\n"
    return text


class Case:
    """A bad input: the calls of every entry point that takes it, the check that refuses it
    (a name in the traceback), and its survey file with the key path (None: no file has it)."""

    def __init__(self, name: str, check: str, calls: dict[str, Callable[[], object]],
                 text: str | None = None, key: str = "") -> None:  # fmt: skip
        self.name, self.check, self.calls, self.text, self.key = name, check, calls, text, key


RK = {"method": "rk45"}
CASES = [
    Case("rtol", "check_rtol", {
        "evaluate": lambda: evaluate(**RK, rtol=0.5),
        "survey": lambda: survey(**RK, rtol=0.5),
        "launch_survey": lambda: launch_survey(**RK, rtol=0.5),
        "simulate": lambda: simulate(**RK, rtol=0.5),
        "story": lambda: story_(**RK, rtol=0.5),
        "launch_fates": lambda: launch_fates_(**RK, rtol=0.5),
        "evaluate_integrated": lambda: evaluate_integrated_(rtol=0.5),
        "fates": lambda: fates_(rtol=0.5),
    }, survey_text(INVARIANT_FILE, 'method = "rk45"\nrtol = 0.5'), "rtol"),
    Case("rtol_text", "real_value", {
        "evaluate": lambda: evaluate(**RK, rtol="1e-8"),
        "survey": lambda: survey(**RK, rtol="1e-8"),
        "simulate": lambda: simulate(**RK, rtol="1e-8"),
        "story": lambda: story_(**RK, rtol="1e-8"),
        "launch_fates": lambda: launch_fates_(**RK, rtol="1e-8"),
        "evaluate_integrated": lambda: evaluate_integrated_(rtol="1e-8"),
        "fates": lambda: fates_(rtol="1e-8"),
    }, survey_text(INVARIANT_FILE, 'method = "rk45"\nrtol = "1e-8"'), "rtol"),
    Case("method", "check_method", {
        "evaluate": lambda: evaluate(method="rk54"),
        "survey": lambda: survey(method="rk54"),
        "launch_survey": lambda: launch_survey(method="rk54"),
        "simulate": lambda: simulate(method="rk54"),
        "story": lambda: story_(method="rk54"),
        "launch_fates": lambda: launch_fates_(method="rk54"),
        "evaluate_integrated": lambda: evaluate_integrated_(method="rk54"),
        "fates": lambda: fates_(method="rk54"),
    }, survey_text(INVARIANT_FILE, 'method = "rk54"'), "method"),
    Case("closed_form_where_an_integrator_runs", "check_method", {
        "simulate": lambda: simulate(method="exact"),
        "story": lambda: story_(method="exact"),
        "launch_fates": lambda: launch_fates_(method="exact"),
        "evaluate_integrated": lambda: evaluate_integrated_(method="exact"),
        "fates": lambda: fates_(method="exact"),
    }),
    Case("scene", "check_scene", {
        "evaluate": lambda: evaluate(scene="cone"),
        "survey": lambda: survey(scene="cone"),
        "launch_survey": lambda: launch_survey(scene="cone"),
        "simulate": lambda: simulate(scene="cone"),
        "story": lambda: story_(scene="cone"),
        "launch_fates": lambda: launch_fates_(scene="cone"),
        "evaluate_integrated": lambda: evaluate_integrated_(scene="cone"),
        "fates": lambda: fates_(scene="cone"),
        "invariants": lambda: invariants(scene="cone"),
        "launch_state": lambda: launch_state(scene="cone"),
        "minimum_energy": lambda: minimum_energy(scene="cone"),
    }),
    Case("alpha", "check_values", {
        "evaluate": lambda: evaluate(alpha=2.0),
        "survey": lambda: survey(alpha=2.0),
        "launch_survey": lambda: launch_survey(alpha=2.0),
        "simulate": lambda: simulate(alpha=2.0),
        "story": lambda: story_(alpha=2.0),
        "launch_fates": lambda: launch_fates_(alpha=2.0),
        "invariants": lambda: invariants(alpha=2.0),
        "launch_state": lambda: launch_state(alpha=2.0),
        "minimum_energy": lambda: minimum_energy(alpha=2.0),
    }, survey_text({**INVARIANT_FILE, "alpha": 2.0}), "axes.alpha.values[0]"),
    Case("energy_nan", "check_values", {
        "evaluate": lambda: evaluate(energy=math.nan),
        "survey": lambda: survey(energy=math.nan),
        "simulate": lambda: simulate(energy=math.nan),
        "launch_state": lambda: launch_state(energy=math.nan),
    }, survey_text({**INVARIANT_FILE, "energy": math.nan}), "axes.energy.values[0]"),
    Case("energy_text", "check_numbers", {
        "evaluate": lambda: evaluate(energy="20"),
        "survey": lambda: survey(energy="20"),
        "simulate": lambda: simulate(energy="20"),
        "launch_state": lambda: launch_state(energy="20"),
    }),
    Case("r0", "check_values", {
        "launch_survey": lambda: launch_survey(r0=-1.0),
        "story": lambda: story_(r0=-1.0),
        "launch_fates": lambda: launch_fates_(r0=-1.0),
    }, survey_text({**LAUNCH_FILE, "r0": -1.0}), "axes.r0.values[0]"),
    Case("u0_nan", "check_values", {
        "launch_survey": lambda: launch_survey(scene=SLIDING, **RK, horizon_time=1.0,
                                               u0=[math.nan]),
        "simulate": lambda: simulate(scene=SLIDING, u0=math.nan),
        "story": lambda: story_(u0=math.nan),
        "launch_fates": lambda: launch_fates_(u0=math.nan),
    }, survey_text({**LAUNCH_FILE, "u0": math.nan}, 'method = "rk45"', "mu = 0.5\nmu_k = 0.3",
                   "time = 1.0"), "axes.u0.values[0]"),  # fmt: skip
    Case("slip_v_inf", "check_values", {
        "launch_survey": lambda: launch_survey(scene=SLIDING, **RK, horizon_time=1.0,
                                               slip_v=[math.inf]),
        "simulate": lambda: simulate(scene=SLIDING, slip_v=math.inf),
        "story": lambda: story_(slip_v=math.inf),
        "launch_fates": lambda: launch_fates_(slip_v=math.inf),
    }),
    Case("v0_overflow", "check_launch", {
        "launch_survey": lambda: launch_survey(v0=1e200),
        "story": lambda: story_(v0=1e200),
        "launch_fates": lambda: launch_fates_(v0=1e200),
    }, survey_text({**LAUNCH_FILE, "v0": 1e200}), "axes.v0"),
    Case("u0_overflow", "check_launch", {
        "launch_survey": lambda: launch_survey(scene=SLIDING, **RK, horizon_time=1.0, u0=[1e300]),
        "simulate": lambda: simulate(scene=SLIDING, u0=1e300),
        "story": lambda: story_(u0=1e300),
        "launch_fates": lambda: launch_fates_(u0=1e300),
    }, survey_text({**LAUNCH_FILE, "u0": 1e300}, 'method = "rk45"', "mu = 0.5\nmu_k = 0.3",
                   "time = 1.0"), "axes.u0"),  # fmt: skip
    Case("release_on_a_rolling_scene", "check_release", {
        "launch_survey": lambda: launch_survey(u0=0.5),
        "simulate": lambda: simulate(u0=0.5),
    }, survey_text({**LAUNCH_FILE, "u0": 0.5}), "axes.u0"),
    Case("rolling_scene_for_a_story", "check_scene", {
        "story": lambda: story_(scene=engine.Scene()),
        "launch_fates": lambda: launch_fates_(scene=engine.Scene()),
    }),
    Case("max_steps", "check_max_steps", {
        "simulate": lambda: simulate(max_steps=0),
        "evaluate_integrated": lambda: evaluate_integrated_(max_steps=0),
        "fates": lambda: fates_(max_steps=0),
    }),
    Case("max_events_negative", "check_count", {"story": lambda: story_(max_events=-1)}),
    Case("max_events_float", "check_count", {"story": lambda: story_(max_events=2.0)}),
    Case("horizon_time", "horizon_value", {
        "evaluate": lambda: evaluate(scene=FATE, **RK, horizon_time=-1.0),
        "survey": lambda: survey(scene=FATE, **RK, horizon_time=-1.0),
        "launch_survey": lambda: launch_survey(scene=FATE, **RK, horizon_time=-1.0),
        "story": lambda: story_(horizon_time=-1.0),
        "launch_fates": lambda: launch_fates_(horizon_time=-1.0),
        "fates": lambda: fates_(horizon=Horizon(time=-1.0)),
    }, survey_text(INVARIANT_FILE, 'method = "rk45"', "c_rr = 0.01", "time = -1.0"),
        "horizon.time"),  # fmt: skip
]  # fmt: skip


def _frames(exc: BaseException) -> list[str]:
    return [f.name for f in traceback.extract_tb(exc.__traceback__)]


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_a_bad_input_gets_one_message_through_every_entry_point(case, tmp_path, capsys):
    refusals = {}
    for entry, call in case.calls.items():
        with pytest.raises(PlanError) as info:
            call()
        refusals[entry] = info.value
        assert case.check in _frames(info.value), (entry, _frames(info.value))
    messages = {entry: str(exc) for entry, exc in refusals.items()}
    first = next(iter(refusals.values()))
    assert len(set(messages.values())) == 1, messages
    assert all(exc.field == first.field for exc in refusals.values())
    if case.text is None:
        return
    with pytest.raises(SurveyError) as file:
        parse_survey(case.text, origin="bad.toml")
    assert file.value.key == case.key
    expected = first.problem + (f", got {toml_repr(first.value)}" if first.has_value else "")
    assert file.value.problem == expected, (file.value.problem, first)
    (tmp_path / "bad.toml").write_text(case.text)
    proc = runs.here(tmp_path, capsys, "validate", "bad.toml")
    assert proc.returncode == 2, proc
    assert f"bad.toml: {case.key}: {expected}" in proc.stderr, proc.stderr
    assert runs.listing(tmp_path) == ["bad.toml"]  # nothing written


def test_a_misspelt_method_gets_a_did_you_mean_wherever_it_is_given():
    with pytest.raises(PlanError) as info:
        simulate(method="dop835")
    assert "(did you mean 'dop853'?)" in str(info.value)
    assert "check_method" in _frames(info.value)


def test_a_scene_number_beyond_the_bounds_is_refused_in_one_wording(tmp_path, capsys):
    with pytest.raises(ValueError) as api:
        engine.Scene(M=1e300)
    assert str(api.value).startswith("Scene.M must be at most 1e150")
    with pytest.raises(SurveyError) as file:
        parse_survey(survey_text(INVARIANT_FILE, scene="M = 1e300"))
    assert file.value.key == "scene.M"
    assert f"Scene.M {file.value.problem}" == str(api.value)

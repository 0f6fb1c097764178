"""The recipes of docs/architecture.md, applied to one copy of the package and run.

Each recipe is a list of edits (and new files); the copy takes all of them, then one
subprocess exercises each recipe end to end (one compile cache for all, kept by
``runs.copy_cache``). Each test asserts that its recipe touched exactly the files the doc lists
for it, with the lines the doc gives, and that the copy ran it:

- a new effect: a toy linear air drag (a force -c_drag M (1+k) V on the centre: the centre's
  velocity decays at the rate c_drag), one row of the effects table, its terms in the
  right-hand side (the force and the power it dissipates), its parameter slot and its Scene
  field; the copy must take it in survey files and ``conesurvey validate``, refuse it in the
  methods that cannot follow dissipative forces, follow it to each orbit's fate in a written
  survey, list the fate map's variables in the schema, and honour it while sliding (a
  sliding launch's story is the rigid-body model's with the drag, its energy balance closed
  with the drag's work booked);
- not a recipe: a second toy effect with a couple against the sphere's angular velocity, in the
  same copy, so that the sliding model is checked on an effect's couples as on its forces;
- a new output variable: ``apsidal_degrees``, the one-period map's apsidal angle in degrees,
  declared in the schema and written by the kernel's row; a survey file's results hold it,
  with its units, equal to the apsidal angle in degrees;
- a new command: a toy ``conesurvey hello SURVEY.toml`` (one module and its registration); the
  command line lists it, runs it on a survey file and refuses a missing one with status 2.
"""

from __future__ import annotations

import difflib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from runs import copy_cache

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "engine"
DOC = ROOT / "docs" / "architecture.md"


#: The recipe: the effect's row in the effects table.
ROW = """
    Effect(
        name="air_drag",
        bit=16,
        scene_field="c_drag",
        switch="coefficient",
        params=("c_drag",),
        forces=True,
        dissipative=True,
        events=("rest", "vertex"),
        needs=("dissipative forces",),
        variables=(("period", ("energy_loss",)),),
        doc="linear air drag: the centre's velocity decays at the rate c_drag",
    ),"""
ROW_AFTER = 'integrated with the motion",\n    ),'
_IMPORT = "from .layouts import MODEL_BASE, P_CRR, P_INV_M1K"
_BIT = 'ROLLING_RESISTANCE = EFFECT_BITS["rolling_resistance"]'
_RETURN = "    return f1, f2, t1, t2, t3"
_DRAG_NAMES = '\nAIR_DRAG = EFFECT_BITS["air_drag"]\nP_DRAG = SLOTS["c_drag"]'
#: Its terms: the force on the centre, -c_drag M (1 + k) V (rolling, the velocity decays at the
#: rate c_drag; its power, the work the drag takes, follows from the force).
TERMS = """
    if effects & AIR_DRAG:
        drag = p[P_DRAG] / p[P_INV_M1K]
        f1 -= drag * u
        f2 -= drag * v"""
#: (file, old text, new text): the recipe's edits; each old text occurs once.
EFFECT_EDITS = [
    ("kernels/effects.py", ROW_AFTER, ROW_AFTER + ROW),
    ("kernels/forces.py", _IMPORT, _IMPORT + ", SLOTS"),
    (
        "kernels/forces.py",
        _BIT,
        _BIT + '\nAIR_DRAG = EFFECT_BITS["air_drag"]\nP_DRAG = SLOTS["c_drag"]',
    ),
    ("kernels/forces.py", _RETURN, TERMS.lstrip("\n") + "\n" + _RETURN),
    (
        "scene.py",
        "    attitude: bool = False",
        "    attitude: bool = False\n    c_drag: float = 0.0",
    ),
]


#: Not a recipe: a second toy effect, with a couple, that the check applies to the same copy
#: after the recipes (the sliding model must honour couples as it honours forces): a couple
#: -c_twist M a^2 omega against the sphere's whole angular velocity, T/a = -c_twist M (p1, p2, w).
TWIST_ROW = """
    Effect(
        name="twist",
        bit=128,
        scene_field="c_twist",
        switch="coefficient",
        params=("c_twist",),
        forces=True,
        dissipative=True,
        events=("rest", "vertex"),
        needs=("dissipative forces",),
        variables=(("period", ("energy_loss",)),),
        doc="a couple against the spin: omega decays at the rate c_twist / k",
    ),"""
TWIST_TERMS = """
    if effects & TWIST:
        twist = p[P_TWIST] * p[P_MASS]
        t1 -= twist * p1
        t2 -= twist * p2
        t3 -= twist * w"""
_DRAG_ROW_END = 'the rate c_drag",\n    ),'
TWIST_EDITS = [
    ("kernels/effects.py", _DRAG_ROW_END, _DRAG_ROW_END + TWIST_ROW),
    (
        "kernels/forces.py",
        _DRAG_NAMES,
        _DRAG_NAMES + '\nTWIST = EFFECT_BITS["twist"]\nP_TWIST = SLOTS["c_twist"]\n'
        'P_MASS = SLOTS["M"]',
    ),
    ("kernels/forces.py", _RETURN, TWIST_TERMS.lstrip("\n") + "\n" + _RETURN),
    ("scene.py", "    c_drag: float = 0.0", "    c_drag: float = 0.0\n    c_twist: float = 0.0"),
]

#: The recipe "a new output variable": its row in the schema, the map kind's lists that hold it,
#: and the kernel row that computes it.
VARIABLE_ROW = """
    "apsidal_degrees": _f("degree", "apsidal angle of one integrated radial period, in degrees"),"""
_STATUS_ROW = '    "status": Variable("int8", None, "integrator status", STATUS_FLAGS),'
_LOSS_STORE = "    out_f[4, i] = loss"
VARIABLE_EDITS = [
    ("variables.py", _STATUS_ROW, _STATUS_ROW + VARIABLE_ROW),
    (
        "variables.py",
        'INTEGRATED = ("n_steps", "energy_drift", "status")',
        'INTEGRATED = ("n_steps", "energy_drift", "status", "apsidal_degrees")',
    ),
    (
        "schema.py",
        '(*REPLACED_BY_INTEGRATION, "energy_drift", *effect_variables(scene, "period"))',
        '(*REPLACED_BY_INTEGRATION, "energy_drift", "apsidal_degrees",\n'
        '            *effect_variables(scene, "period"))',
    ),
    (
        "kernels/orbit.py",
        '"energy_drift", "energy_loss")',
        '"energy_drift", "energy_loss",\n               "apsidal_degrees")',
    ),
    ("kernels/orbit.py", _LOSS_STORE, _LOSS_STORE + "\n    out_f[5, i] = psi * (180.0 / math.pi)"),
]

#: The recipe "a new command": its module, and its registration.
HELLO = '''"""``conesurvey hello SURVEY.toml``: greet a survey (a toy command)."""

from __future__ import annotations

import argparse

from . import Command, load_plan

__all__ = ["COMMAND"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("survey", metavar="SURVEY.toml", help="survey definition (TOML)")


def _hello(args: argparse.Namespace, command: str) -> int:
    plan = load_plan(args.survey)
    print(f"hello, {plan.title}: {plan.size:,} points, a {plan.map_kind} map")
    return 0


COMMAND = Command(
    name="hello",
    help="greet a survey",
    description="Greet SURVEY.toml.",
    add_arguments=add_arguments,
    run=_hello,
)
'''
_VALIDATE_IMPORT = "from .commands import validate as _validate"
COMMAND_EDITS = [
    ("commands/hello.py", None, HELLO),
    ("cli.py", _VALIDATE_IMPORT, "from .commands import hello as _hello\n" + _VALIDATE_IMPORT),
    ("cli.py", "    _convert.COMMAND,\n", "    _convert.COMMAND,\n    _hello.COMMAND,\n"),
]

#: The recipe "a new model": a toy paraboloid, its centre on z = rho^2 / (2 R) (rolling only),
#: one module of the model interface's kernels and one row of the model registry.
TOY_MODEL = """\"\"\"A toy model: a rolling centre on the paraboloid z = rho^2 / (2 R).\"\"\"

import math

import numpy as np

from .._jit import kernel
from .fate_codes import NO_ORBIT, REST_SPEED, RUNS
from .layouts import ATTITUDE, P_G, P_K, P_KK, P_M, P_MU, P_R_VERTEX, P_V_REST, model_slots
from .layouts import state_size

SLOTS = ("R",)
P_R = model_slots(SLOTS)["R"]
DOMAIN_FLOOR_SLOT = None


@kernel
def _geometry(q, p):
    t = q / p[P_R]  # tan b; q is the centre's distance from the axis
    cb = 1.0 / math.sqrt(1.0 + t * t)
    return cb, t * cb, cb * cb * cb / p[P_R], 1.0 / cb  # cos b, sin b, kappa, ds/dq


@kernel
def motion_rates(q, u, v, w, p, effects):
    cb, sb, kappa, sigma = _geometry(q, p)
    udot = v * v * cb / q + p[P_KK] * sb / q * v * w - p[P_G] * sb / (1.0 + p[P_K])
    vdot = -u * v * cb / q - p[P_KK] * kappa * u * w
    return u / sigma, v / q, udot, vdot, -u * v * (sb / q - kappa)


@kernel
def dissipated_power(q, u, v, w, p, effects):
    return 0.0


@kernel
def omega_fixed(q, theta, u, v, w, p):
    return 0.0, 0.0, w


@kernel
def invariants(y, p):
    M, k, q = p[P_M], p[P_K], y[0]
    kinetic = 0.5 * (1.0 + k) * M * (y[2] ** 2 + y[3] ** 2) + 0.5 * k * M * y[4] ** 2
    return kinetic + M * p[P_G] * q * q / (2.0 * p[P_R]), M * q * y[3], y[4]


@kernel
def slip_margin(y, p, effects):
    cb, sb, kappa, sigma = _geometry(y[0], p)
    N = p[P_M] * (p[P_G] * cb + sb / y[0] * y[3] ** 2 + kappa * y[2] ** 2)
    return p[P_KK] * p[P_M] * (p[P_G] * sb + sb / y[0] * y[3] * y[4]) - p[P_MU] * N


LEAVES = False  # the paraboloid curves towards the ball: N >= M g cos b > 0


@kernel
def lift_margin(y, p):
    cb, sb, kappa, sigma = _geometry(y[0], p)
    return -p[P_M] * (p[P_G] * cb + sb / y[0] * y[3] ** 2 + kappa * y[2] ** 2)


@kernel
def domain_floor(p):
    return 0.0


@kernel
def set_point(p, X, i):
    p[P_R_VERTEX] = 1e-3 * p[P_R]


@kernel
def _start(effects, p, X, i, rtol):
    y = np.zeros(state_size(effects))
    y[0], y[3], y[4] = X[0, i], X[1, i], X[2, i]
    if effects & ATTITUDE:
        y[5] = 1.0
    speed = max(abs(y[3]), abs(y[4]), math.sqrt(p[P_G] * y[0] * y[0] / p[P_R]))
    sc = np.full(y.shape[0], speed)
    sc[0] = y[0]
    sc[1] = 1.0
    return y, sc * rtol, speed


@kernel
def period_start(effects, p, X, i, rtol):
    y, atol, speed = _start(effects, p, X, i, rtol)
    return y[0] > 0.0, y, atol, (math.nan, math.nan, math.nan)


@kernel
def fate_start(effects, p, X, i, rtol):
    y, atol, speed = _start(effects, p, X, i, rtol)
    nan = (math.nan, math.nan, math.nan)
    if not y[0] > 0.0:
        return NO_ORBIT, math.nan, np.empty(0), 0.0, 0.0, np.empty(0), nan
    p[P_V_REST] = REST_SPEED * speed * rtol
    return RUNS, math.nan, y, 0.0, 0.0, atol, nan


@kernel
def holds_at_rest(p, y):
    return False


@kernel
def starts_inner(effects, p, y0):
    return motion_rates(y0[0], 0.0, y0[3], y0[4], p, effects)[2] > 0.0
"""
_LAST_MODEL = "\n)\n#: Model id -> row"
TOY_ROW = """
    Model("toy_paraboloid", 2, toy_paraboloid, toy_paraboloid, (), tuple(
        (c, "a toy: it only rolls, and has no exact map") for c in MODEL_CAPABILITIES)),"""
_MODEL_IMPORT = "from . import cone, cone_starts, surface, surface_starts"
MODEL_EDITS = [
    ("kernels/toy_paraboloid.py", None, TOY_MODEL),
    ("kernels/model.py", _MODEL_IMPORT, _MODEL_IMPORT + ", toy_paraboloid"),
    ("kernels/model.py", _LAST_MODEL, TOY_ROW + _LAST_MODEL),
]


#: The recipes, by their title in docs/architecture.md.
RECIPES = {
    "A new effect": EFFECT_EDITS,
    "A new output variable": VARIABLE_EDITS,
    "A new command": COMMAND_EDITS,
    "A new model": MODEL_EDITS,
}


def _apply(copy: Path, edits: list) -> dict[str, tuple[int, int]]:
    """Apply ``edits`` to the package copy: (file, old text, new text), each old text occurring
    once (old text None: a new file). Returns the lines each file gained and lost, diffed."""
    before: dict[str, str] = {}
    for rel, old, new in edits:
        path = copy / rel
        if old is None:
            assert not path.exists(), rel
            before.setdefault(rel, "")
            path.write_text(new)
            continue
        src = path.read_text()
        before.setdefault(rel, src)
        assert src.count(old) == 1, (rel, old)
        path.write_text(src.replace(old, new))
    stats = {}
    for rel, old in before.items():
        new = (copy / rel).read_text().splitlines()
        diff = list(difflib.unified_diff(old.splitlines(), new, lineterm="", n=0))
        plus = sum(1 for d in diff if d.startswith("+") and not d.startswith("+++"))
        minus = sum(1 for d in diff if d.startswith("-") and not d.startswith("---"))
        stats[rel] = (plus, minus)
    return stats


def _doc_says(title: str) -> tuple[set[str], tuple[int, int]]:
    """The files and the lines added and removed that docs/architecture.md gives for a recipe:
    its paragraph ``**Title** (applied by ...; files: `a`, `b`; +N/-M lines)``."""
    text = DOC.read_text()
    start = text.index(f"**{title}**")
    para = text[start : text.find("\n\n", start)].replace("\n", " ")
    m = re.search(r"files: ((?:`[^`]+`(?:, |; ))+)\+(\d+)/-(\d+) lines", para)
    assert m, para
    return set(re.findall(r"`([^`]+)`", m.group(1))), (int(m.group(2)), int(m.group(3)))


CHECK = r"""
import contextlib
import io
import sys
import traceback
from pathlib import Path

import numpy as np
import xarray as xr

import engine
from engine.cli import build_parser, main
from engine.methods import check_method
from engine.schema import RESULTS, map_kind, period_variables, result_variables
from engine.kernels import symplectic

tmp = Path(sys.argv[1])
failed = []


@contextlib.contextmanager
def section(name):
    try:
        yield
        print(f"{name} ok", flush=True)
    except BaseException:
        failed.append(name)
        print(f"{name} FAILED\n{traceback.format_exc()}", flush=True)


with section("command"):
    assert "hello" in build_parser().format_help()
    (tmp / "hello.toml").write_text(
        'title = "greeted"\n[axes.alpha]\nvalues = [0.5]\n[axes.energy]\nvalues = [1.0, 2.0]\n'
        '[axes.h]\nvalues = [0.0]\n[axes.Lz]\nvalues = [0.3, 0.6, 0.9]\n'
    )
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["hello", str(tmp / "hello.toml")]) == 0
    assert out.getvalue() == "hello, greeted: 6 points, a closed form map\n", out.getvalue()
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert main(["hello", str(tmp / "missing.toml")]) == 2
    assert "survey file not found" in err.getvalue(), err.getvalue()

with section("variable"):
    assert RESULTS["apsidal_degrees"].units == "degree"
    assert "apsidal_degrees" in result_variables("symplectic", engine.Scene())
    survey = tmp / "degrees.toml"
    survey.write_text('''
title = "apsidal angle in degrees"
method = "symplectic"
[axes.alpha]
values = [0.6]
[axes.energy]
values = [0.5, 1.0]
relative_to = "V_min"
[axes.h]
values = [0.0]
[axes.Lz]
values = [0.5]
''')
    assert main(["run", str(survey), "-o", str(tmp / "degrees.nc"), "-q"]) == 0
    with xr.open_dataset(tmp / "degrees.nc") as ds:
        assert ds.attrs["map_kind"] == "one period"
        assert ds.apsidal_degrees.attrs["units"] == "degree"
        psi = ds.apsidal_angle.values.ravel()
        deg = ds.apsidal_degrees.values.ravel()
        assert np.all(np.isfinite(psi)) and np.all(psi > 0), psi
        np.testing.assert_allclose(deg, np.degrees(psi), rtol=4e-16)

with section("effect"):
    scene = engine.Scene(c_drag=0.5)
    assert scene.effects == ("air_drag",), scene.effects
    try:
        engine.Scene(c_drag=-1.0)
        raise AssertionError("a negative c_drag was taken")
    except ValueError as exc:
        assert "Scene.c_drag" in str(exc), exc
    # the sliding model asks the drag's terms too: a sliding launch tells the rigid-body
    # model's story with the drag (tests/hybrid_oracle.py, Cartesian Newton-Euler, scipy
    # DOP853 at rtol 1e-12), keeps its energy balance and books the drag's work
    from engine.story import story

    sys.path.insert(0, sys.argv[2])
    from hybrid_oracle import Oracle, polar, start_state

    a = 0.01
    for alpha, r0, u0, v0, w0, su, sv in ((0.6, 0.3, 1.0, 0.5, 1.0, 1.0, 0.5),
                                          (1.0, 0.4, -1.0, 0.7, -1.0, -1.0, 0.7)):
        told = {}
        for drag in (0.0, 0.5):
            sc = engine.Scene(M=1.0, a=a, k=0.4, rim=1.0, mu=0.6, mu_k=0.5, c_drag=drag)
            told[drag] = story(alpha, r0, v0, w0, u0=u0, slip_u=su, slip_v=sv, scene=sc,
                               rtol=1e-11, horizon_time=0.5)
        out = told[0.5]
        assert out["invariant_drift"] < 1e-9, out["invariant_drift"]
        assert told[0.0]["lost_effects"] == 0.0 and out["lost_effects"] > 0.0, out
        split = out["lost_effects"] + out["lost_sliding_friction"] + out["lost_spin_friction"]
        assert abs(split - out["energy_lost"]) <= 1e-9 * out["energy_lost"], out
        assert out["events"][0]["t"] != told[0.0]["events"][0]["t"]  # the slide feels it
        oracle = Oracle(alpha, 1.0, sc.g, a, 0.4, sc.mu, sc.mu_k,
                        rim_centre=1.0 - a / np.tan(alpha), drag=0.5)
        speed = max(abs(u0), abs(v0), abs(w0), abs(su), abs(sv))
        y0 = start_state(alpha, r0, u0, v0, w0, su, sv, a)
        ev, y_end, _ = oracle.run(y0, "sliding", 0.5, speed)
        assert [e["kind"] for e in out["events"]] == [e[0] for e in ev], (out["events"], ev)
        for e, (kind, t, y) in zip(out["events"], ev, strict=True):
            assert abs(e["t"] - t) <= 1e-7 * t + 1e-9, (kind, e["t"], t)
            assert abs(e["state"]["r"] - polar(y, alpha)[0]) <= 1e-7 * r0, kind
        lost = oracle.energy(y0) - oracle.energy(y_end)
        scale = 0.5 * speed**2 + sc.g * r0
        assert abs(out["energy_lost"] - lost) <= 1e-8 * scale, (out["energy_lost"], lost)
        print(f"sliding with air_drag: {[e[0] for e in ev]}, drag took "
              f"{out['lost_effects']:.6f} J", flush=True)
    # refusals: the closed form and the symplectic method cannot follow dissipative forces
    for name, why in (("exact", "lossless"), ("symplectic", "conservative")):
        try:
            check_method(name, scene)
            raise AssertionError(f"{name} took air drag")
        except ValueError as exc:
            assert "air_drag" in str(exc) and why in str(exc), exc
    assert symplectic.UNSUPPORTED_EFFECTS & 16
    check_method("rk45", scene)
    # the schema: an integrator follows the drag to each orbit's fate
    assert map_kind("rk45", scene) == "fate"
    assert "fate" in result_variables("rk45", scene)
    assert "energy_loss" in period_variables(scene)
    # a survey file: validate and run
    survey = tmp / "drag.toml"
    survey.write_text('''
title = "air drag"
method = "rk45"
rtol = 1e-8
[scene]
c_drag = 0.5
[horizon]
time = 40.0
[axes.alpha]
values = [0.6]
[axes.r0]
values = [0.3, 0.6]
[axes.v0]
values = [0.5]
[axes.w0]
values = [0.0]
''')
    assert main(["validate", str(survey)]) == 0
    assert main(["run", str(survey), "-o", str(tmp / "drag.nc"), "-q"]) == 0
    with xr.open_dataset(tmp / "drag.nc") as ds:
        assert ds.attrs["scene_c_drag"] == 0.5
        assert ds.attrs["map_kind"] == "fate"
        fates = [engine.FATE_NAMES[int(f)] for f in ds.fate.values.ravel()]
        # the drag takes the orbit's energy and angular momentum: it rolls down to the vertex
        assert set(fates) == {"vertex"}, fates
        lost = ds.energy_lost.values.ravel()
        assert np.all(lost > 0), lost
        # the work the drag term's power integrates matches the energy the drag force took
        drift = ds.invariant_drift.values.ravel()
        assert np.all(drift < 1e-6), drift

with section("couple"):
    # a test's toy effect with a couple (TWIST_EDITS), not a documented recipe: a couple
    # against the whole angular velocity, honoured by the rolling constraint, the sliding
    # equations, the friction rolling needs and the spin's hold alike; with spin friction every
    # stretch runs on the hybrid steps (rolling too)
    from engine.story import story

    sys.path.insert(0, sys.argv[2])
    from hybrid_oracle import Oracle, polar, start_state

    a = 0.01
    alpha, r0, u0, v0, w0, su, sv = 0.6, 0.3, 1.0, 0.5, 1.0, 1.0, 0.5
    sc = engine.Scene(M=1.0, a=a, k=0.4, rim=1.0, mu=0.6, mu_k=0.5, c_spin=0.01, c_twist=2.0)
    assert sc.effects == ("rim", "slip_check", "twist", "sliding", "spin_friction"), sc.effects
    out = story(alpha, r0, v0, w0, u0=u0, slip_u=su, slip_v=sv, scene=sc, rtol=1e-11,
                horizon_time=0.5)  # fmt: skip
    oracle = Oracle(alpha, 1.0, sc.g, a, 0.4, sc.mu, sc.mu_k, c_spin=sc.c_spin,
                    rim_centre=1.0 - a / np.tan(alpha), twist=2.0)  # fmt: skip
    speed = max(abs(u0), abs(v0), abs(w0), abs(su), abs(sv))
    y0 = start_state(alpha, r0, u0, v0, w0, su, sv, a)
    ev, y_end, _ = oracle.run(y0, "sliding", 0.5, speed)
    # it rolls, the couple makes rolling need more than mu N (a slip), and it rolls again
    assert [e[0] for e in ev] == ["roll", "slip", "roll"], ev
    assert [e["kind"] for e in out["events"]] == [e[0] for e in ev], (out["events"], ev)
    for e, (kind, t, y) in zip(out["events"], ev, strict=True):
        assert abs(e["t"] - t) <= 1e-7 * t + 1e-9, (kind, e["t"], t)
        assert abs(e["state"]["r"] - polar(y, alpha)[0]) <= 1e-7 * r0, kind
    lost = oracle.energy(y0) - oracle.energy(y_end)
    scale = 0.5 * speed**2 + sc.g * r0
    assert abs(out["energy_lost"] - lost) <= 1e-8 * scale, (out["energy_lost"], lost)
    assert out["invariant_drift"] < 1e-9 and out["lost_effects"] > 0.0, out
    print(f"couple: {[e[0] for e in ev]}, the couple took {out['lost_effects']:.6f} J", flush=True)

with section("model"):
    from engine.kernels.model import MODELS
    from engine.methods import METHODS, check_model
    from engine.surface_maps import surface_fates, surface_period

    toy = MODELS[2]
    assert toy.name == "toy_paraboloid", toy
    for name, why in (("exact", "exact maps"), ("symplectic", "separable split")):
        try:
            check_model(METHODS[name], toy)
            raise AssertionError(f"{name} took the toy model")
        except ValueError as exc:
            assert why in str(exc) and "a toy" in str(exc), exc
    scene = engine.Scene(M=1.0, g=9.81, k=0.4)
    R = 0.5

    def toy_params(sc):
        named = sc.effect_slots()
        slots = np.array([engine.kernels.layouts.SLOTS[n] for n in named], np.int64)
        p = engine.kernels.model.make_params(sc.M, sc.g, sc.k, sc.a, slots,
                                             np.array(list(named.values())))
        p[engine.kernels.layouts.MODEL_BASE] = R
        return p

    p = toy_params(scene)
    rho0 = np.array([0.1, 0.2, 0.3])
    v_circ = np.sqrt(9.81 * rho0**2 / (R * 1.4))  # du/dt = 0 at u = 0, w = 0
    for method in ("rk45", "dop853"):
        X = np.ascontiguousarray(np.stack([rho0, 1.3 * v_circ, np.zeros(3)]))
        res = surface_period(X, p, scene, METHODS[method], 1e-10, 100_000, model=2)
        assert np.all(res["status"] == 0), res["status"]
        assert np.all(res["energy_drift"] < 1e-8), res["energy_drift"]
        assert np.all(res["period"] > 0), res["period"]
        # a circular launch stays circular: after 5 s its q is still rho0
        X = np.ascontiguousarray(np.stack([rho0, v_circ, np.zeros(3)]))
        held = engine.Scene(mu=10.0)
        fates = surface_fates(X, toy_params(held), held, METHODS[method], 1e-10, 5.0, model=2)
        assert np.all(fates["fate"] == 1), fates["fate"]
        np.testing.assert_allclose(fates["fate_r"], rho0, rtol=1e-7)
    print("model toy_paraboloid: rk45 and dop853 ran", flush=True)

sys.exit(1 if failed else 0)
"""


@pytest.fixture(scope="module")
def applied(tmp_path_factory):
    """Every recipe applied to one copy of the package and the copy's check run once: the
    lines each recipe's files gained and lost, and the check's process."""
    tmp = tmp_path_factory.mktemp("recipes")
    copy = tmp / "engine"
    shutil.copytree(PKG, copy, ignore=shutil.ignore_patterns("__pycache__"))
    stats = {title: _apply(copy, edits) for title, edits in RECIPES.items()}
    _apply(copy, TWIST_EDITS)  # not a recipe: the check's toy couple
    env = dict(os.environ, PYTHONPATH=str(tmp), CONESURVEY_CACHE_DIR=str(copy_cache(tmp, "all")))
    env["NUMBA_NUM_THREADS"] = "1"
    res = subprocess.run(
        [sys.executable, "-c", CHECK, str(tmp), str(ROOT / "tests")],
        env=env,
        cwd=tmp,
        capture_output=True,
        text=True,
    )
    return stats, res


def _touched_as_documented(stats: dict, title: str) -> None:
    files, lines = _doc_says(title)
    assert set(stats[title]) == files, (title, sorted(stats[title]))
    assert tuple(map(sum, zip(*stats[title].values(), strict=True))) == lines, stats[title]


def _ran(res: subprocess.CompletedProcess, section: str) -> None:
    assert f"{section} ok" in res.stdout.splitlines(), res.stdout[-3000:] + res.stderr[-3000:]


def test_recipe_new_effect(applied):
    """One row, its right-hand-side terms, its parameter slot and Scene field: the effect reaches
    survey files, validate, fate maps, refusals, the schema and the sliding model."""
    stats, res = applied
    _touched_as_documented(stats, "A new effect")
    _ran(res, "effect")
    assert "effect air_drag: honoured by rk45, dop853" in res.stdout
    assert res.stdout.count("sliding with air_drag") == 2, res.stdout


def test_the_sliding_model_honours_an_effects_couple(applied):
    """A toy effect with a couple (not a recipe; applied to the same copy): a sliding launch
    with spin friction, every stretch on the hybrid steps, tells the rigid-body model's story
    with the same couple, its energy balance closed with the couple's work booked."""
    _, res = applied
    _ran(res, "couple")


def test_recipe_new_output_variable(applied):
    """Its schema row, the map kind's lists and its kernel row: the variable reaches a survey's
    results, with its units and values."""
    stats, res = applied
    _touched_as_documented(stats, "A new output variable")
    _ran(res, "variable")


def test_recipe_new_command(applied):
    """One module and its registration: the command line lists it, runs it and refuses a
    missing survey file."""
    stats, res = applied
    _touched_as_documented(stats, "A new command")
    _ran(res, "command")


def test_recipe_new_model(applied):
    """One module and one registry row: rk45 and dop853 run one-period and fate maps on it
    (energy conserved, a circular launch stays circular), the closed form and the symplectic
    method refuse it with its reason."""
    stats, res = applied
    _touched_as_documented(stats, "A new model")
    _ran(res, "model")

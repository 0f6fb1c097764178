"""The recipe "a new effect" (docs/architecture.md), applied to a copy of the package and run.

A toy effect, linear air drag (a force -c_drag M (1+k) V on the centre: the centre's velocity
decays at the rate c_drag), is added as one row of the effects table, its terms in the right-hand
side (the force and the power it dissipates), its parameter slot and its Scene field, and nothing
else. The copy must then take it in survey files and ``conesurvey validate``, refuse it in the
methods that cannot follow dissipative forces, follow it to each orbit's fate in a written
survey, and list the fate map's variables in the schema.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

from runs import copy_cache

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "engine"


#: The recipe: the effect's row in the effects table.
ROW = """
    Effect(
        name="air_drag",
        bit=16,
        scene_field="c_drag",
        switch="coefficient",
        params=("P_DRAG",),
        dissipative=True,
        events=("rest", "vertex"),
        needs=("dissipative forces",),
        variables=(("period", ("energy_loss",)),),
        doc="linear air drag: the centre's velocity decays at the rate c_drag",
    ),"""
ROW_AFTER = 'integrated with the motion",\n    ),'
_ATT = 'ATTITUDE = EFFECT_BITS["attitude"]'
_RETURN = "    return u, vir / p[P_SIN], udot, vdot, -kappa * u * v"
_RR_POWER = "        power += p[P_CRR] * N * math.sqrt(u * u + v * v)"
#: Its terms in the right-hand side: the force, and the power it takes (the work state's rate).
RHS_TERM = """
    if effects & AIR_DRAG:
        udot -= p[P_DRAG] * u
        vdot -= p[P_DRAG] * v"""
POWER_TERM = """
    if effects & AIR_DRAG:
        power += p[P_DRAG] * (u * u + v * v) / p[P_INV_M1K]"""
#: (file, old text, new text): the recipe's edits; each old text occurs once.
EDITS = [
    ("kernels/effects.py", ROW_AFTER, ROW_AFTER + ROW),
    ("kernels/model.py", _ATT, _ATT + '\nAIR_DRAG = EFFECT_BITS["air_drag"]'),
    (
        "kernels/model.py",
        "\nN_PARAMS = 18",
        "\nP_DRAG = 18  # linear drag rate [s-1]\nN_PARAMS = 19",
    ),
    ("kernels/model.py", _RETURN, RHS_TERM.lstrip("\n") + "\n" + _RETURN),
    ("kernels/model.py", _RR_POWER, _RR_POWER + POWER_TERM),
    (
        "scene.py",
        "    attitude: bool = False",
        "    attitude: bool = False\n    c_drag: float = 0.0",
    ),
]


def _apply(copy: Path) -> int:
    """Apply the recipe to the package copy; returns the number of lines it adds."""
    added = 0
    for rel, old, new in EDITS:
        path = copy / rel
        src = path.read_text()
        assert src.count(old) == 1, (rel, old)
        path.write_text(src.replace(old, new))
        added += new.count("\n") - old.count("\n")
    return added


CHECK = r"""
import sys
from pathlib import Path

import numpy as np
import xarray as xr

import engine
from engine.cli import main
from engine.methods import check_method
from engine.schema import map_kind, period_variables, result_variables
from engine.kernels import symplectic

tmp = Path(sys.argv[1])
scene = engine.Scene(c_drag=0.5)
assert scene.effects == ("air_drag",), scene.effects
try:
    engine.Scene(c_drag=-1.0)
    raise AssertionError("a negative c_drag was taken")
except ValueError as exc:
    assert "Scene.c_drag" in str(exc), exc
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
print("ok")
"""


def test_recipe_new_effect(tmp_path, capsys):
    """One row, its right-hand-side terms, its parameter slot and Scene field: the effect reaches
    survey files, validate, fate maps, refusals and the schema."""
    copy = tmp_path / "engine"
    shutil.copytree(PKG, copy, ignore=shutil.ignore_patterns("__pycache__"))
    lines = _apply(copy)
    assert lines <= 25, lines
    env = dict(
        os.environ,
        PYTHONPATH=str(tmp_path),
        CONESURVEY_CACHE_DIR=str(copy_cache(tmp_path, "new-effect")),
    )
    env["NUMBA_NUM_THREADS"] = "1"
    res = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(CHECK), str(tmp_path)],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    assert "effect air_drag: honoured by rk45, dop853" in res.stdout
    assert res.stdout.rstrip().endswith("ok")

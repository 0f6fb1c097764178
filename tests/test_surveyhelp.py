"""The help of the command line is written from the tables the file format is read by: every
key the survey parser takes is in ``run --help``, the top-level help speaks of the sliding
model too, and ``plot --help`` names the default variable and axes that a map really gets."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from engine import cli, surveyfile
from engine.mapspec import plan
from engine.scene import Scene
from engine.schema import GRID_DIMS, result_variables
from engine.surveyaxes import SCALES
from engine.surveyfile import load_survey

ROOT = Path(__file__).resolve().parents[1]


def _help(*args: str, capsys) -> str:
    with pytest.raises(SystemExit) as info:
        cli.main([*args, "--help"])
    assert info.value.code == 0
    return capsys.readouterr().out


def test_run_help_lists_every_key_the_parser_reads(capsys):
    text = _help("run", capsys=capsys)
    for key in surveyfile._TOP_KEYS:
        assert re.search(rf"^\s+{key}\s|\[{key}\]|\[axes\.", text, re.M), key
    for key in ("title", "method", "rtol", "circular_tol", "precision"):
        assert re.search(rf"^  {key}\s+\S", text, re.M), key
    for key in surveyfile._HORIZON_KEYS:
        assert re.search(rf"^  {key}\s+\S", text, re.M), key
    for f in dataclasses.fields(Scene):
        assert re.search(rf"^  {f.name}\s+\S", text, re.M), f.name
    axes = {d for dims in GRID_DIMS for d in dims}
    assert {"u0", "slip_u", "slip_v", "backspin"} <= axes
    for name in axes:
        assert f"[axes.{name}]" in text, name
    for scale in SCALES:
        assert f'"{scale}"' in text
    assert '"double" | "single"' in text and "None" not in text


def test_every_axis_the_help_names_is_read_from_a_survey_file(tmp_path):
    """The help's axes are the parser's: a sliding launch survey over each of them parses."""
    text = _help_text()
    named = re.findall(r"\[axes\.(\w+)\]", text)
    base = ('method = "dop853"\n[scene]\nmu = 0.5\nmu_k = 0.3\n[horizon]\ntime = 1.0\n'
            "[axes.alpha]\nvalues = [0.5]\n[axes.r0]\nvalues = [0.3]\n[axes.v0]\n"
            "values = [0.5]\n[axes.w0]\nvalues = [0.0]\n")  # fmt: skip
    on = {"rho0": 'kind = "bowl"\nradius = 0.5', "z0": 'kind = "cylinder"\nradius = 0.5'}
    for name in named:
        if name in ("alpha", "r0", "v0", "w0", "energy", "h", "Lz"):
            continue
        if name in on:  # a surface's launch position: a survey on that surface
            s = surveyfile.parse_survey(
                f'method = "dop853"\n[surface]\n{on[name]}\n[axes.{name}]\n'
                "values = [0.1, 0.2]\n[axes.v0]\nvalues = [0.5]\n[axes.w0]\nvalues = [0.0]\n"
            )
            assert name in s.dims and s.size == 2, name
            continue
        s = surveyfile.parse_survey(base + f"[axes.{name}]\nvalues = [0.0, 1.0]\n")
        assert name in s.dims and s.size == 2, name


def _help_text() -> str:
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sub.choices["run"].format_help()


def test_the_top_level_help_speaks_of_sliding_too(capsys):
    text = " ".join(_help(capsys=capsys).split())
    assert "rolling without slipping on the ideal cone" in text
    assert "sliding under kinetic friction" in text and "backspin" in text
    assert "orbit draws one orbit" in text


def _fake_result(path: Path) -> xr.Dataset:
    """A Dataset shaped as the survey file's result would be (its variables, zeros)."""
    s = load_survey(path)
    kind = result_variables(s.method, s.scene, s.energy_relative, s.launch)
    coords = {d: getattr(s, d) for d in s.dims}
    zeros = np.zeros(s.shape, np.int8)
    return xr.Dataset({n: (s.dims, zeros) for n in kind if n in ("orbit_class", "fate")},
                      coords=coords)  # fmt: skip


@pytest.mark.parametrize("survey", ["gravity_precession", "fate_rolling_resistance"])
def test_plot_help_names_the_default_map_a_shipped_survey_gets(capsys, survey):
    """The epilog's examples say which variable and axes ``conesurvey plot FILE`` draws: the
    ones the plan picks for the shipped survey's result (fate on a fate map)."""
    text = _help("plot", capsys=capsys)
    spec = plan(_fake_result(ROOT / "surveys" / f"{survey}.toml"))
    line = next(x for x in text.splitlines() if re.search(rf"plot {survey}\.nc\s+#", x))
    assert line.split("#")[1].strip() == f"{spec.variable}, {spec.x} (x) by {spec.y} (y)"
    assert "fate" in text.split("VARIABLE defaults to")[1].split(".")[0]
    assert "--contour" in text and "precession_per_revolution" in text

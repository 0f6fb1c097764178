"""``conesurvey accuracy`` and ``engine.work_precision`` (engine/accuracy.py,
engine/commands/accuracy.py): the table's errors against errors computed here, independently,
against the mpmath oracle (tests/oracle.py); the sample drawn from the survey's grid; the
recommendation; bad input."""

from __future__ import annotations

import functools
import itertools
import math
import re

import numpy as np
import pytest
from oracle import reference
from runs import ROOT, here, listing

import engine
from engine.accuracy import EXACT_ERROR, recommend, sample_grid
from engine.commands import accuracy as command
from engine.mapspec import LookError
from engine.simulate import simulate
from engine.surveyfile import load_survey

ALPHA, REL, H, LZ = (0.4, 1.1), (1e-3, 0.1, 3.0), (-1.5, 0.5), (0.2, 0.9)
#: 24 bounded orbits under gravity (every one's turning points are integrated: <= 24).
SURVEY = f"""\
title = "accuracy test survey"
[axes.alpha]
values = {list(ALPHA)}
[axes.energy]
values = {list(REL)}
relative_to = "V_min"
[axes.h]
values = {list(H)}
[axes.Lz]
values = {list(LZ)}
"""
RTOLS = (1e-5, 1e-8)
NUMBER = r"[-+]?\d+(?:\.\d+)?(?:e[-+]\d+)?"


@functools.cache
def orbits() -> dict[str, np.ndarray]:
    """The survey's points in grid order, absolute energies, and the oracle's period, apsidal
    angle and turning points of each (60 digits, quadrature and polynomial roots)."""
    pts = np.array(list(itertools.product(ALPHA, REL, H, LZ)))
    a, rel, h, lz = pts.T
    vmin = engine.minimum_energy(a, h, lz)
    out = {"alpha": a, "energy": vmin + rel * np.abs(vmin), "h": h, "Lz": lz}
    ref = {k: np.empty(a.size) for k in ("T_r", "psi", "r1", "r2")}
    for i in range(a.size):
        cls, vals, _ = reference(a[i], out["energy"][i], h[i], lz[i], with_cond=False)
        assert cls == "bounded"
        for k in ref:
            ref[k][i] = vals[k]
    return out | ref


def independent_errors(method: str, rtol: float) -> dict[str, np.ndarray]:
    """Per-orbit relative errors against the oracle: the map's period and apsidal angle
    (``engine.evaluate``), one period's turning points (``engine.simulate``), the energy drift."""
    o = orbits()
    ds = engine.evaluate(o["alpha"], o["energy"], o["h"], o["Lz"], method=method, rtol=rtol)
    assert (ds.status.values == 0).all()
    turning = np.empty(o["alpha"].size)
    for i in range(turning.size):
        tr = simulate(o["alpha"][i], o["energy"][i], o["h"][i], o["Lz"][i], periods=1,
                      method=method, rtol=rtol, dt_out=1e300)  # fmt: skip
        kinds, r = tr.event_kind.values, tr.event_r.values
        assert list(kinds) == [1, 0]  # apocentre, then the pericentre a period later
        turning[i] = max(abs(r[0] / o["r2"][i] - 1), abs(r[1] / o["r1"][i] - 1))
    return {
        "period": np.abs(ds.period.values / o["T_r"] - 1),
        "apsidal_angle": np.abs(ds.apsidal_angle.values / o["psi"] - 1),
        "turning_point": turning,
        "energy": ds.energy_drift.values,
    }


def close(printed: float, want: float) -> bool:
    """A value printed with two significant digits against the one computed here."""
    return abs(printed - want) <= 0.06 * want + 1e-14


def parse_table(out: str) -> dict[tuple[str, float], dict[str, str]]:
    lines = out.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("method"))
    names = lines[head].split()
    rows = {}
    for line in lines[head + 2 :]:
        if not re.match(r"(exact|rk45|dop853|symplectic)\s", line):
            break
        cells = dict(zip(names, line.split(), strict=True))
        rtol = math.nan if cells["rtol"] == "-" else float(cells["rtol"])
        rows[(cells["method"], rtol)] = cells
    return rows


def test_the_table_holds_the_errors_computed_independently(tmp_path, capsys):
    """Every integrator's row: the largest period, apsidal-angle, turning-point and energy
    error over the survey equal those computed here against the mpmath oracle (to the two
    digits printed); the error column is their largest; the closed form's row states its
    tested accuracy; the recommendation is the fastest row that meets the target; the diagram
    is written."""
    (tmp_path / "small.toml").write_text(SURVEY)
    png = tmp_path / "wp.png"
    res = here(tmp_path, capsys, "accuracy", "small.toml", "--rtols", "1e-5,1e-8",
               "--target", "1e-6", "--png", str(png))  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "24 points; sample 24 points" in res.stdout
    assert "24 orbits compared against the closed form" in res.stdout
    rows = parse_table(res.stdout)
    want_rows = [("exact", math.nan)] + [(m, r) for m in ("rk45", "dop853", "symplectic")
                                         for r in sorted(RTOLS, reverse=True)]  # fmt: skip
    assert [k[0] for k in rows] == [k[0] for k in want_rows]
    assert rows[("exact", math.nan)]["error"] == f"{EXACT_ERROR:.0e}*"
    columns = {"period": "period", "apsidal_angle": "apsidal", "turning_point": "turning",
               "energy": "energy"}  # fmt: skip
    for method, rtol in want_rows[1:]:
        row = rows[(method, rtol)]
        errors = independent_errors(method, rtol)
        for q, col in columns.items():
            want = float(np.max(errors[q]))
            assert close(float(row[col]), want), (method, rtol, q, row[col], want)
        worst = max(float(np.max(e)) for e in errors.values())
        assert close(float(row["error"]), worst), (method, rtol, row["error"], worst)
        assert row["failed"] == "0"
    speed = {k: float(r["s/point"]) for k, r in rows.items()}
    assert all(s > 0 for s in speed.values())
    survey = {k: float(r["survey"].rstrip("s")) for k, r in rows.items()}
    for k in rows:  # the survey's time is its points times the time per point
        assert survey[k] == pytest.approx(24 * speed[k], rel=0.06)  # 2 digits printed
    meets = [k for k, r in rows.items() if float(r["error"].rstrip("*")) <= 1e-6]
    fastest = min(meets, key=lambda k: speed[k])
    line = next(x for x in res.stdout.splitlines() if x.startswith("target 1e-06:"))
    assert line.startswith(f"target 1e-06: {fastest[0]}")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_dataset_holds_each_orbit_with_its_errors():
    """``engine.work_precision``: the orbits compared are the survey's points (alpha and the
    invariants), each with its errors, equal to those computed here against the oracle."""
    o = orbits()
    ds = engine.work_precision(load_survey_text(SURVEY), methods=["rk45"], rtols=[1e-6],
                               repeats=1, min_time=0.0)  # fmt: skip
    assert list(ds.method.values) == ["rk45"] and float(ds.rtol[0]) == 1e-6
    got = np.stack([ds.alpha.values, ds.orbit_energy.values, ds.orbit_h.values,
                    ds.orbit_Lz.values], axis=1)  # fmt: skip
    want = np.stack([o["alpha"], o["energy"], o["h"], o["Lz"]], axis=1)
    np.testing.assert_array_equal(got, want)  # grid order, the energies the survey runs
    errors = independent_errors("rk45", 1e-6)
    for q, e in errors.items():
        np.testing.assert_allclose(ds[f"{q}_error"].values[0], e, rtol=1e-3, atol=1e-15)
    best = recommend(ds, 1e-3)
    assert best is not None and best["method"] == "rk45"
    assert recommend(ds, 1e-12) is None  # rk45 at 1e-6 does not reach it


def load_survey_text(text: str):
    from engine.surveyfile import parse_survey

    return parse_survey(text)


def test_the_sample_is_drawn_reproducibly_from_the_grid():
    plan = load_survey(ROOT / "surveys" / "gravity_precession.toml").plan
    one, again, other = (sample_grid(plan, 256, seed) for seed in (0, 0, 1))
    assert 256 <= one.size <= 512
    for a, b, full in zip(one.axes, again.axes, plan.axes, strict=True):
        np.testing.assert_array_equal(a, b)
        assert np.isin(a, full).all() and np.unique(a).size == a.size
        assert a.size >= min(2, full.size)
    assert any(not np.array_equal(a, b) for a, b in zip(one.axes, other.axes, strict=True))
    small = load_survey_text(SURVEY).plan
    assert sample_grid(small, 256, 0) == small  # smaller than the sample: the whole grid


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--target", "0"], "--target"),
        (["--target", "nan"], "--target"),
        (["--rtols", "1e-2"], "--rtols"),
        (["--rtols", "1e-6,x"], "--rtols"),
        (["--methods", "exact,euler"], "--methods"),
        (["--sample", "0"], "--sample"),
        (["--png", "out.pdf"], "--png"),
        (["--png", "missing/out.png"], "--png"),
    ],
)
def test_bad_input_exits_2_naming_the_field(tmp_path, capsys, args, named):
    (tmp_path / "small.toml").write_text(SURVEY)
    before = listing(tmp_path)
    res = here(tmp_path, capsys, "accuracy", "small.toml", *args)
    assert res.returncode == 2
    assert res.stderr.startswith(f"conesurvey: error: {named}"), res.stderr
    assert res.stdout == "" and listing(tmp_path) == before


def test_a_method_that_cannot_serve_the_scene_is_refused_with_its_reason(tmp_path, capsys):
    (tmp_path / "rr.toml").write_text(
        'method = "rk45"\n[scene]\nc_rr = 0.02\n[horizon]\ntime = 5.0\n' + SURVEY.split("\n", 1)[1]
    )
    res = here(tmp_path, capsys, "accuracy", "rr.toml", "--methods", "symplectic")
    assert res.returncode == 2
    assert "--methods: 'symplectic' cannot serve this scene" in res.stderr
    assert "rolling_resistance: it integrates the conservative" in res.stderr
    assert res.stderr.rstrip().endswith("methods that can: rk45, dop853")
    res = here(tmp_path, capsys, "accuracy", "missing.toml")
    assert res.returncode == 2 and "survey file not found" in res.stderr


def test_without_matplotlib_the_diagram_is_refused_before_measuring(tmp_path, capsys,
                                                                    monkeypatch):  # fmt: skip
    def absent():
        raise LookError("drawing maps needs matplotlib, which is not installed: ...")

    monkeypatch.setattr(command, "matplotlib_parts", absent)
    (tmp_path / "small.toml").write_text(SURVEY)
    res = here(tmp_path, capsys, "accuracy", "small.toml")
    assert res.returncode == 2 and res.stdout == ""
    assert "needs matplotlib" in res.stderr and "--no-png for the table only" in res.stderr
    assert listing(tmp_path) == ["small.toml"]


def test_api_bad_input_names_the_argument():
    survey = load_survey_text(SURVEY)
    for kw, named in (({"sample": 0}, "sample"), ({"rtols": [1.0]}, "rtols"),
                      ({"methods": ["rk4"]}, "methods"), ({"rtols": []}, "rtols"),
                      ({"seed": -1}, "seed"), ({"repeats": True}, "repeats")):  # fmt: skip
        with pytest.raises(ValueError, match=f"^{named}"):
            engine.work_precision(survey, **kw)
    with pytest.raises(ValueError, match="^survey must be"):
        engine.work_precision(42)
    escapes = SURVEY.replace("[axes.alpha]", "[scene]\ng = 0.0\n[axes.alpha]").replace(
        'values = [0.001, 0.1, 3.0]\nrelative_to = "V_min"', "values = [0.5, 1.0, 2.0]"
    )  # free fall above the escape energy: every orbit hyperbolic
    with pytest.raises(ValueError, match="^sample: none of its 24 points is a bounded orbit"):
        engine.work_precision(load_survey_text(escapes))
    with pytest.raises(ValueError, match="^target must be"):
        recommend(None, 0.0)


@pytest.mark.slow  # dop853's fate map (the reference) is a compile of its own
def test_a_fate_map_is_measured_against_dop853_at_a_tight_tolerance(tmp_path, capsys):
    """Rolling resistance: no closed form; each launch's fate, fate time, fate radius and
    energy lost against dop853 at rtol 1e-13, here through ``engine.launch_survey``; the
    command's table counts the fates that differ."""
    text = """\
method = "rk45"
[scene]
c_rr = 0.02
rim = 2.0
[horizon]
time = 3.0
[axes.alpha]
values = [0.6, 1.2]
[axes.r0]
values = [0.3, 0.8]
[axes.v0]
values = [0.5, 1.5, 3.0]
[axes.w0]
values = [0.0]
"""
    ds = engine.work_precision(load_survey_text(text), rtols=[1e-6], repeats=1, min_time=0.0)
    assert list(ds.method.values) == ["rk45", "dop853"]  # exact, symplectic: no fates here
    assert ds.attrs["reference"] == "dop853 at rtol 1e-13"
    scene = engine.Scene(c_rr=0.02, rim=2.0)
    axes = dict(alpha=[0.6, 1.2], r0=[0.3, 0.8], v0=[0.5, 1.5, 3.0], w0=[0.0])
    ref = engine.launch_survey(**axes, scene=scene, method="dop853", rtol=1e-13,
                               horizon_time=3.0)  # fmt: skip
    got = engine.launch_survey(**axes, scene=scene, method="rk45", rtol=1e-6, horizon_time=3.0)
    keep = ~np.isin(ref.fate.values.reshape(-1), (0, 6))  # no_orbit, failed: no fate to compare
    differs = got.fate.values.reshape(-1)[keep] != ref.fate.values.reshape(-1)[keep]
    np.testing.assert_array_equal(ds.fate_differs.values[0], differs)
    for q in ("fate_time", "fate_r", "energy_lost"):
        a, b = got[q].values.reshape(-1)[keep], ref[q].values.reshape(-1)[keep]
        want = np.where(differs, np.nan, np.abs(a - b) / np.abs(b))
        np.testing.assert_allclose(ds[f"{q}_error"].values[0], want, rtol=1e-12, equal_nan=True)
    (tmp_path / "rr.toml").write_text(text)
    res = here(tmp_path, capsys, "accuracy", "rr.toml", "--rtols", "1e-6", "--no-png")
    assert res.returncode == 0, res.stderr
    assert "orbits compared against the dop853 at rtol 1e-13" in res.stdout
    rows = parse_table(res.stdout)
    assert list(rows) == [("rk45", 1e-6), ("dop853", 1e-6)]
    assert int(rows[("rk45", 1e-6)]["differ"]) == int(differs.sum())
    assert close(float(rows[("rk45", 1e-6)]["fate_time"]), float(np.nanmax(ds.fate_time_error[0])))

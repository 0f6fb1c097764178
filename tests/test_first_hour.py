"""What a new user meets in the first hour: a first run's compile is announced, help texts name
every key, messages say what to type, and mistakes that would pass silently are refused or
warned about (issue 18, "First hour")."""

from __future__ import annotations

import dataclasses
import io
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import engine
from engine.cli import main
from engine.progress import Progress
from engine.scene import Scene

ROOT = Path(__file__).resolve().parents[1]


def _help(command: str, capsys) -> str:
    with pytest.raises(SystemExit):
        main([command, "--help"])
    return capsys.readouterr().out


# -- 1. compiling does not look like a hang ---------------------------------------------------


@pytest.mark.parametrize("tty", [True, False])
def test_a_long_compile_is_announced_with_its_elapsed_time(tty):
    from engine.progress import COMPILE_MESSAGE

    out = io.StringIO()
    progress = Progress(out, tty=tty)
    with progress.compiling(delay=0.05):
        time.sleep(1.3)  # a compile: longer than the delay, and than one redraw (1 s)
    text = out.getvalue()
    assert COMPILE_MESSAGE == "compiling kernels (first run only, cached)"
    assert f"conesurvey: {COMPILE_MESSAGE}  0:00" in text
    assert "compiled kernels in 0:01 (cached for later runs)" in text
    assert text.endswith("\n")
    if tty:
        assert text.count("\r") >= 3  # redrawn while it lasts, then the closing line
    else:
        assert text.count(COMPILE_MESSAGE) == 1  # a log gets one line, not one per second


def test_a_cache_load_is_not_announced():
    out = io.StringIO()
    with Progress(out, tty=False).compiling(delay=5.0):
        pass
    assert out.getvalue() == ""


def test_the_run_announces_its_compile_before_the_first_point(tmp_path):
    """run_survey wraps its compile in the progress reporter's compiling(), before any
    point is reported."""
    from engine.runner import run_survey
    from engine.surveyfile import parse_survey

    events = []

    class Recorder:
        def __call__(self, done, total):
            events.append(("points", done))

        def compiling(self):
            import contextlib

            @contextlib.contextmanager
            def around():
                events.append("compile starts")
                yield
                events.append("compile ends")

            return around()

    survey = parse_survey(
        'method = "exact"\n[axes.alpha]\nvalues = [0.5]\n[axes.energy]\nvalues = [5.0, 20.0]\n'
        "[axes.h]\nvalues = [1.0]\n[axes.Lz]\nvalues = [0.8]\n"
    )
    run_survey(survey, tmp_path / "o.nc", progress=Recorder())
    assert events[:2] == ["compile starts", "compile ends"]
    assert ("points", 2) in events[2:]


def test_validate_counts_the_compile_when_the_cache_is_cold(tmp_path, capsys):
    env_cold = _validate_time(tmp_path, cache=tmp_path / "empty-cache")
    assert "compiling" in env_cold and "first run" in env_cold


def _validate_time(tmp_path: Path, cache: Path) -> str:
    import os

    env = dict(os.environ, CONESURVEY_CACHE_DIR=str(cache))
    done = subprocess.run(
        [sys.executable, "-m", "engine.cli", "validate", str(ROOT / "surveys/slip_map.toml")],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr
    return next(line for line in done.stdout.splitlines() if line.strip().startswith("time"))


def test_validate_leaves_out_the_compile_when_the_kernels_are_cached(tmp_path):
    engine.evaluate(0.5, [5.0], 1.0, 0.8, scene=Scene(rim=1.0, mu=0.25))  # the cache warm
    assert "compiling" not in _validate_time(tmp_path, cache=_default_cache())


def _default_cache() -> Path:
    from engine import _jit

    assert _jit.CACHE_DIR is not None
    return _jit.CACHE_DIR.parent


# -- 7. help and messages -----------------------------------------------------------------


def test_run_help_lists_every_scene_key_the_horizon_and_the_launch_axes(capsys):
    text = _help("run", capsys)
    for f in dataclasses.fields(Scene):
        if not f.name.startswith("_"):
            assert f"\n  {f.name} " in text, f.name
    for key in ("[horizon]", "[axes.r0]", "[axes.v0]", "[axes.w0]", "revolutions"):
        assert key in text, key


def test_convert_help_reads_as_text_not_restructuredtext(capsys):
    text = _help("convert", capsys)
    for markup in ("``", ":mod:", ":func:", ":class:"):
        assert markup not in text, markup
    assert "bit for bit" in text


_FATE_SURVEY = """\
method = "rk45"
[scene]
rim = 1.0
[axes.alpha]
values = [0.6]
[axes.r0]
values = [0.5]
[axes.v0]
values = [1.0]
[axes.w0]
values = [0.0]
"""


def test_the_horizon_error_names_the_keys_of_a_file_and_of_the_api(tmp_path, capsys):
    path = tmp_path / "fate.toml"
    path.write_text(_FATE_SURVEY)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "[horizon]" in err and "time = " in err and "horizon_time" not in err
    with pytest.raises(ValueError, match="horizon_time=") as exc:
        engine.launch_survey([0.6], [0.5], [1.0], [0.0], scene=Scene(rim=1.0), method="rk45")
    assert "[horizon]" not in str(exc.value)


def test_workers_without_dask_is_a_usage_error_that_says_how_to_install_it(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(_EXACT)
    code = (
        "import sys\n"
        "sys.modules['distributed'] = None  # as if dask were not installed\n"
        "from engine.cli import main\n"
        f"raise SystemExit(main(['run', {str(path)!r}, '-o', {str(tmp_path / 'o.nc')!r}, "
        "'--workers', '2']))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 2, done.stderr
    assert "--workers needs dask.distributed" in done.stderr
    assert "-m pip install '.[dask]'" in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]  # nothing written


# -- 8. mistakes that would pass silently -------------------------------------------------

_EXACT = """\
method = "exact"
[axes.alpha]
values = [0.5]
[axes.energy]
values = [5.0, 20.0]
[axes.h]
values = [1.0]
[axes.Lz]
values = [0.8]
"""


@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_survey_whose_energies_all_lie_below_v_min_is_warned_about(tmp_path, capsys, command):
    vmin = float(engine.minimum_energy(0.5, 1.0, 0.8))
    assert vmin > 0.01  # the grid below is all forbidden
    path = tmp_path / "low.toml"
    path.write_text(_EXACT.replace("[5.0, 20.0]", f"[{vmin / 4!r}, {vmin / 2!r}]"))
    args = [command, str(path)] + (["-o", str(tmp_path / "o.nc")] if command == "run" else [])
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "warning: every energy lies below V_min" in err
    assert 'relative_to = "V_min"' in err
    if command == "run":
        with xr.open_dataset(tmp_path / "o.nc") as ds:
            assert (ds.orbit_class.values == engine.CLASS_NAMES.index("forbidden")).all()


def test_a_survey_with_allowed_energies_is_not_warned_about(tmp_path, capsys):
    path = tmp_path / "ok.toml"
    path.write_text(_EXACT)
    assert main(["validate", str(path)]) == 0
    assert "warning" not in capsys.readouterr().err


@pytest.fixture(scope="module")
def slip_map(tmp_path_factory):
    """A closed-form map with a rim and a friction limit (end_r NaN where rolling never
    ends)."""
    out = tmp_path_factory.mktemp("slip") / "slip.nc"
    ds = engine.survey(
        alpha=[0.3, 0.9],
        energy=np.geomspace(1e-3, 3.0, 6),
        h=[-1.0, 1.0],
        Lz=np.linspace(0.2, 1.0, 5),
        scene=Scene(rim=1.5, mu=0.25),
        energy_relative=True,
    )
    ds.to_netcdf(out)
    return out


def test_plot_at_outside_the_axis_range_is_refused_with_range_and_unit(slip_map, tmp_path, capsys):
    out = tmp_path / "m.png"
    assert main(["plot", str(slip_map), "--at", "alpha=30", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--at alpha=30 lies outside the axis alpha: 0.3 .. 0.9 radian" in err
    assert "30 degree is 0.5236 radian" in err
    assert not out.exists()


def test_plot_at_inside_the_axis_range_still_takes_the_nearest_value(slip_map, tmp_path):
    out = tmp_path / "m.png"
    assert main(["plot", str(slip_map), "--at", "alpha=0.5", "-o", str(out)]) == 0
    assert out.exists()


def test_nan_in_end_r_is_labelled_as_never_ending(slip_map):
    from engine.mapspec import plan
    from engine.plot import map_figure

    with xr.open_dataset(slip_map) as ds:
        where = np.argwhere(np.isnan(ds.end_r.values))  # some orbits roll on forever
        assert where.size
        a, _, h, _ = where[0]
        at = {"alpha": float(ds.alpha[a]), "h": float(ds.h[h])}  # a view that holds one
        fig = map_figure(ds, plan(ds, "end_r", x="Lz", y="energy", at=at))
        labels = [t.get_text() for leg in fig.legends for t in leg.get_texts()]
    assert any("never ends" in label for label in labels), labels
    assert "undefined (NaN)" not in labels


# -- 9. the test suite leaves nothing behind ----------------------------------------------


def test_the_store_machine_leaves_no_temporary_directory(tmp_path):
    """Importing the store-machine tests builds their reference file in a temporary directory;
    it must be gone afterwards (it was left in /tmp by every run)."""
    import os

    code = (
        "import importlib.util, sys\n"
        "sys.path[:0] = ['tests', 'tests/io']\n"
        "spec = importlib.util.spec_from_file_location('sm', 'tests/io/test_store_machine.py')\n"
        "spec.loader.exec_module(importlib.util.module_from_spec(spec))\n"
    )
    env = dict(os.environ, TMPDIR=str(tmp_path))
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert list(tmp_path.iterdir()) == []


# -- 6. fate maps are summarised by their fates ---------------------------------------------

_FATE_MAP = """\
title = "fates"
method = "rk45"
rtol = 1e-8
[scene]
M = 0.05
c_rr = 0.02
rim = 1.0
mu = 0.45
[horizon]
time = 30.0
[axes.alpha]
values = [0.6, 1.2, 1.56]
[axes.r0]
values = [0.3, 0.5]
[axes.v0]
values = [0.2, 1.0, 3.0]
[axes.w0]
values = [0.0]
"""


@pytest.fixture(scope="module")
def fate_map(tmp_path_factory):
    d = tmp_path_factory.mktemp("fate")
    (d / "fate.toml").write_text(_FATE_MAP)
    assert main(["run", str(d / "fate.toml"), "-o", str(d / "fate.nc"), "-q"]) == 0
    return d / "fate.nc"


def _fate_counts(path: Path) -> dict[str, int]:
    with xr.open_dataset(path) as ds:
        codes = ds.fate.values.ravel()
    n = np.bincount(codes, minlength=len(engine.FATE_NAMES))
    return dict(zip(engine.FATE_NAMES, n.tolist(), strict=True))


def test_info_lists_the_fates_of_a_fate_map_first(fate_map, capsys):
    assert main(["info", str(fate_map)]) == 0
    out = capsys.readouterr().out
    counts = _fate_counts(fate_map)
    assert sum(counts.values()) == 18 and len([n for n in counts.values() if n]) >= 3
    assert out.index("  fates") < out.index("  classes")
    for name, n in counts.items():
        assert f"    {name:<12}{n:>14,}" in out


def test_the_summary_of_a_fate_map_counts_its_fates(fate_map):
    with xr.open_dataset(fate_map) as ds:
        text = ds.cone.summary()
    counts = _fate_counts(fate_map)
    lines = text.splitlines()
    assert lines[1].startswith("fates of 18 points: ")
    for name, n in counts.items():
        assert (f"{name} {n} (" in lines[1]) == (n > 0)
    assert lines[2].startswith("launch orbits on the ideal cone of 18 points: ")


def test_names_and_counts_of_flag_codes(fate_map):
    with xr.open_dataset(fate_map) as ds:
        names = ds.cone.names("fate")
        codes = ds.fate.values
        assert names.dims == ds.fate.dims
        counted = ds.cone.flag_counts("fate")
    assert (names.values == np.asarray(engine.FATE_NAMES)[codes]).all()
    assert counted == _fate_counts(fate_map)


def test_the_report_of_a_fate_map_shows_the_fate_first(fate_map, tmp_path):
    import re

    out = tmp_path / "r.html"
    assert main(["report", str(fate_map), "-o", str(out)]) == 0
    page = out.read_text()
    maps = re.findall(r'<figure id="map-([^"]+)"', page)
    assert maps[0] == "fate" and maps.index("fate_time") < maps.index("orbit_class")
    assert page.index('id="flags-fate"') < page.index('id="flags-orbit_class"')


def test_long_titles_are_wrapped_to_the_figure(fate_map):
    from engine.mapspec import plan
    from engine.plot import map_figure

    with xr.open_dataset(fate_map) as ds:
        ds.attrs["title"] = "a survey title long enough to be wider than any figure " * 3
        fig = map_figure(ds, plan(ds, "fate", x="v0", y="alpha"))  # a flag legend with a title
    fig.canvas.draw()  # every text stays inside the figure
    box = fig.bbox
    legends = [(leg.get_title(), *leg.get_texts()) for leg in fig.legends]
    for text in [fig._suptitle, *(t for group in legends for t in group)]:
        extent = text.get_window_extent()
        inside = box.x0 - 1 <= extent.x0 and extent.x1 <= box.x1 + 1 and extent.y1 <= box.y1 + 1
        assert inside, text.get_text()


def test_the_cf_checker_test_raises_no_warning():
    """The suite's warnings are fixed or filtered with a reason (pyproject.toml): the CF
    compliance test printed four deprecation warnings of a checker it does not use."""
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:randomly", "-p", "no:cacheprovider",
         "tests/io/test_netcdf.py", "-k", "passes_cf_checker"],
        cwd=ROOT, capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:]
    assert "1 passed" in done.stdout and "warning" not in done.stdout, done.stdout[-3000:]


def test_broadcast_arguments_raise_no_warning():
    """evaluate, minimum_energy and invariants broadcast their arguments; numba warned
    (FutureWarning) on every call that handed it a broadcast view."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for n in (1, 2):  # one point: a broadcast view numpy calls contiguous
            engine.evaluate(0.5, [20.0] * n, 1.0, 0.8)
            engine.minimum_energy(0.5, [1.0] * n, 0.8)
            engine.invariants(0.5, [1.0] * n, 0.0, 1.0, 0.0)

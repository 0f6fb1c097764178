"""``precision = "single"`` in a survey file: the float results are stored as float32 (the
double run's values rounded once to float32), the integer ones (orbit_class) exactly as in a
double run; the file records it, ``validate`` reports it, a bad value is refused naming the
key; the in-memory run and the fingerprint (resume) follow it."""

from __future__ import annotations

import netCDF4
import numpy as np
import pytest
import runs
import xarray as xr

from engine import cli
from engine.io.contents import verify_file
from engine.io.manifest import fingerprint
from engine.plan import plan_from_survey
from engine.runner import run_survey
from engine.surveyfile import SurveyError, parse_survey

DOUBLE = runs.gravity_survey("precision test", alpha=(0.4, 1.1), energy=30, h=9, lz=20)
SINGLE = 'precision = "single"\n' + DOUBLE


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("precision")
    run_survey(parse_survey(DOUBLE), d / "double.nc")
    run_survey(parse_survey(SINGLE), d / "single.nc")
    return d


def _read(path):
    with netCDF4.Dataset(path) as nc:
        nc.set_auto_maskandscale(False)
        assert verify_file(nc)[0]
        attrs = {k: nc.getncattr(k) for k in nc.ncattrs()}
        return {n: np.asarray(v[:]) for n, v in nc.variables.items()}, attrs


def test_single_stores_float32_rounded_once_and_classes_exactly(files):
    double, _ = _read(files / "double.nc")
    single, attrs = _read(files / "single.nc")
    assert "single" in attrs["precision"]
    assert double.keys() == single.keys()
    # the results: on the grid's 4 dims, r_circ on (alpha, h, Lz); the 1-D axes stay float64
    floats = [n for n, v in double.items() if v.dtype.kind == "f" and v.ndim >= 3]
    assert {"r_min", "r_max", "r_circ", "period", "apsidal_angle"} <= set(floats)
    for name, values in double.items():
        if values.ndim < 3:  # the axes stay float64
            assert single[name].dtype == np.float64 and single[name].tobytes() == values.tobytes()
        elif name in floats:
            assert single[name].dtype == np.float32, name
            want = values.astype(np.float32)
            assert np.array_equal(single[name], want, equal_nan=True), name
        else:
            assert single[name].dtype == values.dtype and np.array_equal(single[name], values)
    assert (files / "single.nc").stat().st_size < 0.75 * (files / "double.nc").stat().st_size


def test_the_in_memory_run_and_the_fingerprint_follow_it():
    s, d = parse_survey(SINGLE), parse_survey(DOUBLE)
    assert s.run()["period"].dtype == np.float32 and d.run()["period"].dtype == np.float64
    assert s.run()["orbit_class"].dtype == np.int8
    assert fingerprint(plan_from_survey(s)) != fingerprint(
        plan_from_survey(d)
    )  # a double run's blocks are never resumed as single


def test_validate_reports_it_and_a_bad_value_is_refused(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(SINGLE)
    assert cli.main(["validate", str(tmp_path / "s.toml")]) == 0
    out = capsys.readouterr().out
    assert "precision single" in out and "float32" in out, out
    with pytest.raises(SurveyError, match=r'precision: must be one of double, single, got "half"'):
        parse_survey('precision = "half"\n' + DOUBLE)


def test_a_zarr_store_holds_the_same_float32_values(files, tmp_path):
    run_survey(parse_survey(SINGLE), tmp_path / "s.zarr")
    single, _ = _read(files / "single.nc")
    with xr.open_zarr(tmp_path / "s.zarr") as ds:
        assert ds["period"].dtype == np.float32
        for name in ("period", "r_min", "orbit_class"):
            assert ds[name].values.tobytes() == single[name].tobytes(), name


# --- values float32 cannot hold ----------------------------------------------------------------

F32 = np.finfo(np.float32)


def _extreme(energies: str, lz: str) -> str:
    return f"""title = "extreme"
precision = "single"
[axes.alpha]
values = [0.7]
[axes.energy]
values = [{energies}]
[axes.h]
values = [0.0, 1.0]
[axes.Lz]
values = [{lz}]
"""


def _lost(values: np.ndarray) -> np.ndarray:
    """Where float32 cannot hold a float64 value as what it is: finite beyond its largest, or
    non-zero below its smallest normal magnitude (an independent statement of the rule)."""
    a = np.abs(values[np.isfinite(values)])
    return a[(a > F32.max) | ((a > 0) & (a < F32.tiny))]


EXTREMES = {
    # a bounded orbit with r_max 1.9e39: float32 would store +inf, an escape's marker
    "r_max beyond float32": ("1.0, 2.0, 1e40", "0.25, 0.5", "r_max"),
    # r_min 1.3e-45: float32 keeps one significant bit of it (and 0 below 7e-46)
    "r_min below float32": ("1.0, 1e30", "1e-30, 0.5", "r_min"),
    # r_circ 8.6e39, on (alpha, h, Lz): refused before any block is computed
    "r_circ beyond float32": ("5.0, 1e3", "0.5, 1e60", "r_circ"),
}


@pytest.mark.parametrize("fmt", ["nc", "zarr"])
@pytest.mark.parametrize("case", list(EXTREMES), ids=list(EXTREMES))
def test_a_value_float32_cannot_hold_is_refused_and_nothing_is_left(tmp_path, capsys, fmt, case):
    """The double run of the same survey has the value (found here with numpy, not the rule
    under test); the single run refuses, exit 2, one line naming the variable, the value, the
    point, float32's range and the way out; nothing is left behind."""
    energies, lz, name = EXTREMES[case]
    text = _extreme(energies, lz)
    double = parse_survey(text.replace('precision = "single"\n', "")).run()
    assert _lost(double[name].values).size, "the case must hold a value float32 cannot"
    (tmp_path / "s.toml").write_text(text)
    out = tmp_path / f"out.{fmt}"
    status = cli.main(["run", str(tmp_path / "s.toml"), "-o", str(out), "-q", "--block-points",
                       "4"])  # fmt: skip
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"cannot store {name} = " in err and "float32 holds magnitudes from 1.18e-38 to " in err
    assert "alpha = 0.7" in err and 'precision = "double"' in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_the_in_memory_survey_refuses_it_too():
    with pytest.raises(ValueError, match=r'cannot store r_max = 1\.86589e\+39.*"double"'):
        parse_survey(_extreme("1.0, 1e40", "0.5")).run()


def test_values_float32_holds_are_stored_as_before(tmp_path):
    """Right at float32's edges (a largest r_max and a smallest r_min it holds), the single
    run stores the double run's values rounded once, and every bounded orbit's r_max is
    finite (no stored marker of an escape)."""
    text = _extreme("1.0, 1e37", "1e-15, 0.5")
    double = parse_survey(text.replace('precision = "single"\n', "")).run()
    assert not any(_lost(double[n].values).size for n in ("r_min", "r_max", "period", "r_circ"))
    run_survey(parse_survey(text), tmp_path / "x.nc")
    single, _ = _read(tmp_path / "x.nc")
    for name in ("r_min", "r_max", "period", "r_circ"):
        want = double[name].values.astype(np.float32)
        assert np.array_equal(single[name], want, equal_nan=True), name
    bounded = single["orbit_class"] == 1
    assert bounded.any() and np.isfinite(single["r_max"][bounded]).all()

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

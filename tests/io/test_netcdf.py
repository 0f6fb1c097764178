"""engine.io.netcdf: CF attributes, encodings, round trip and crash safety."""

from __future__ import annotations

import os
import re
import warnings

import netCDF4
import numpy as np
import pytest
import xarray as xr

import engine
from engine.io import netcdf
from engine.io.netcdf import cf_dataset, encoding_for, write_netcdf, write_survey
from engine.plan import plan_from_survey
from engine.surveyfile import parse_survey

# Free fall: B of both signs, so several classes and NaN fields occur. Non-ASCII and quotes
# check that the definition is stored verbatim.
SURVEY_TEXT = """\
# A "small" survey: free fall, \u03b1 in radian
title = "Round trip \u2014 free fall"

[scene]
g = 0.0
rim = 40.0

[axes.alpha]
values = [0.5, 1.0]

[axes.energy]
start = -0.3
stop = 0.3
num = 7

[axes.h]
values = [-2.0, 2.0]

[axes.Lz]
values = [-0.5, 0.5]
"""


@pytest.fixture(scope="module")
def survey():
    return parse_survey(SURVEY_TEXT, origin="roundtrip.toml")


@pytest.fixture(scope="module")
def ds(survey):
    return survey.run()


@pytest.fixture(scope="module")
def ds_relative():
    return engine.survey([0.4], np.geomspace(1e-6, 1.0, 4), [0.0, 1.0], [0.3], energy_relative=True)


#: The name of a temporary file of out.nc (engine.io.atomic.create_new).
TMP = re.compile(r"out\.nc\.[0-9a-f]{12}\.tmp")


def write(ds, path, survey, **kw):
    return write_survey(
        ds, path, plan_from_survey(survey), command="conesurvey run roundtrip.toml", **kw
    )


def test_survey_has_several_classes_and_nans(ds):
    """Guard: the round trip below covers NaN fields and more than one class."""
    assert np.unique(ds.orbit_class.values).size >= 3
    assert np.isnan(ds.r_max.values).any()


def test_round_trip_values_and_attrs(tmp_path, survey, ds):
    path = write(ds, tmp_path / "out.nc", survey)
    assert path == tmp_path / "out.nc"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # opens cleanly: no decoding or CF warnings
        back = xr.open_dataset(path, engine="netcdf4").load()
    back.close()
    expected = cf_dataset(ds, title=survey.title, survey_definition=SURVEY_TEXT, scene=survey.scene)
    assert set(back.data_vars) == set(ds.data_vars)
    assert set(back.coords) == set(ds.coords)
    for name in ds.variables:
        np.testing.assert_array_equal(back[name].values, ds[name].values)  # NaN == NaN here
        assert back[name].dtype == ds[name].dtype, name
        assert back[name].dims == ds[name].dims
        for key, value in expected[name].attrs.items():
            np.testing.assert_array_equal(back[name].attrs[key], value)
        assert set(back[name].attrs) == set(expected[name].attrs), name
    for key, value in expected.attrs.items():
        if key != "history":  # written at its own time stamp
            assert back.attrs[key] == value, key
    assert back.attrs["survey_definition"] == SURVEY_TEXT
    assert back.orbit_class.dtype == np.int8
    assert back.orbit_class.attrs["flag_values"].dtype == np.int8
    np.testing.assert_array_equal(
        back.orbit_class.attrs["flag_values"], np.arange(len(engine.CLASS_NAMES))
    )
    assert back.orbit_class.attrs["flag_meanings"].split() == list(engine.CLASS_NAMES)


def test_global_attributes(tmp_path, survey, ds):
    path = write(ds, tmp_path / "out.nc", survey)
    with xr.open_dataset(path) as back:
        attrs = dict(back.attrs)
    assert attrs["Conventions"] == "CF-1.11"
    assert attrs["title"] == "Round trip \u2014 free fall"
    assert attrs["source"] == f"conesurvey {engine.__version__}"
    assert attrs["method"] == "exact"
    for key, value in survey.scene.as_attrs().items():  # a value not set is left out (CF)
        assert (key not in attrs) if value == "none" else (attrs[key] == value), key
    assert attrs["scene_rim"] == 40.0 and attrs["scene_g"] == 0.0
    history = attrs["history"]
    assert re.match(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ conesurvey run roundtrip\.toml ", history)
    assert "numba threading layer: " in history
    assert engine._jit.threading_layer() in history
    assert list(attrs)[:4] == ["Conventions", "title", "history", "source"]


def test_encodings_on_disk(tmp_path, survey, ds):
    path = write(ds, tmp_path / "out.nc", survey, compression="zlib")
    with netCDF4.Dataset(path) as nc:
        assert nc.data_model == "NETCDF4"
        for name in ("alpha", "energy", "h", "Lz"):
            var = nc.variables[name]
            assert "_FillValue" not in var.ncattrs(), name
            assert var.dtype == np.float64
        for name in ds.data_vars:
            filters = nc.variables[name].filters()
            assert filters["zlib"] and filters["shuffle"] and filters["complevel"] == 1, name
        cls = nc.variables["orbit_class"]
        assert cls.dtype == np.int8
        assert cls.getncattr("flag_values").dtype == np.int8
        assert isinstance(nc.getncattr("survey_definition"), str)


def test_encoding_for_separates_coordinates_and_data(ds):
    enc = encoding_for(ds, "zlib")
    for name in ("alpha", "energy", "h", "Lz"):
        assert enc[name] == {"_FillValue": None}
    assert enc["orbit_class"]["dtype"] == np.int8
    assert enc["r_min"] == {
        "compression": "zlib",
        "complevel": 1,
        "shuffle": True,
        "dtype": np.float64,
    }


def test_blosc_is_kept_from_variables_smaller_than_a_chunk_it_can_shrink(ds):
    """blosc_lz4 for a variable of >= 64 KiB; zstd for a smaller one, where
    HDF5's blosc filter would fail on a chunk it cannot shrink (engine.io.codecs)."""
    big = ds.isel(alpha=[0] * 512)  # 512 x 7 x 2 x 2 points: 114,688 bytes of float64
    assert big.r_min.nbytes >= 1 << 16 > ds.r_min.nbytes
    assert encoding_for(big, "blosc_lz4")["r_min"]["compression"] == "blosc_lz4"
    assert encoding_for(big, "blosc_lz4")["r_min"]["blosc_shuffle"] == 1
    assert encoding_for(ds, "blosc_lz4")["r_min"]["compression"] == "zstd"
    assert encoding_for(ds)["r_min"]["compression"] == "zlib"  # the default
    assert encoding_for(big, "zstd", 3)["r_min"]["complevel"] == 3


def test_v_min_and_relative_axis_round_trip(tmp_path, ds_relative):
    full = cf_dataset(ds_relative, title="rel", survey_definition="x = 1\n")
    path = write_netcdf(full, tmp_path / "rel.nc")
    with xr.open_dataset(path) as back:
        assert back.energy.attrs["units"] == "1"
        assert back.V_min.attrs["units"] == "J" and back.V_min.dims == ("alpha", "h", "Lz")
        np.testing.assert_array_equal(back.V_min.values, ds_relative.V_min)
        np.testing.assert_array_equal(
            back.cone.energy_absolute().values, ds_relative.cone.energy_absolute().values
        )


def test_cf_dataset_does_not_modify_its_input_and_prepends_history(ds):
    before = dict(ds.attrs)
    first = cf_dataset(ds, title="t", survey_definition="a = 1\n", command="first")
    second = cf_dataset(first, title="t", survey_definition="a = 1\n", command="second")
    assert ds.attrs == before
    lines = second.attrs["history"].split("\n")
    assert len(lines) == 2
    assert " second " in lines[0] and " first " in lines[1]


def test_flag_values_are_made_int8(ds):
    bad = ds.copy()
    bad["orbit_class"] = bad.orbit_class.copy()
    bad.orbit_class.attrs["flag_values"] = [0, 1, 2, 3, 4, 5]  # a list would be written int64
    fixed = cf_dataset(bad, title="t", survey_definition="")
    assert fixed.orbit_class.attrs["flag_values"].dtype == np.int8
    assert isinstance(bad.orbit_class.attrs["flag_values"], list)  # input untouched


# --- crash safety -----------------------------------------------------------------------------


def listing(directory):
    return sorted(p.name for p in directory.iterdir())


def test_existing_output_is_not_clobbered(tmp_path, survey, ds):
    path = tmp_path / "out.nc"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError) as info:
        write(ds, path, survey)
    assert str(path) in str(info.value)
    assert path.read_bytes() == b"precious"
    assert listing(tmp_path) == ["out.nc"]


def test_overwrite_replaces_existing_output(tmp_path, survey, ds):
    path = tmp_path / "out.nc"
    path.write_bytes(b"old")
    write(ds, path, survey, overwrite=True)
    with xr.open_dataset(path) as back:
        assert back.sizes["energy"] == 7
    assert listing(tmp_path) == ["out.nc"]


def test_error_while_writing_keeps_existing_output_and_removes_tmp(tmp_path, ds):
    path = tmp_path / "out.nc"
    path.write_bytes(b"precious")
    bad = ds.copy()
    bad.attrs = {"not_allowed": {"a": 1}}  # xarray refuses dict attributes (xarray#3743)
    with pytest.raises(TypeError):
        write_netcdf(bad, path, overwrite=True)
    assert path.read_bytes() == b"precious"
    assert listing(tmp_path) == ["out.nc"]


def test_interrupt_before_rename_leaves_nothing(tmp_path, ds, monkeypatch):
    seen = []

    def interrupted(p):
        seen.append(p)
        assert p.exists()  # the full .tmp file was written before the interrupt
        raise KeyboardInterrupt

    monkeypatch.setattr(netcdf, "fsync_path", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_netcdf(ds, tmp_path / "out.nc")
    assert len(seen) == 1 and TMP.fullmatch(seen[0].name) and seen[0].parent == tmp_path
    assert listing(tmp_path) == []


def test_output_created_meanwhile_is_not_clobbered(tmp_path, ds, monkeypatch):
    """Another process creates the output while we write: the final rename must not replace it."""
    path = tmp_path / "out.nc"
    real_fsync_path = netcdf.fsync_path

    def racing(p):
        real_fsync_path(p)
        path.write_bytes(b"theirs")

    monkeypatch.setattr(netcdf, "fsync_path", racing)
    with pytest.raises(FileExistsError):
        write_netcdf(ds, path)
    assert path.read_bytes() == b"theirs"
    assert listing(tmp_path) == ["out.nc"]


def test_stale_tmp_file_is_left_alone(tmp_path, ds):
    """A temporary file another writer (or a crashed one) left is neither reused nor written
    through: each write makes its own."""
    (tmp_path / "out.nc.tmp").write_bytes(b"left by a crashed run")
    write_netcdf(ds, tmp_path / "out.nc")
    assert listing(tmp_path) == ["out.nc", "out.nc.tmp"]
    assert (tmp_path / "out.nc.tmp").read_bytes() == b"left by a crashed run"
    with xr.open_dataset(tmp_path / "out.nc") as back:
        assert back.sizes == ds.sizes


def test_file_and_directory_are_fsynced(tmp_path, ds, monkeypatch):
    synced = []
    real_fsync = os.fsync

    def spy(fd):
        synced.append(os.readlink(f"/proc/self/fd/{fd}") if os.path.exists("/proc/self") else fd)
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", spy)
    write_netcdf(ds, tmp_path / "out.nc")
    if os.path.exists("/proc/self"):
        assert len(synced) == 2 and synced[1] == str(tmp_path)
        assert TMP.fullmatch(os.path.basename(synced[0])), synced
    else:
        assert len(synced) == 2


# --- CF compliance (runs where the optional `compliance-checker` package is installed) ---------


def cf_problems(path) -> tuple[bool, list[str]]:
    import json

    runner = pytest.importorskip("compliance_checker.runner")
    runner.CheckSuite.load_all_available_checkers()
    report_path = f"{path}.json"
    ok, _ = runner.ComplianceChecker.run_checker(
        str(path), ["cf:1.11"], 0, "normal", output_filename=report_path, output_format="json"
    )
    with open(report_path, encoding="utf-8") as f:
        report = json.load(f)["cf:1.11"]
    msgs = [
        m
        for level in ("high_priorities", "medium_priorities")
        for item in report[level]
        for m in item["msgs"]
    ]
    return ok, msgs


def test_output_passes_cf_checker(tmp_path, survey, ds, ds_relative):
    path = write(ds, tmp_path / "out.nc", survey)
    assert cf_problems(path) == (True, [])
    rel = cf_dataset(ds_relative, title="rel", survey_definition="x = 1\n")
    assert cf_problems(write_netcdf(rel, tmp_path / "rel.nc")) == (True, [])


def test_cf_checker_catches_a_planted_error(tmp_path, ds):
    """Guard for the test above: a plain to_netcdf (int64 flags, coordinate fill values) fails."""
    bad = ds.copy()
    bad["orbit_class"] = bad.orbit_class.copy()
    bad.orbit_class.attrs["flag_values"] = [0, 1, 2, 3, 4, 5]
    bad.to_netcdf(tmp_path / "bad.nc")
    ok, msgs = cf_problems(tmp_path / "bad.nc")
    assert not ok
    assert any("flag_values" in m for m in msgs)

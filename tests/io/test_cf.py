"""The scene's and the horizon's global attributes have one type in every file, with units: a
number is a float64, a flag an int64, a value that is not set an absent attribute (CF), never
the string "none"; ``parameter_units`` names the unit of each."""

from __future__ import annotations

import netCDF4
import numpy as np
import pytest
import xarray as xr

from engine.horizon import Horizon
from engine.io.cf import UNITS_ATTR, cf_attrs
from engine.runner import run_survey
from engine.scene import Scene
from engine.schema import result_attrs
from engine.surveyfile import parse_survey

SURVEY = """\
title = "cf attributes"
{scene}
[axes.alpha]
values = [0.5]

[axes.energy]
values = [0.5, 1.0]
relative_to = "V_min"

[axes.h]
values = [0.0]

[axes.Lz]
values = [0.5, 1.0]
"""

#: The units a reader needs, as docs/physics.md states them for the scene's fields.
UNITS = {"scene_M": "kg", "scene_g": "m s-2", "scene_a": "m", "scene_k": "1",
         "scene_rim": "m", "scene_c_rr": "1", "scene_attitude": "1"}  # fmt: skip


def _units(text: str) -> dict[str, str]:
    return dict(part.split(": ") for part in text.split(", "))


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_scene_attributes_have_one_type_in_every_file(tmp_path, suffix):
    with_rim = run_survey(parse_survey(SURVEY.format(scene="[scene]\nrim = 40.0\n")),
                          tmp_path / f"rim{suffix}", warn=lambda m: None)  # fmt: skip
    without = run_survey(parse_survey(SURVEY.format(scene="")), tmp_path / f"inf{suffix}",
                         warn=lambda m: None)  # fmt: skip
    engine = "zarr" if suffix == ".zarr" else "netcdf4"
    a = xr.open_dataset(with_rim.path, engine=engine).attrs
    b = xr.open_dataset(without.path, engine=engine).attrs
    assert float(a["scene_rim"]) == 40.0
    assert "scene_rim" not in b and "scene_mu" not in a and "scene_mu" not in b  # not set
    for attrs in (a, b):
        assert not any(isinstance(v, str) and v == "none" for v in attrs.values())
        units = _units(attrs[UNITS_ATTR])
        for key in attrs:
            if key.startswith("scene_") or key.startswith("horizon_"):
                assert key in units, key
        for key, unit in UNITS.items():
            if key in attrs:
                assert units[key] == unit
    assert "scene_rim" not in _units(b[UNITS_ATTR])
    if suffix == ".nc":  # the stored type, as netCDF tools see it
        with netCDF4.Dataset(with_rim.path) as nc, netCDF4.Dataset(without.path) as nc2:
            for f in (nc, nc2):
                for key in ("scene_M", "scene_g", "scene_c_rr"):
                    assert np.asarray(f.getncattr(key)).dtype == np.float64, key
                assert np.asarray(f.getncattr("scene_attitude")).dtype == np.int64
            assert np.asarray(nc.getncattr("scene_rim")).dtype == np.float64


def test_a_horizon_not_set_is_absent_not_a_string():
    attrs = result_attrs(Scene(rim=3.0), "rk45", 1e-12, 1e-9, Horizon(time=5.0))
    out = cf_attrs(attrs, title="t", survey_definition="")
    assert out["horizon_time"] == 5.0 and isinstance(out["horizon_time"], np.float64)
    assert "horizon_revolutions" not in out
    assert "horizon_time: s" in out[UNITS_ATTR]
    # an older file's "none" is dropped when its attributes are written again (convert)
    again = cf_attrs({**attrs, "horizon_revolutions": "none", "scene_mu": "none"},
                     title="t", survey_definition="")  # fmt: skip
    assert "horizon_revolutions" not in again and "scene_mu" not in again

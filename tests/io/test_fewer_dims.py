"""Variables stored on fewer dims (engine.schema.variable_dims): r_circ and V_min depend on
(alpha, h, L_z) only and are stored on those dims, in every format, by every path that writes
or reads an output (a streamed run, resume, convert, an unfinished run, the in-memory survey)."""

import netCDF4
import numpy as np
import pytest
import xarray as xr

import engine
from engine import backends, cli
from engine.evaluation import evaluate_flat
from engine.io.formats import format_for
from engine.io.results import open_result
from engine.plan import map_plan
from engine.schema import DIMS
from engine.surveyfile import load_survey

FEWER = ("alpha", "h", "Lz")
SURVEY = """title = "fewer dims"
method = "exact"
[scene]
g = 9.81
k = 0.4
[axes.alpha]
values = [0.4, 0.8, 1.1, 1.3]
[axes.energy]
start = 1e-6
stop = 10.0
num = 40
scale = "log"
relative_to = "V_min"
[axes.h]
start = -2.0
stop = 2.0
num = 30
[axes.Lz]
start = 0.0
stop = 2.0
num = 30
"""


@pytest.fixture(scope="module")
def toml(tmp_path_factory):
    path = tmp_path_factory.mktemp("fewer") / "fewer.toml"
    path.write_text(SURVEY)
    return path


@pytest.fixture(scope="module")
def memory(toml):
    """The survey in memory (engine.api.run_plan)."""
    return load_survey(toml).run()


def _run(toml, out, *extra):
    # 144,000 points in storage chunks (4, 20, 15, 30): 4 blocks of one chunk each
    return cli.main(["run", str(toml), "-o", str(out), "-q", "--block-points", "36000", *extra])


@pytest.fixture(scope="module")
def outputs(toml):
    out = {}
    for suffix in (".nc", ".zarr"):
        out[suffix] = toml.with_name("fewer" + suffix)
        assert _run(toml, out[suffix]) == 0
    return out


def test_in_memory_survey_has_r_circ_and_v_min_on_alpha_h_lz(memory):
    ds = memory
    assert ds.r_circ.dims == ds.V_min.dims == FEWER and ds.r_min.dims == DIMS
    assert "energy_absolute" not in ds
    assert np.isnan(ds.V_min.values[:, :, 0]).all()  # L_z = 0: no minimum
    assert np.isfinite(ds.r_circ.values[:, :, 1:]).all()
    # each point's own r_circ (the former per-point variable), bit for bit where it has one
    A, _, H, L = (x.values.reshape(-1) for x in xr.broadcast(ds.alpha, ds.energy, ds.h, ds.Lz))
    e_abs = ds.cone.energy_absolute().values.reshape(-1)
    per_point = evaluate_flat(A, e_abs, H, L, map_plan(engine.Scene(g=9.81, k=0.4)))
    mine = np.broadcast_to(ds.r_circ.values[:, None], ds.orbit_class.shape).reshape(-1)
    rc = per_point["r_circ"]
    assert np.isfinite(rc).sum() > 50 and np.array_equal(rc[np.isfinite(rc)], mine[np.isfinite(rc)])
    assert np.array_equal(per_point["r_min"], ds.r_min.values.reshape(-1), equal_nan=True)


@pytest.mark.parametrize(("suffix", "engine_name"),
                         [(".nc", "netcdf4"), (".nc", "h5netcdf"), (".zarr", "zarr")])  # fmt: skip
def test_outputs_store_them_on_fewer_dims(outputs, memory, suffix, engine_name):
    with xr.open_dataset(outputs[suffix], engine=engine_name) as back:
        assert back.r_circ.dims == back.V_min.dims == FEWER
        assert back.r_min.dims == back.orbit_class.dims == DIMS
        assert "energy_absolute" not in back
        assert back.r_circ.attrs["units"] == "m" and back.V_min.attrs["units"] == "J"
        assert "long_name" in back.V_min.attrs
        assert set(back.data_vars) == set(memory.data_vars)
        for name in memory.data_vars:
            assert np.array_equal(back[name].values, memory[name].values, equal_nan=True), name
    info = format_for(outputs[suffix]).read_info(outputs[suffix], verify=True)
    assert info["verified"][0], info["verified"]
    assert tuple(info["dims"]) == DIMS  # `info` says the grid in its order, in both formats


def test_netcdf_variable_dims_as_written(outputs):
    with netCDF4.Dataset(outputs[".nc"]) as nc:
        assert nc["r_circ"].dimensions == nc["V_min"].dimensions == FEWER
        assert nc["r_circ"].filters()["zlib"] and nc["r_circ"].filters()["shuffle"]


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_resume_after_an_interrupt_gives_the_same_output(tmp_path, toml, outputs, suffix,
                                                          monkeypatch):  # fmt: skip
    out = tmp_path / ("resumed" + suffix)
    original = backends.evaluate_block
    calls = []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) > 2:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(backends, "evaluate_block", interrupted)
    assert _run(toml, out) == 130
    with open_result(out) as part:  # the unfinished run: computed from its survey
        assert not part.complete and part.ds.r_circ.dims == FEWER
        with xr.open_dataset(outputs[".nc"]) as done:
            assert np.array_equal(part.ds.r_circ.values, done.r_circ.values, equal_nan=True)
    monkeypatch.setattr(backends, "evaluate_block", original)
    assert _run(toml, out) == 0
    with xr.open_dataset(out, engine="zarr" if suffix == ".zarr" else "netcdf4") as a:
        with xr.open_dataset(outputs[suffix], engine="zarr" if suffix == ".zarr" else None) as b:
            assert a.attrs["content_checksum"] == b.attrs["content_checksum"]
            assert a.r_circ.dims == FEWER
            for name in b.data_vars:
                assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name


def test_convert_keeps_them(tmp_path, outputs, memory):
    zarr_copy, nc_copy = tmp_path / "copy.zarr", tmp_path / "copy.nc"
    assert cli.main(["convert", str(outputs[".nc"]), str(zarr_copy)]) == 0
    assert cli.main(["convert", str(zarr_copy), str(nc_copy)]) == 0
    for path in (zarr_copy, nc_copy):
        assert format_for(path).read_info(path, verify=True)["verified"][0]
        with xr.open_dataset(path, engine="zarr" if path.suffix == ".zarr" else None) as back:
            assert back.r_circ.dims == back.V_min.dims == FEWER
            for name in memory.data_vars:
                assert np.array_equal(back[name].values, memory[name].values, equal_nan=True)
    with netCDF4.Dataset(nc_copy) as a, netCDF4.Dataset(outputs[".nc"]) as b:
        assert a.content_checksum == b.content_checksum  # the same contents, the same checksum
        assert a["r_circ"].chunking() == b["r_circ"].chunking()


def test_energy_absolute_from_the_accessor(memory):
    ds = memory
    e = ds.cone.energy_absolute()
    assert e.dims == DIMS and e.attrs["units"] == "J"
    vmin = ds.V_min.values[:, None]
    assert np.array_equal(e.values, vmin + ds.energy.values[None, :, None, None] * np.abs(vmin),
                          equal_nan=True)  # fmt: skip
    absolute = engine.survey([0.4], [1.0], [0.0], [0.3])
    with pytest.raises(ValueError, match="no 'V_min'"):
        absolute.cone.energy_absolute()

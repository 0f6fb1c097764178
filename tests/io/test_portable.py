"""The default output is read by every netCDF-4 tool with no HDF5 filter plugin: Debian's
``ncdump`` and ``h5dump`` (netcdf-bin, hdf5-tools; installed by .ci/system-packages) and xarray's
netcdf4 and h5netcdf engines, each run with ``HDF5_PLUGIN_PATH`` set to an empty directory.
The chunks it writes directly (engine.io.deflate) are the bytes HDF5's own shuffle and
deflate filters make, so the values are those of an uncompressed run, bit for bit."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zlib

import h5py
import netCDF4
import numpy as np
import pytest
import runs

from engine.io import codecs, deflate
from engine.io.contents import verify_file
from engine.runner import run_survey
from engine.surveyfile import parse_survey

# 3 x 40 x 33 x 70 = 277,200 points; chunks (3, 20, 33, 18): the last chunk along Lz hangs
# over the grid's edge (70 = 3 x 18 + 16), so edge chunks are written too.
SURVEY = runs.gravity_survey("portable default", alpha=(0.3, 0.8, 1.3), energy=40, h=33, lz=70)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("portable")
    s = parse_survey(SURVEY)
    notices: list[str] = []
    run_survey(s, d / "default.nc", block_points=70_000, warn=notices.append)
    run_survey(s, d / "none.nc", block_points=70_000, compression="none")
    (d / "plugins").mkdir()  # an empty HDF5 plugin directory: no filter plugin anywhere
    return d, notices


def _env(files) -> dict[str, str]:
    return runs.env(HDF5_PLUGIN_PATH=str(files[0] / "plugins"))


def _values(path) -> dict[str, np.ndarray]:
    with netCDF4.Dataset(path) as nc:
        nc.set_auto_maskandscale(False)
        return {name: np.asarray(v[:]) for name, v in nc.variables.items()}


def test_the_default_is_deflate_with_shuffle_and_says_nothing(files):
    d, notices = files
    assert codecs.DEFAULT_COMPRESSION == "zlib" and notices == []
    with netCDF4.Dataset(d / "default.nc") as nc:
        assert nc["r_min"].chunking() == [3, 20, 33, 18]
        for name in ("r_min", "orbit_class"):
            f = nc[name].filters()
            assert f["zlib"] and f["shuffle"] and f["complevel"] == 1, (name, f)
            assert not f["blosc"] and not f["zstd"], (name, f)
        assert verify_file(nc)[0]
    ref, got = _values(d / "none.nc"), _values(d / "default.nc")
    assert ref.keys() == got.keys()
    for name in ref:
        assert got[name].tobytes() == ref[name].tobytes(), name
    assert (d / "default.nc").stat().st_size < 0.8 * (d / "none.nc").stat().st_size


def test_debian_ncdump_reads_every_value_without_plugins(files):
    assert shutil.which("ncdump"), "needs Debian's ncdump (netcdf-bin): bash .ci/system-packages"
    d, _ = files
    proc = subprocess.run(
        ["ncdump", "-p", "9,17", "-v", "period,orbit_class", str(d / "default.nc")],
        env=_env(files), capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    data = proc.stdout.split("data:", 1)[1]
    ref = _values(d / "none.nc")
    for name in ("period", "orbit_class"):
        text = data.split(f" {name} =", 1)[1].split(";", 1)[0]
        words = [w.strip() for w in text.replace("\n", " ").split(",")]
        printed = np.array([np.nan if w == "_" else float(w) for w in words])
        want = ref[name].ravel().astype(np.float64)
        assert np.array_equal(printed, want, equal_nan=True), name  # 17 digits: exact


def test_debian_h5dump_reads_a_variable_without_plugins(files):
    assert shutil.which("h5dump"), "needs Debian's h5dump (hdf5-tools): bash .ci/system-packages"
    d, _ = files
    out = d / "r_max.bin"
    proc = subprocess.run(
        ["h5dump", "-d", "/r_max", "-b", "LE", "-o", str(out), str(d / "default.nc")],
        env=_env(files), capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0 and "error" not in proc.stderr.lower(), proc.stderr
    got = np.fromfile(out, dtype="<f8")
    assert got.tobytes() == _values(d / "none.nc")["r_max"].astype("<f8").tobytes()


READ = """\
import sys, json, numpy as np, xarray as xr
with xr.open_dataset(sys.argv[1], engine=sys.argv[2], mask_and_scale=False) as ds:
    print(json.dumps({n: ds[n].values.tobytes().hex() for n in ds.data_vars}))
"""


@pytest.mark.parametrize("engine", ["netcdf4", "h5netcdf"])
def test_xarray_engines_read_every_value_without_plugins(files, engine):
    d, _ = files
    proc = subprocess.run(
        [sys.executable, "-c", READ, str(d / "default.nc"), engine],
        env=_env(files), capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    ref = _values(d / "none.nc")
    assert set(got) == set(ref) - {"alpha", "energy", "h", "Lz"}
    for name, hexed in got.items():
        assert bytes.fromhex(hexed) == ref[name].tobytes(), (engine, name)


def test_blosc_output_is_what_those_readers_cannot_open(files, tmp_path):
    """The former default, as a control: the same reader, the same empty plugin directory,
    fails on a blosc_lz4 file (so the tests above would see a plugin if one were used)."""
    run_survey(parse_survey(SURVEY), tmp_path / "b.nc", compression="blosc_lz4")
    proc = subprocess.run(
        ["ncdump", "-v", "period", str(tmp_path / "b.nc")],
        env=_env(files), capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode != 0 and "filter" in proc.stderr.lower(), proc.stderr


@pytest.mark.parametrize("dtype", ["<f8", "<f4", "i1", "<i4"])
def test_a_chunk_is_the_bytes_hdf5s_own_filters_make(tmp_path, dtype):
    """HDF5 compresses a chunk itself (h5py, shuffle + gzip); its stored bytes, inflated, are
    what engine.io.deflate.shuffle makes; and a chunk compressed by compress_chunk at each
    level reads back through HDF5's filters as the values."""
    rng = np.random.default_rng(3)
    values = (rng.standard_normal((4, 6, 5)) * 1e3).astype(dtype)
    with h5py.File(tmp_path / "h.h5", "w") as f:
        dset = f.create_dataset("v", data=values, chunks=values.shape, shuffle=True, compression=1)
        _, stored = dset.id.read_direct_chunk((0, 0, 0))
        assert zlib.decompress(stored) == deflate.shuffle(values)
        for level in (1, 3, 4, 9):
            dset.id.write_direct_chunk((0, 0, 0), deflate.compress_chunk(values, level))
            assert dset[...].tobytes() == values.tobytes(), level


def test_a_compression_this_library_cannot_write_falls_back_to_zlib(tmp_path, monkeypatch):
    """A default never fails: blosc_lz4 where the netCDF library has no blosc filter writes
    zlib, and says so in one line."""
    monkeypatch.setattr(codecs, "_cannot_write", lambda kw: "filter 32001 not available")
    notices: list[str] = []
    s = parse_survey(runs.free_fall_survey("no blosc here"))
    run_survey(s, tmp_path / "a.nc", compression="blosc_lz4", warn=notices.append)
    assert len(notices) == 1 and "\n" not in notices[0], notices
    assert "'blosc_lz4' cannot be written" in notices[0] and "writing zlib" in notices[0]
    with netCDF4.Dataset(tmp_path / "a.nc") as nc:
        assert nc["r_min"].filters()["zlib"] and verify_file(nc)[0]


def test_without_h5py_zlib_is_written_by_netcdf4_with_a_notice(files, tmp_path, monkeypatch):
    monkeypatch.setattr("engine.io.deflate.unavailable", lambda: "h5py is not installed")
    notices: list[str] = []
    s = parse_survey(SURVEY)
    run_survey(s, tmp_path / "a.nc", block_points=70_000, warn=notices.append)
    assert len(notices) == 1 and "h5py is not installed" in notices[0], notices
    ref, got = _values(files[0] / "none.nc"), _values(tmp_path / "a.nc")
    assert all(got[n].tobytes() == ref[n].tobytes() for n in ref)


def test_where_h5py_cannot_open_the_file_netcdf4_writes_it_with_a_notice(
    files, tmp_path, monkeypatch
):
    def refuse(path, names):
        raise OSError("unable to open file (file signature not found)")

    monkeypatch.setattr("engine.io.deflate.DirectChunks", refuse)
    notices: list[str] = []
    run_survey(parse_survey(SURVEY), tmp_path / "a.nc", block_points=70_000, warn=notices.append)
    assert len(notices) == 1 and "h5py cannot write" in notices[0], notices
    ref, got = _values(files[0] / "none.nc"), _values(tmp_path / "a.nc")
    assert all(got[n].tobytes() == ref[n].tobytes() for n in ref)
    with netCDF4.Dataset(tmp_path / "a.nc") as nc:
        assert nc["period"].filters()["zlib"] and verify_file(nc)[0]

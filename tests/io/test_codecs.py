"""engine.io.codecs and ``--compression``: every choice stores the same values bit for bit and
opens with plain xarray; a bad choice is refused before anything is written; a chunk blosc
cannot write makes the merge write that variable with zstd instead."""

from __future__ import annotations

import netCDF4
import numpy as np
import pytest
import runs
import xarray as xr

from engine import cli
from engine.backends import compute_block
from engine.grid import Tiling
from engine.io import codecs, netcdf
from engine.io.blocks import BlockStore
from engine.io.contents import CHECKSUM_ATTR, verify_file
from engine.io.manifest import Manifest, fingerprint, parts_dir
from engine.plan import plan_from_survey
from engine.runner import RunError, run_survey
from engine.surveyfile import parse_survey

# 2 x 64 x 8 x 16 = 16,384 points in one block and chunk: 128 KiB of float64 (blosc), 16 KiB
# of int8 (orbit_class: zstd, see engine.io.codecs.SMALL_CHUNK_BYTES).
SURVEY = runs.gravity_survey("codecs test", alpha=(0.4, 1.1), energy=64, h=8, lz=16)


def _raw(path) -> dict[str, bytes]:
    """Every variable's stored values as raw bytes (NaN payloads included)."""
    with netCDF4.Dataset(path) as nc:
        nc.set_auto_maskandscale(False)
        return {name: np.asarray(v[:]).tobytes() for name, v in nc.variables.items()}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("codecs")
    s = parse_survey(SURVEY)
    for name in codecs.COMPRESSIONS:
        run_survey(s, d / f"{name}.nc", compression=name, warn=print)
    return d


def test_every_compression_stores_the_same_values_bit_for_bit(files):
    ref = _raw(files / "none.nc")
    assert len(ref) == 4 + 9
    for name in codecs.COMPRESSIONS:
        assert _raw(files / f"{name}.nc") == ref, name
        with netCDF4.Dataset(files / f"{name}.nc") as nc:
            assert verify_file(nc)[0], name
            checksum = nc.getncattr(CHECKSUM_ATTR)
        with netCDF4.Dataset(files / "none.nc") as nc:
            assert checksum == nc.getncattr(CHECKSUM_ATTR)


def test_each_file_has_the_filters_asked_for_and_opens_with_plain_xarray(files):
    sizes = {}
    for name in codecs.COMPRESSIONS:
        path = files / f"{name}.nc"
        sizes[name] = path.stat().st_size
        with xr.open_dataset(path) as ds:  # no engine or plugin named: the default reader
            assert ds.r_min.shape == (2, 64, 8, 16)
            assert np.isfinite(ds.r_min.values).any()
        with netCDF4.Dataset(path) as nc:
            period = nc["period"].filters()
            cls = nc["orbit_class"].filters()
        if name == "blosc_lz4":
            assert period["blosc"] == {"compressor": "blosc_lz4", "shuffle": 1}
            assert cls["zstd"] and not cls["blosc"]  # 16 KiB chunks: too small for blosc
        elif name == "zstd":
            assert period["zstd"] and cls["zstd"]
        elif name == "zlib":
            assert period["zlib"] and period["shuffle"] and period["complevel"] == 1
        else:
            assert not any(period[k] for k in ("zlib", "zstd", "blosc", "shuffle"))
    # zstd 1 without shuffle shrinks these ~1.09x (1.3x while r_circ, which repeats along the
    # energy axis, was stored per point); the others ~1.3x
    assert sizes["none"] > 1.05 * max(sizes[n] for n in ("blosc_lz4", "zstd", "zlib")), sizes
    assert sizes["none"] > 1.2 * max(sizes[n] for n in ("blosc_lz4", "zlib")), sizes


def test_bad_compression_option_exits_2_naming_it_and_writes_nothing(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(runs.free_fall_survey("bad option"))
    out = tmp_path / "out.nc"
    for args, named in (
        (["--compression", "lzma"], ("--compression", "lzma")),
        (["--complevel", "12"], ("--complevel", "12")),
    ):
        with pytest.raises(SystemExit) as exc:
            cli.main(["run", str(tmp_path / "s.toml"), "-o", str(out), *args])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert all(word in err for word in named), err
    assert runs.listing(tmp_path) == ["s.toml"]


def test_run_survey_refuses_a_compression_before_writing(tmp_path):
    s = parse_survey(runs.free_fall_survey("bad compression"))
    with pytest.raises(RunError, match="compression must be one of .*; got 'lz77'"):
        run_survey(s, tmp_path / "a.nc", compression="lz77")
    with pytest.raises(RunError, match="complevel must be an integer 0..9; got 10"):
        run_survey(s, tmp_path / "a.nc", complevel=10)
    assert runs.listing(tmp_path) == []


def test_a_chunk_blosc_cannot_shrink_is_written_with_zstd(tmp_path):
    """Random bits in r_min: blosc cannot shrink its 64 KiB chunks (HDF5's filter fails); the
    merge writes the file again from the store with r_min in zstd, says so, and every value
    is kept bit for bit."""
    lz = tuple(0.1 + 0.01 * i for i in range(128))
    survey = parse_survey(runs.free_fall_survey("incompressible", energy=64, lz=lz))
    tiling = Tiling(survey.shape, (1, 64, 2, 64), (1, 64, 2, 64))  # 8,192 points a block
    out = tmp_path / "out.nc"
    store = BlockStore.create(parts_dir(out), Manifest.new(plan_from_survey(survey), tiling))
    rng = np.random.default_rng(7)
    spec = plan_from_survey(survey)
    for i in range(tiling.nblocks):
        arrays = compute_block(spec, tiling, i)[1]
        shape = arrays["r_min"].shape
        arrays["r_min"] = rng.integers(0, 1 << 62, shape).view(np.float64)
        store.commit(i, arrays)
    warnings: list[str] = []
    netcdf.merge(
        store, spec, out, fingerprint=fingerprint(spec), compression="blosc_lz4",
        warn=warnings.append,
    )  # fmt: skip
    assert len(warnings) == 1 and "r_min" in warnings[0] and "zstd" in warnings[0], warnings
    with netCDF4.Dataset(out) as nc:
        assert nc["r_min"].filters()["zstd"]
        assert nc["period"].filters()["blosc"]
        assert verify_file(nc)[0]
        nc.set_auto_maskandscale(False)
        for i in range(tiling.nblocks):
            block = store.load(i)
            for name, values in block.items():
                got = np.asarray(nc[name][tiling.slices(i)])
                assert got.tobytes() == values.tobytes(), (i, name)

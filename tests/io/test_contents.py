"""engine.io.contents: the content checksum of a result file, and its verification."""

from __future__ import annotations

import netCDF4
import pytest
import runs

from engine.grid import Tiling
from engine.io.contents import CHECKSUM_ATTR, CHECKSUM_BLOCK_ATTR, verify_file
from engine.runner import run_survey
from engine.surveyfile import parse_survey

SURVEY = runs.gravity_survey("contents test", alpha=(0.3, 0.6, 0.9), energy=40, lz=60)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The survey written uncompressed (z0), zlib level 1 (z1) and with the default
    compression (blosc), in blocks of 2^14 points."""
    d = tmp_path_factory.mktemp("contents")
    s = parse_survey(SURVEY)
    for name, kw in (("z1", {"compression": "zlib"}), ("z0", {"complevel": 0}), ("blosc", {})):
        run_survey(s, d / f"{name}.nc", block_points=1 << 14, **kw)
    return d


def verify(path):
    with netCDF4.Dataset(path) as nc:
        return verify_file(nc)


def test_a_fresh_file_verifies_and_records_its_scheme(files):
    for name in ("z0", "z1", "blosc"):
        assert verify(files / f"{name}.nc") == (
            True,
            "every value and attribute matches the recorded checksum",
        )
    with netCDF4.Dataset(files / "z1.nc") as nc:
        assert nc.getncattr(CHECKSUM_ATTR).startswith("sha256-v1:")
        assert len(nc.getncattr(CHECKSUM_ATTR)) == len("sha256-v1:") + 64
        block = Tiling.for_grid(parse_survey(SURVEY).shape, 1 << 14).block
        assert list(nc.getncattr(CHECKSUM_BLOCK_ATTR)) == list(block)


def test_the_checksum_does_not_depend_on_compression_or_storage(files):
    """Same values and attributes, compressed or not (different bytes on disk)."""
    with netCDF4.Dataset(files / "z0.nc") as a, netCDF4.Dataset(files / "z1.nc") as b:
        assert a.getncattr(CHECKSUM_ATTR) == b.getncattr(CHECKSUM_ATTR)
    assert (files / "z0.nc").stat().st_size > 1.3 * (files / "z1.nc").stat().st_size


def _copy(src, dst, change=None):
    """A copy of ``src`` with other storage chunks, written by netCDF4 directly (another tool);
    ``change(nc)`` edits it."""
    with netCDF4.Dataset(src) as a, netCDF4.Dataset(dst, "w") as b:
        b.setncatts({k: a.getncattr(k) for k in a.ncattrs()})
        for d, dim in a.dimensions.items():
            b.createDimension(d, len(dim))
        for name, v in a.variables.items():
            v.set_auto_maskandscale(False)
            fill = v.getncattr("_FillValue") if "_FillValue" in v.ncattrs() else False
            kw = {"chunksizes": [1, 7, 11, 13]} if v.ndim == 4 else {}
            w = b.createVariable(name, v.dtype, v.dimensions, fill_value=fill, **kw)
            w.set_auto_maskandscale(False)
            w.setncatts({k: v.getncattr(k) for k in v.ncattrs() if k != "_FillValue"})
            w[...] = v[...]
        if change is not None:
            change(b)


def test_a_copy_with_other_chunks_verifies(files, tmp_path):
    _copy(files / "z1.nc", tmp_path / "copy.nc")
    assert verify(tmp_path / "copy.nc")[0]


@pytest.mark.parametrize(
    "change",
    [
        lambda nc: nc.variables["period"].__setitem__((0, 5, 7, 9), 1.0),
        lambda nc: nc.variables["orbit_class"].__setitem__((2, 39, 32, 59), 3),
        lambda nc: nc.variables["Lz"].__setitem__(0, 0.0500001),
        lambda nc: nc.variables["r_min"].setncattr("units", "km"),
        lambda nc: nc.setncattr("scene_M", 2.0),
        lambda nc: nc.setncattr("survey_definition", "changed"),
        lambda nc: nc.renameVariable("r_max", "r_maximum"),
    ],
    ids=["a value", "a class", "an axis", "a unit", "the scene", "the definition", "a name"],
)
def test_any_change_but_history_is_found(files, tmp_path, change):
    _copy(files / "z1.nc", tmp_path / "copy.nc", change)
    ok, found = verify(tmp_path / "copy.nc")
    assert not ok and "do not match the recorded checksum" in found


def test_a_new_history_entry_is_not_a_change(files, tmp_path):
    _copy(files / "z1.nc", tmp_path / "copy.nc", lambda nc: nc.setncattr("history", "ncks ..."))
    assert verify(tmp_path / "copy.nc")[0]


def test_a_flipped_bit_is_found_compressed_or_not(files, tmp_path):
    """Uncompressed: a value changes (checksum). zlib: the chunk fails to inflate (adler32).
    blosc (LZ4 has no checksum here): the chunk decodes to other values, or fails to."""
    cases = (("z0", ("do not match",)), ("z1", ("cannot be read",)))
    for name, expect in (*cases, ("blosc", ("do not match", "cannot be read"))):
        data = bytearray((files / f"{name}.nc").read_bytes())
        data[len(data) // 2] ^= 0x10
        bad = tmp_path / f"bad{name}.nc"
        bad.write_bytes(bytes(data))
        ok, found = verify(bad)
        assert not ok and any(e in found for e in expect), found


def test_a_file_without_a_checksum_cannot_be_verified(files, tmp_path):
    _copy(files / "z1.nc", tmp_path / "copy.nc", lambda nc: nc.delncattr(CHECKSUM_ATTR))
    assert verify(tmp_path / "copy.nc") == (
        False,
        "no content checksum recorded (not written by a conesurvey run)",
    )
    _copy(files / "z1.nc", tmp_path / "c2.nc", lambda nc: nc.setncattr(CHECKSUM_BLOCK_ATTR, "x"))
    assert not verify(tmp_path / "c2.nc")[0]

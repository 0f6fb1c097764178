"""``conesurvey convert``: netCDF <-> Zarr, exact, the content checksum verified and kept;
refusals (a missing, unfinished or tampered source, an existing output) exit 2 and write
nothing. In process (``engine.cli.main``) on a 132,000-point survey of 4 blocks, so that the
file costs seconds."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import runs
import xarray as xr

from engine.cli import main
from engine.io.contents import BLOCK_SCHEME, CHECKSUM_ATTR, SCHEME
from engine.runner import run_survey
from engine.surveyfile import parse_survey

zarr = pytest.importorskip("zarr")

SURVEY = runs.gravity_survey("convert test", energy=10)  # 4 x 10 x 33 x 100
BLOCK_POINTS = 33_000  # one storage chunk a block: 4 blocks


def checksum(path: Path) -> str:
    if path.suffix == ".zarr":
        return json.loads((path / "zarr.json").read_text())["attributes"][CHECKSUM_ATTR]
    with netCDF4.Dataset(path) as nc:
        return nc.getncattr(CHECKSUM_ATTR)


def load(path: Path) -> xr.Dataset:
    opened = xr.open_zarr(path, chunks=None) if path.suffix == ".zarr" else xr.open_dataset(path)
    with opened as ds:
        return ds.load()


def same_values(a: Path, b: Path) -> None:
    """Same variables, bit-identical values, same attributes (flag_values by value), same
    global attributes but ``history``; storage chunks equal."""
    x, y = load(a), load(b)
    assert set(x.variables) == set(y.variables)
    for name in x.variables:
        u, v = x[name].values, y[name].values
        assert u.dtype == v.dtype and x[name].dims == y[name].dims, name
        np.testing.assert_array_equal(u.view(f"u{u.itemsize}"), v.view(f"u{v.itemsize}"))
        assert x[name].attrs.keys() == y[name].attrs.keys(), name
        for key, value in x[name].attrs.items():
            np.testing.assert_array_equal(value, y[name].attrs[key])
        if u.ndim == 4:
            ex, ey = x[name].encoding, y[name].encoding
            a, b = (e.get("chunksizes") or e.get("chunks") for e in (ex, ey))
            assert tuple(a) == tuple(b), name
    assert set(x.attrs) - {"history"} == set(y.attrs) - {"history"}
    for key in set(x.attrs) - {"history"}:
        np.testing.assert_array_equal(x.attrs[key], y.attrs[key], err_msg=key)


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """The survey run to netCDF and to Zarr (they hold the same values: tests/io/test_zarr.py)."""
    d = tmp_path_factory.mktemp("conv")
    survey = parse_survey(SURVEY)
    for out in ("run.nc", "run.zarr"):
        run_survey(survey, d / out, block_points=BLOCK_POINTS)
    assert load(d / "run.nc").orbit_class.size == 132_000
    return d


@pytest.fixture
def work(tmp_path, made, monkeypatch):
    for name in ("run.nc", "run.zarr"):
        src = made / name
        (shutil.copytree if src.is_dir() else shutil.copy2)(src, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def convert(capsys, *args: str) -> tuple[int, str, str]:
    status = main(["convert", *args])
    out, err = capsys.readouterr()
    return status, out, err


def tree(directory: Path) -> dict[Path, bytes]:
    """Every file under ``directory`` with its bytes."""
    return {p.relative_to(directory): p.read_bytes() for p in directory.rglob("*") if p.is_file()}


@pytest.mark.parametrize(("src", "dst"), [("run.nc", "c.zarr"), ("run.zarr", "c.nc")])
def test_round_trip_is_exact_and_keeps_the_checksum(work, capsys, src, dst):
    """SRC -> DST -> SRC: bit-identical values, same attributes and chunks; every copy records
    the source's content checksum (verified on the way), and ``info --verify`` accepts it."""
    status, out, err = convert(capsys, src, dst)
    assert status == 0, err
    assert "carried over; the source's was verified" in out and "4 blocks" in out
    assert checksum(work / dst) == checksum(work / src)
    assert checksum(work / src).startswith((SCHEME if src.endswith(".nc") else BLOCK_SCHEME) + ":")
    same_values(work / src, work / dst)
    assert main(["info", dst, "--verify"]) == 0
    assert "complete, verified" in capsys.readouterr().out
    first, rest = load(work / dst).attrs["history"].split("\n", 1)
    assert f" conesurvey convert {src} {dst} (numba threading layer" in first
    assert rest == load(work / src).attrs["history"]  # the source's history follows
    back = "back" + Path(src).suffix
    status, _, err = convert(capsys, dst, back)
    assert status == 0, err
    same_values(work / src, work / back)
    assert checksum(work / back) == checksum(work / src)
    assert runs.listing(work) == sorted(["run.nc", "run.zarr", dst, back])


def tamper_netcdf(work: Path) -> None:
    """One value changed through netCDF4, the recorded checksum left as it was."""
    with netCDF4.Dataset(work / "run.nc", "a") as nc:
        old = nc["r_max"][3, 7, 20, 60]
        nc["r_max"][3, 7, 20, 60] = old * (1 + 1e-15) + 1e-300
    with netCDF4.Dataset(work / "run.nc") as nc:
        assert nc["r_max"][3, 7, 20, 60] != old


def tamper_zarr(work: Path) -> None:
    """One value changed through zarr (a well-formed chunk), the checksum left as it was."""
    arr = zarr.open_array(work / "run.zarr" / "period", mode="r+")
    arr[1, 2, 3, 90] = arr[1, 2, 3, 90] + 1.0


@pytest.mark.parametrize(
    ("tamper", "src", "dst"),
    [(tamper_netcdf, "run.nc", "c.zarr"), (tamper_zarr, "run.zarr", "c.nc")],
)
def test_a_tampered_source_is_refused_and_nothing_is_written(work, capsys, tamper, src, dst):
    tamper(work)
    before = tree(work)
    status, out, err = convert(capsys, src, dst)
    assert status == 2 and out == "", err
    assert f"{src} is damaged" in err and "content checksum" in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert tree(work) == before  # no DST, no temporary, no lock file left


def test_a_damaged_chunk_is_refused(work, capsys):
    """A chunk whose compressed bytes were changed: refused (exit 2) whether the codec notices
    or the checksum does; nothing written."""
    chunk = work / "run.zarr" / "r_max" / "c.0.0.0.1"
    data = bytearray(chunk.read_bytes())
    data[-5] ^= 0x10
    chunk.write_bytes(bytes(data))
    status, _, err = convert(capsys, "run.zarr", "c.nc")
    assert status == 2 and "run.zarr" in err and "Traceback" not in err, err
    assert runs.listing(work) == ["run.nc", "run.zarr"]


def test_an_unfinished_run_is_refused(work, capsys):
    """A run stopped after its first block: refused by the name the user knows (u.zarr, whose
    u.zarr.parts/ holds the blocks) and by its store's own path; nothing written."""

    def stop(index: int) -> None:
        raise KeyboardInterrupt

    for out in ("u.zarr", "u.nc"):
        with pytest.raises(KeyboardInterrupt):
            run_survey(parse_survey(SURVEY), work / out, block_points=BLOCK_POINTS, on_block=stop)
        assert (work / f"{out}.parts").is_dir() and not (work / out).exists()
    before = tree(work)
    for src, dst in (("u.zarr", "c.nc"), ("u.nc", "c.zarr"), ("u.zarr.parts/store.zarr", "c.nc")):
        status, _, err = convert(capsys, src, dst)
        assert status == 2 and "unfinished run" in err, err
        assert err.count("\n") == 1 and "Traceback" not in err
    assert tree(work) == before


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("run.nc", "x.nc"), "both netCDF"),
        (("run.zarr", "x.zarr"), "both Zarr"),
        (("missing.nc", "x.zarr"), "no such result: missing.nc"),
        (("run.nc", "run.zarr"), "output exists: run.zarr"),
        (("run.zarr", "run.nc"), "output exists: run.nc"),
        (("run.nc", "nodir/x.zarr"), "output directory does not exist: nodir"),
    ],
)
def test_refusals_write_nothing(work, capsys, args, message):
    before = tree(work)
    status, _, err = convert(capsys, *args)
    assert status == 2 and message in err, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert tree(work) == before


def test_overwrite_replaces_the_output(work, capsys):
    status, _, err = convert(capsys, "run.nc", "run.zarr", "--overwrite")
    assert status == 0, err
    assert checksum(work / "run.zarr") == checksum(work / "run.nc")
    assert "conesurvey convert" in load(work / "run.zarr").attrs["history"]
    assert runs.listing(work) == ["run.nc", "run.zarr"]

"""engine.io.zarr: a run to OUT.zarr gives the netCDF file's Dataset, and keeps the netCDF
path's guarantees (resume after SIGKILL with verified blocks, fingerprint refusal, refusals
that write nothing, info --verify, reading an unfinished run)."""

from __future__ import annotations

import hashlib
import json
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
import runs
import xarray as xr

from engine.grid import Tiling
from engine.io import OutputError
from engine.io import zarr as zarr_io
from engine.io.contents import BLOCK_SCHEME, CHECKSUM_ATTR, ContentHasher, block_digest
from engine.io.results import open_result
from engine.io.zarrlayout import RUN_ATTR, UNFINISHED_ATTR, ChunkWriter
from engine.io.zarrstore import JOURNAL, RunStore
from engine.runner import RunError, run_survey
from engine.surveyfile import parse_survey

pytest.importorskip("zarr")

# 4 x 40 x 33 x 100 = 528,000 points in 16 blocks of one storage chunk
SURVEY = runs.gravity_survey("zarr test", energy=40)
BLOCK = "65536"
ARGS = ("run", "s.toml", "-o", "out.zarr", "-q", "--block-points", BLOCK)
NBLOCKS = Tiling.for_grid(parse_survey(SURVEY).shape, int(BLOCK)).nblocks


def bits(a: np.ndarray) -> np.ndarray:
    """The values' bit patterns (NaN payloads and signed zeros compared exactly)."""
    return np.ascontiguousarray(a).view(f"u{a.dtype.itemsize}")


def open_zarr(path: Path) -> xr.Dataset:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # opens cleanly: no decoding or CF warnings
        return xr.open_zarr(path, chunks=None).load()


def assert_same_dataset(nc: Path, store: Path) -> None:
    """``xr.open_zarr(store)`` is ``xr.open_dataset(nc)``: variables, dims, dtypes, bit-identical
    values, attributes, _FillValue conventions, storage chunks; global attributes except the
    history line and the content checksum (another scheme). Only the order in which the
    variables are listed differs (a Zarr group lists them by name)."""
    with xr.open_dataset(nc) as a:
        a.load()
    b = open_zarr(store)
    assert set(a.variables) == set(b.variables)  # zarr lists its arrays by name
    assert dict(a.sizes) == dict(b.sizes) and set(a.coords) == set(b.coords)
    for name in a.variables:
        x, y = a[name], b[name]
        assert x.dims == y.dims and x.dtype == y.dtype, name
        np.testing.assert_array_equal(bits(x.values), bits(y.values), err_msg=name)
        assert x.attrs.keys() == y.attrs.keys(), name
        for key, value in x.attrs.items():
            np.testing.assert_array_equal(value, y.attrs[key], err_msg=f"{name}.{key}")
        fx, fy = x.encoding.get("_FillValue"), y.encoding.get("_FillValue")
        assert (fx is None) == (fy is None), name
        if fx is not None:
            assert np.isnan(fx) and np.isnan(fy), name
        if x.ndim == 4:
            assert x.encoding["chunksizes"] == y.encoding["chunks"], name
    skip = {"history", CHECKSUM_ATTR}
    assert set(a.attrs) - skip == set(b.attrs) - skip
    for key in set(a.attrs) - skip:
        np.testing.assert_array_equal(a.attrs[key], b.attrs[key], err_msg=key)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The survey to netCDF and to Zarr, uninterrupted."""
    d = tmp_path_factory.mktemp("ref")
    (d / "s.toml").write_text(SURVEY)
    for out in ("ref.nc", "ref.zarr"):
        proc = runs.run(d, "run", "s.toml", "-o", out, "-q", "--block-points", BLOCK)
        assert proc.returncode == 0, proc.stderr
    return d


@pytest.fixture
def work(tmp_path):
    (tmp_path / "s.toml").write_text(SURVEY)
    return tmp_path


def test_open_zarr_reads_the_netcdf_dataset(reference):
    assert_same_dataset(reference / "ref.nc", reference / "ref.zarr")
    b = open_zarr(reference / "ref.zarr")
    assert b.attrs[CHECKSUM_ATTR].startswith(BLOCK_SCHEME + ":")
    assert UNFINISHED_ATTR not in b.attrs and RUN_ATTR not in b.attrs


def test_closed_form_free_fall_with_several_classes_and_nans(tmp_path):
    """A survey with several classes, +inf and NaN fields, relative and absolute energy."""
    survey = parse_survey(runs.free_fall_survey("free fall zarr"))
    run_survey(survey, tmp_path / "f.nc")
    run_survey(survey, tmp_path / "f.zarr")
    assert_same_dataset(tmp_path / "f.nc", tmp_path / "f.zarr")
    ds = open_zarr(tmp_path / "f.zarr")
    assert np.unique(ds.orbit_class.values).size >= 3 and np.isinf(ds.r_max.values).any()


def test_the_store_appears_complete_and_nothing_else_is_left(reference):
    assert sorted(p.name for p in reference.iterdir()) == ["ref.nc", "ref.zarr", "s.toml"]
    proc = runs.run(reference, "info", "ref.zarr", "--verify")
    assert proc.returncode == 0 and "complete, verified" in proc.stdout, proc.stdout
    again = runs.run(reference, "run", "s.toml", "-o", "ref.zarr")
    assert again.returncode == 0 and "nothing to do" in again.stdout


def test_info_verify_finds_a_changed_chunk(tmp_path, reference):
    store = tmp_path / "copy.zarr"
    subprocess.run(["cp", "-r", str(reference / "ref.zarr"), str(store)], check=True)
    chunk = store / "period" / "c" / "0" / "1" / "0" / "0"
    data = bytearray(chunk.read_bytes())
    data[-9] ^= 0x01  # a bit of the compressed values
    chunk.write_bytes(bytes(data))
    proc = runs.run(tmp_path, "info", "copy.zarr", "--verify")
    assert proc.returncode == 1 and "DAMAGED" in proc.stdout, proc.stdout
    assert "Traceback" not in proc.stderr


def journal_lines(work: Path) -> int:
    try:
        return (work / "out.zarr.parts" / JOURNAL).read_bytes().count(b"\n")
    except FileNotFoundError:
        return 0


def killed_after(work: Path, blocks: int) -> None:
    proc = subprocess.Popen(runs.cli(*ARGS), cwd=work, env=runs.env(), stderr=subprocess.PIPE)
    assert runs.kill_when(proc, lambda: journal_lines(work) >= blocks), "finished first"


def test_killed_run_resumes_verifies_blocks_and_matches(work, reference):
    """SIGKILL after 3 blocks; one journaled block's chunk is edited, another's deleted: the
    rerun reports both, computes them again and the store equals the uninterrupted one."""
    killed_after(work, 3)
    parts = work / "out.zarr.parts"
    assert not (work / "out.zarr").exists()
    meta = json.loads((parts / "store.zarr" / "zarr.json").read_text())
    assert UNFINISHED_ATTR in meta["attributes"]  # the store in progress says so
    store = RunStore.open(parts)
    done = sorted(store.journal)
    edited, deleted = store.keys(done[0])[3], store.keys(done[1])[5]
    path = parts / "store.zarr" / edited
    path.write_bytes(path.read_bytes()[:-1] + b"\x00")
    (parts / "store.zarr" / deleted).unlink()
    proc = runs.run(work, *ARGS)
    assert proc.returncode == 0, proc.stderr
    assert f"block {done[0]} " in proc.stderr and f"block {done[1]} " in proc.stderr
    assert "recomputing" in proc.stderr
    assert runs.listing(work) == ["out.zarr", "s.toml"]
    assert_same_dataset(reference / "ref.nc", work / "out.zarr")
    verified = runs.run(work, "info", "out.zarr", "--verify")
    assert verified.returncode == 0 and "complete, verified" in verified.stdout
    ref = json.loads((reference / "ref.zarr" / "zarr.json").read_text())["attributes"]
    got = json.loads((work / "out.zarr" / "zarr.json").read_text())["attributes"]
    assert got[CHECKSUM_ATTR] == ref[CHECKSUM_ATTR]


def test_another_survey_is_refused_and_nothing_changes(work):
    killed_after(work, 2)
    before = {p: p.read_bytes() for p in (work / "out.zarr.parts").rglob("*") if p.is_file()}
    (work / "s.toml").write_text(SURVEY.replace('"zarr test"', '"another"'))
    proc = runs.run(work, *ARGS)
    assert proc.returncode == 2 and "another survey" in proc.stderr, proc.stderr
    after = {p: p.read_bytes() for p in (work / "out.zarr.parts").rglob("*") if p.is_file()}
    assert after == before


def test_an_existing_store_is_kept_without_overwrite(work, reference):
    subprocess.run(["cp", "-r", str(reference / "ref.zarr"), str(work / "out.zarr")], check=True)
    (work / "s.toml").write_text(SURVEY.replace('"zarr test"', '"another"'))
    proc = runs.run(work, *ARGS)
    assert proc.returncode == 2 and "exists" in proc.stderr
    assert runs.listing(work) == ["out.zarr", "s.toml"]
    again = runs.run(work, *ARGS, "--overwrite")
    assert again.returncode == 0, again.stderr
    assert runs.listing(work) == ["out.zarr", "s.toml"]
    assert open_zarr(work / "out.zarr").attrs["title"] == "another"


def test_reading_an_unfinished_run(work, reference):
    """What plot and report see during a run: the journaled blocks, NaN elsewhere."""
    killed_after(work, 3)
    with open_result(work / "out.zarr") as res, xr.open_dataset(reference / "ref.nc") as ref:
        assert not res.complete and res.kind == "parts" and res.blocks_done >= 3
        mask = res.computed().values
        assert mask.sum() == res.points_done
        got, want = res.ds.period.values, ref.period.values
        np.testing.assert_array_equal(bits(got[mask]), bits(want[mask]))
        assert np.isnan(got[~mask]).all()
        np.testing.assert_array_equal(res.ds.orbit_class.values[mask], ref.orbit_class.values[mask])
    proc = runs.run(work, "info", "out.zarr")
    assert proc.returncode == 0 and "unfinished" in proc.stdout, proc.stdout
    plotted = runs.run(work, "plot", "out.zarr", "-o", "m.png")
    assert plotted.returncode == 0, plotted.stderr


def test_a_writer_never_writes_into_another_runs_store(tmp_path, reference):
    """A dask task of a killed run that finishes late (a "zombie") may hold a writer of a
    store that a new run removed and made again: it refuses, writing nothing."""
    survey = parse_survey(SURVEY)
    out = tmp_path / "z.zarr"
    root = tmp_path / "z.zarr.parts"
    tiling = Tiling.for_grid(survey.shape, 1 << 16)
    run = zarr_io.create(root, survey, tiling, 1, print)
    stale = ChunkWriter(**{**run.writer.__dict__, "run_id": "0" * 32})
    values = {n: np.zeros([s.stop - s.start for s in tiling.slices(0)], dt)
              for n, dt in run.names.items()}  # fmt: skip
    with pytest.raises(OSError, match="no longer this run's"):
        stale.write(0, tiling.slices(0), values)
    assert not (root / "store.zarr" / "period" / "c").exists()
    receipt = run.writer.write(0, tiling.slices(0), values)
    assert receipt["bytes"] > 0 and (root / "store.zarr" / "period" / "c").is_dir()
    assert not out.exists()


def test_block_digest_scheme():
    """sha256-blocks-v1: a variable's digest is SHA-256 over the SHA-256 of its blocks."""
    a, b = np.arange(6.0), np.array([np.nan, -0.0])
    h = ContentHasher((2, 1, 1, 1), BLOCK_SCHEME)
    h.add("x", a)
    h.add_digest("x", block_digest(b))
    manual = hashlib.sha256(
        hashlib.sha256(a.astype("<f8").tobytes()).digest()
        + hashlib.sha256(b.astype("<f8").tobytes()).digest()
    ).digest()
    assert h._data["x"].digest() == manual
    with pytest.raises(ValueError):
        ContentHasher((1,), "sha256-v1").add_digest("x", manual)


def test_without_the_zarr_package_the_run_is_refused_before_writing(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "zarr", None)  # import zarr raises ImportError
    with pytest.raises(RunError, match=r"pip install 'conesurvey\[zarr\]'"):
        run_survey(parse_survey(SURVEY), tmp_path / "x.zarr")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(OutputError, match="zarr"):
        zarr_io.zarr_module()


def test_killed_after_the_last_block_the_rerun_only_commits(work, reference):
    """Killed once every block is journaled (during the commit or the rename, or just after):
    the rerun computes nothing; it commits and renames, or finds the store complete."""
    proc = subprocess.Popen(runs.cli(*ARGS), cwd=work, env=runs.env(), stderr=subprocess.PIPE)
    assert runs.kill_when(proc, lambda: journal_lines(work) >= NBLOCKS), "finished first"
    again = runs.run(work, *[a for a in ARGS if a != "-q"])
    assert again.returncode == 0, again.stderr
    assert (
        f"{NBLOCKS} of {NBLOCKS} blocks from an earlier run" in again.stdout
        or "nothing to do" in again.stdout
    ), again.stdout
    assert runs.listing(work) == ["out.zarr", "s.toml"]
    assert_same_dataset(reference / "ref.nc", work / "out.zarr")

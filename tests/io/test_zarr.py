"""engine.io.zarr: a run to OUT.zarr gives the netCDF file's Dataset, and keeps the netCDF
path's guarantees (resume after SIGKILL with verified blocks, fingerprint refusal, refusals
that write nothing, info --verify, reading an unfinished run). Only the runs that are killed
are subprocesses (one killed run is shared by the tests that only need one); the rest runs in
process, so that the file costs little more than its runs."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
import runs
import xarray as xr

from engine.cli import main
from engine.grid import Tiling
from engine.io import OutputError
from engine.io import zarr as zarr_io
from engine.io.contents import BLOCK_SCHEME, CHECKSUM_ATTR, ContentHasher, block_digest
from engine.io.results import open_result
from engine.io.zarrlayout import RUN_ATTR, UNFINISHED_ATTR, ChunkWriter
from engine.io.zarrstore import JOURNAL, RunStore
from engine.plan import plan_from_survey
from engine.runner import RunError, run_survey
from engine.surveyfile import parse_survey

pytest.importorskip("zarr")

# 4 x 20 x 33 x 100 = 264,000 points in 8 blocks of one storage chunk
SURVEY = runs.gravity_survey("zarr test", energy=20)
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


def cli(capsys, *args: str) -> tuple[int, str, str]:
    """``conesurvey ARGS`` in this process: exit status, stdout, stderr."""
    status = main(list(args))
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The survey to netCDF and to Zarr, uninterrupted."""
    d = tmp_path_factory.mktemp("ref")
    (d / "s.toml").write_text(SURVEY)
    for out in ("ref.nc", "ref.zarr"):
        run_survey(parse_survey(SURVEY), d / out, block_points=int(BLOCK))
    return d


@pytest.fixture
def work(tmp_path, monkeypatch):
    (tmp_path / "s.toml").write_text(SURVEY)
    monkeypatch.chdir(tmp_path)
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


def test_the_store_appears_complete_and_nothing_else_is_left(reference, capsys, monkeypatch):
    assert sorted(p.name for p in reference.iterdir()) == ["ref.nc", "ref.zarr", "s.toml"]
    monkeypatch.chdir(reference)
    status, out, _ = cli(capsys, "info", "ref.zarr", "--verify")
    assert status == 0 and "complete, verified" in out, out
    status, out, _ = cli(capsys, "run", "s.toml", "-o", "ref.zarr")
    assert status == 0 and "nothing to do" in out, out


def test_info_verify_finds_a_changed_chunk(work, reference, capsys):
    store = work / "copy.zarr"
    shutil.copytree(reference / "ref.zarr", store)
    chunk = store / "period" / "c.0.0.1.0"  # chunk (0, 0, 1, 0): keys "default", separator "."
    data = bytearray(chunk.read_bytes())
    data[len(data) // 2] ^= 0x01  # a bit of the compressed values
    chunk.write_bytes(bytes(data))
    status, out, err = cli(capsys, "info", "copy.zarr", "--verify")
    assert status == 1 and "DAMAGED" in out, out
    assert "Traceback" not in err


def journal_lines(work: Path) -> int:
    try:
        return (work / "out.zarr.parts" / JOURNAL).read_bytes().count(b"\n")
    except FileNotFoundError:
        return 0


def killed_after(work: Path, blocks: int) -> None:
    proc = subprocess.Popen(runs.cli(*ARGS), cwd=work, env=runs.env(), stderr=subprocess.PIPE)
    assert runs.kill_when(proc, lambda: journal_lines(work) >= blocks), "finished first"


@pytest.fixture(scope="module")
def killed(tmp_path_factory):
    """A run of ``out.zarr`` SIGKILLed after 3 blocks (its ``out.zarr.parts``)."""
    d = tmp_path_factory.mktemp("killed")
    (d / "s.toml").write_text(SURVEY)
    killed_after(d, 3)
    assert not (d / "out.zarr").exists()
    return d / "out.zarr.parts"


@pytest.fixture
def after_kill(work, killed):
    """``work`` with a copy of the killed run's ``out.zarr.parts`` (modes kept)."""
    shutil.copytree(killed, work / killed.name)
    return work


def test_killed_run_resumes_verifies_blocks_and_matches(after_kill, reference, capsys):
    """SIGKILL after 3 blocks; one journaled block's chunk is edited, another's deleted: the
    rerun reports both, computes them again and the store equals the uninterrupted one."""
    work = after_kill
    parts = work / "out.zarr.parts"
    meta = json.loads((parts / "store.zarr" / "zarr.json").read_text())
    assert UNFINISHED_ATTR in meta["attributes"]  # the store in progress says so
    store = RunStore.open(parts)
    done = sorted(store.journal)
    edited, deleted = store.keys(done[0])[3], store.keys(done[1])[5]
    path = parts / "store.zarr" / edited
    path.write_bytes(path.read_bytes()[:-1] + b"\x00")
    (parts / "store.zarr" / deleted).unlink()
    status, _, err = cli(capsys, *ARGS)
    assert status == 0, err
    assert f"block {done[0]} " in err and f"block {done[1]} " in err
    assert "recomputing" in err
    assert runs.listing(work) == ["out.zarr", "s.toml"]
    assert_same_dataset(reference / "ref.nc", work / "out.zarr")
    status, out, _ = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 0 and "complete, verified" in out
    ref = json.loads((reference / "ref.zarr" / "zarr.json").read_text())["attributes"]
    got = json.loads((work / "out.zarr" / "zarr.json").read_text())["attributes"]
    assert got[CHECKSUM_ATTR] == ref[CHECKSUM_ATTR]


def test_a_run_begun_with_nested_chunk_keys_resumes_in_them(work, reference, capsys, monkeypatch):
    """A run whose store keeps each chunk in directories of its own (``period/c/0/0/1/0``: the
    layout before one directory per variable) and was stopped after 3 blocks resumes in that
    layout: the blocks it computes go beside the stored ones, and the store equals the
    uninterrupted one."""
    from engine.io import zarrstore

    stored = {"n": 0}

    def stop(index: int) -> None:
        stored["n"] += 1
        if stored["n"] == 3:
            raise KeyboardInterrupt  # stands for a kill after 3 stored blocks

    with monkeypatch.context() as old, pytest.raises(KeyboardInterrupt):
        old.setattr(zarrstore, "SEPARATOR", "/")
        run_survey(parse_survey(SURVEY), work / "out.zarr", block_points=int(BLOCK), on_block=stop)
    parts = work / "out.zarr.parts" / "store.zarr"  # the code of today resumes it
    meta = json.loads((parts / "period" / "zarr.json").read_text())
    assert meta["chunk_key_encoding"]["configuration"]["separator"] == "/"
    status, _, err = cli(capsys, *ARGS)
    assert status == 0, err
    store = work / "out.zarr"
    files = [p.relative_to(store / "period").as_posix() for p in store.glob("period/c/**/*")]
    files = [f for f in files if (store / "period" / f).is_file()]
    assert len(files) == NBLOCKS and all(re.fullmatch(r"c(/\d+){4}", f) for f in files), files
    assert not list(store.glob("period/c.*"))
    assert_same_dataset(reference / "ref.nc", store)
    status, out, _ = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 0 and "complete, verified" in out


def test_another_survey_is_refused_and_nothing_changes(after_kill, capsys):
    work = after_kill
    before = {p: p.read_bytes() for p in (work / "out.zarr.parts").rglob("*") if p.is_file()}
    (work / "s.toml").write_text(SURVEY.replace('"zarr test"', '"another"'))
    status, _, err = cli(capsys, *ARGS)
    assert status == 2 and "another survey" in err, err
    after = {p: p.read_bytes() for p in (work / "out.zarr.parts").rglob("*") if p.is_file()}
    assert after == before


def _foreign_keys(store: Path) -> None:
    """Every array's chunk key encoding edited: "v2", and period's separator "/"."""
    for meta in store.glob("*/zarr.json"):
        doc = json.loads(meta.read_text())
        if meta.parent.name == "period":
            doc["chunk_key_encoding"]["configuration"]["separator"] = "/"
        elif "chunk_key_encoding" in doc:
            doc["chunk_key_encoding"] = {"name": "v2", "configuration": {"separator": "."}}
        meta.write_text(json.dumps(doc))


def test_edited_chunk_key_encodings_are_written_again(after_kill, reference, capsys):
    """The manifest records the store's compression and chunk key separator, so the arrays'
    metadata is not trusted: a resume writes it again from the plan (naming each file) and the
    store equals the uninterrupted one."""
    work = after_kill
    _foreign_keys(work / "out.zarr.parts" / "store.zarr")
    status, _, err = cli(capsys, *ARGS)
    assert status == 0, err
    assert "period/zarr.json of" in err and "written again" in err, err
    assert_same_dataset(reference / "ref.nc", work / "out.zarr")
    status, out, _ = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 0 and "complete, verified" in out


@pytest.mark.parametrize(
    ("edit", "said"),
    [("foreign", "chunk key encoding of"), ("mixed", "do not share one chunk key separator")],
)
def test_a_store_made_before_its_manifest_said_its_layout_is_read_from_its_arrays(
    after_kill, capsys, edit, said
):
    """A store whose manifest does not say its layout (made before it did) takes it from its
    arrays' metadata: a chunk key encoding conesurvey does not write, or arrays that disagree on
    the separator, is refused, saying so, and nothing changes; --overwrite starts again."""
    import dataclasses

    from engine.io.manifest import read_manifest, write_manifest

    work = after_kill
    parts = work / "out.zarr.parts"
    write_manifest(parts, dataclasses.replace(read_manifest(parts), zarr=None))
    store = parts / "store.zarr"
    if edit == "foreign":
        _foreign_keys(store)
    else:
        meta = store / "period" / "zarr.json"
        doc = json.loads(meta.read_text())
        doc["chunk_key_encoding"]["configuration"]["separator"] = "/"
        meta.write_text(json.dumps(doc))
    before = {p: p.read_bytes() for p in parts.rglob("*") if p.is_file()}
    status, _, err = cli(capsys, *ARGS)
    assert status == 2 and said in err, err
    assert {p: p.read_bytes() for p in parts.rglob("*") if p.is_file()} == before
    status, _, err = cli(capsys, *ARGS, "--overwrite")
    assert status == 0, err


def test_an_existing_store_is_kept_without_overwrite(work, reference, capsys):
    shutil.copytree(reference / "ref.zarr", work / "out.zarr")
    (work / "s.toml").write_text(SURVEY.replace('"zarr test"', '"another"'))
    status, _, err = cli(capsys, *ARGS)
    assert status == 2 and "exists" in err
    assert runs.listing(work) == ["out.zarr", "s.toml"]
    status, _, err = cli(capsys, *ARGS, "--overwrite")
    assert status == 0, err
    assert runs.listing(work) == ["out.zarr", "s.toml"]
    assert open_zarr(work / "out.zarr").attrs["title"] == "another"


def test_reading_an_unfinished_run(after_kill, reference, capsys):
    """What plot and report see during a run: the journaled blocks, NaN elsewhere."""
    work = after_kill
    with open_result(work / "out.zarr") as res, xr.open_dataset(reference / "ref.nc") as ref:
        assert not res.complete and res.kind == "parts" and res.blocks_done >= 3
        mask = res.computed().values
        assert mask.sum() == res.points_done
        got, want = res.ds.period.values, ref.period.values
        np.testing.assert_array_equal(bits(got[mask]), bits(want[mask]))
        assert np.isnan(got[~mask]).all()
        np.testing.assert_array_equal(res.ds.orbit_class.values[mask], ref.orbit_class.values[mask])
    status, out, _ = cli(capsys, "info", "out.zarr")
    assert status == 0 and "unfinished" in out, out
    pytest.importorskip("matplotlib")
    status, _, err = cli(capsys, "plot", "out.zarr", "-o", "m.png")
    assert status == 0 and (work / "m.png").stat().st_size > 0, err


def test_a_writer_never_writes_into_another_runs_store(tmp_path, reference):
    """A dask task of a killed run that finishes late (a "zombie") may hold a writer of a
    store that a new run removed and made again: it refuses, writing nothing."""
    survey = parse_survey(SURVEY)
    out = tmp_path / "z.zarr"
    root = tmp_path / "z.zarr.parts"
    tiling = Tiling.for_grid(survey.shape, 1 << 16)
    run = zarr_io.create(root, plan_from_survey(survey), tiling, 1, print)
    stale = ChunkWriter(**{**run.writer.__dict__, "run_id": "0" * 32})
    values = {n: np.zeros([s.stop - s.start for s in tiling.slices(0)], dt)
              for n, dt in run.names.items()}  # fmt: skip
    with pytest.raises(OSError, match="no longer this run's"):
        stale.write(0, tiling.slices(0), values)
    assert not list((root / "store.zarr" / "period").glob("c*"))
    receipt = run.writer.write(0, tiling.slices(0), values)
    assert receipt["bytes"] > 0 and (root / "store.zarr" / "period" / "c.0.0.0.0").is_file()
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
    with pytest.raises(RunError, match=r"-m pip install '\.\[zarr\]'"):  # from the checkout
        run_survey(parse_survey(SURVEY), tmp_path / "x.zarr")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(OutputError, match="zarr"):
        zarr_io.zarr_module()


def test_killed_after_the_last_block_the_rerun_only_commits(work, reference, capsys):
    """Killed once every block is journaled (during the commit or the rename, or just after):
    the rerun computes nothing; it commits and renames, or finds the store complete."""
    killed_after(work, NBLOCKS)
    status, out, err = cli(capsys, *[a for a in ARGS if a != "-q"])
    assert status == 0, err
    assert f"{NBLOCKS} of {NBLOCKS} blocks from an earlier run" in out or "nothing to do" in out, (
        out
    )
    assert runs.listing(work) == ["out.zarr", "s.toml"]
    assert_same_dataset(reference / "ref.nc", work / "out.zarr")


@pytest.mark.parametrize("compression", ["zlib", "zstd"])
def test_a_netcdf_only_compression_is_refused_for_zarr(work, capsys, compression):
    """A Zarr store is written with Blosc LZ4 or uncompressed: another --compression is a
    one-line refusal naming the value, before anything is written."""
    status, _, err = cli(capsys, *ARGS, "--compression", compression)
    assert status == 2 and f"compression '{compression}'" in err and "Zarr" in err, err
    assert err.count("\n") == 1
    assert runs.listing(work) == ["s.toml"]

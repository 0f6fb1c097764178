"""The recipe "A new output format" of docs/architecture.md, applied: a toy format (one ``.npz``
file) is one :class:`engine.io.formats.OutputFormat` row built from public names and passed to
``register``; nothing else is edited. The command line and the runner then run a survey into
it, refuse a compression it does not write, resume a stopped run through its ``open_run``,
find the finished output through its ``read_fingerprint``, and ``info`` reads it through its
``read_info``. Its values are the netCDF run's, bit for bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import runs
import xarray as xr

from engine.cli import main
from engine.grid import Tiling
from engine.io.atomic import fsync_path, replacing
from engine.io.blocks import BlockStore
from engine.io.formats import FORMATS, OutputFormat, format_for, register, unregister
from engine.io.manifest import Manifest, survey_families
from engine.io.summary import Summary
from engine.runner import AlreadyComplete, RunFailed, run_survey
from engine.surveyfile import parse_survey

# 4 x 20 x 33 x 100 = 264,000 points in 8 blocks (the closed form: kernels the suite compiles)
SURVEY = runs.gravity_survey("format recipe", energy=20)
NBLOCKS = Tiling.for_grid(parse_survey(SURVEY).shape, 65536).nblocks


# --- the recipe: one row -------------------------------------------------------------------


def _create(root, plan, tiling, complevel, warn):
    return BlockStore.create(root, Manifest.new(plan, tiling), warn)


def _commit(store, plan, out, *, fingerprint, overwrite, incoming, **options):
    """Every block, as it comes (the rest read back verified), into one .npz file."""
    tiling, summary = store.tiling, Summary()
    values = {n: np.empty(tiling.shape, dt) for n, dt in store.names.items()}
    got = set()
    for i, block in incoming:
        got.add(i)
        for n, arr in block.items():
            values[n][tiling.slices(i)] = arr
        summary.add(block)
    for i in sorted(set(range(tiling.nblocks)) - got):  # blocks of an earlier, stopped run
        block = store.take(i)
        for n, arr in block.items():
            values[n][tiling.slices(i)] = arr
        summary.add(block)
    axes = dict(zip(plan.dims, plan.axes, strict=True))
    values.update(survey_families(plan))  # r_circ on (alpha, h, Lz): in no block
    with replacing(out, overwrite=overwrite, tmp_dir=store.root) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, fingerprint=np.array(fingerprint), **axes, **values)
        fsync_path(tmp)
    return summary


def _fingerprint(path: Path) -> str | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            return str(z["fingerprint"])
    except (OSError, ValueError, KeyError):
        return None


def _info(path: Path, *, verify: bool = False) -> dict:
    with np.load(path, allow_pickle=False) as z:
        dims = {n: z[n].size for n in ("alpha", "energy", "h", "Lz")}
    return {"path": str(path), "complete": True, "attrs": {}, "dims": dims, "notes": []}


NPZ = OutputFormat(
    name="npz",
    label="NumPy npz",
    suffixes=(".npz",),
    create=_create,
    open_run=BlockStore.open,
    commit=_commit,
    read_fingerprint=_fingerprint,
    read_info=_info,
)


@pytest.fixture
def npz_format():
    register(NPZ)
    yield NPZ
    unregister("npz")
    assert "npz" not in FORMATS


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> xr.Dataset:
    """The same survey run to netCDF."""
    d = tmp_path_factory.mktemp("reference")
    run_survey(parse_survey(SURVEY), d / "ref.nc", block_points=65536, command="test")
    with xr.open_dataset(d / "ref.nc") as ds:
        return ds.load()


def test_a_registered_row_is_found_by_its_suffix(npz_format):
    assert format_for("a/out.NPZ") is npz_format
    assert format_for("out.zarr").name == "zarr" and format_for("out.nc").name == "netcdf"
    assert format_for("out", "npz") is npz_format
    with pytest.raises(ValueError, match="format must be one of .*npz.*; got 'hdf9'"):
        format_for("out.npz", "hdf9")


def test_the_runner_writes_resumes_and_finds_a_new_format(
    npz_format, reference, tmp_path, monkeypatch, capsys
):
    monkeypatch.chdir(tmp_path)
    Path("s.toml").write_text(SURVEY)
    survey = parse_survey(SURVEY)

    # a compression the row does not list is refused, nothing written
    status = main(["run", "s.toml", "-o", "out.npz", "-q", "--compression", "zlib"])
    err = capsys.readouterr().err
    assert status == 2 and "'zlib'" in err and "NumPy npz" in err, err
    assert not Path("out.npz").exists() and not Path("out.npz.parts").exists()

    # a run stopped after 3 blocks leaves its store (the row's create) ...
    def stop(index: int, seen: list = []) -> None:  # noqa: B006 - counts calls
        seen.append(index)
        if len(seen) == 3:
            raise RunFailed("stopped by the test")

    with pytest.raises(RunFailed, match="stopped by the test"):
        run_survey(survey, "out.npz", block_points=65536, on_block=stop, command="test")
    assert not Path("out.npz").exists() and Path("out.npz.parts").is_dir()

    # ... which the next run resumes (the row's open_run) and commits (the row's commit)
    stats = run_survey(survey, "out.npz", command="test")
    assert (stats.blocks_reused, stats.blocks_total) == (3, NBLOCKS)
    assert not Path("out.npz.parts").exists()
    with np.load("out.npz") as z:
        for name in reference.data_vars:
            np.testing.assert_array_equal(z[name], reference[name].values, err_msg=name)
        assert set(z.files) == {"fingerprint", *survey.dims, *reference.data_vars}

    # the finished output is found by its fingerprint (the row's read_fingerprint)
    before = Path("out.npz").stat().st_ino
    with pytest.raises(AlreadyComplete):
        run_survey(survey, "out.npz", command="test")
    assert main(["run", "s.toml", "-o", "out.npz", "-q"]) == 0
    assert Path("out.npz").stat().st_ino == before

    # info reads it through the row
    assert main(["info", "out.npz"]) == 0
    out = capsys.readouterr().out
    assert "state       complete" in out and "alpha 4 x energy 20 x h 33 x Lz 100" in out, out

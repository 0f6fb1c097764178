"""A Zarr resume keeps nothing it did not check: an unfinished store whose axes, variables on
fewer dims (r_circ, V_min) or arrays' metadata (units, scale_factor, fill values, flag tables)
were edited, or whose arrays were deleted or added, is made what the run writes again by the
same command; the store it commits equals the uninterrupted one (values, attributes, content
checksum) and verifies. What a reader interprets is in the content checksum, so an edit of it
after the commit is DAMAGED. A store damaged during the run is caught at the commit (exit 1,
not a refusal of the survey) and the same command finishes it; ``info`` says so before.
``convert`` of a damaged store is one line, never a traceback."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import runs
import xarray as xr

from engine.cli import main
from engine.runner import run_survey
from engine.surveyfile import parse_survey

pytest.importorskip("zarr")

# 4 x 20 x 33 x 100 = 264,000 points in 8 blocks of one storage chunk
SURVEY = runs.gravity_survey("zarr resume attacks", energy=20)
BLOCK = 65536
ARGS = ("run", "s.toml", "-o", "out.zarr", "-q", "--block-points", str(BLOCK))


def cli(capsys, *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    status = main(list(args))
    out, err = capsys.readouterr()
    return status, out, err


def checksum(store: Path) -> str:
    return json.loads((store / "zarr.json").read_text())["attributes"]["content_checksum"]


class Stop(Exception):
    pass


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    d = tmp_path_factory.mktemp("ref")
    run_survey(parse_survey(SURVEY), d / "ref.zarr", block_points=BLOCK)
    return d / "ref.zarr"


@pytest.fixture(scope="module")
def partial(tmp_path_factory):
    """An unfinished run: 3 of 8 blocks stored (the run stopped as a kill would)."""
    d = tmp_path_factory.mktemp("partial")

    def stop(i: int) -> None:
        if i >= 2:
            raise Stop

    with pytest.raises(Stop):
        run_survey(parse_survey(SURVEY), d / "out.zarr", block_points=BLOCK, on_block=stop)
    return d / "out.zarr.parts"


@pytest.fixture
def work(tmp_path, monkeypatch):
    (tmp_path / "s.toml").write_text(SURVEY)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def same_as_reference(store: Path, reference: Path) -> None:
    """The same arrays with the same metadata, every variable's values (as bits), dims and
    attributes equal, and the same content checksum."""
    assert checksum(store) == checksum(reference)
    metas = sorted(p.relative_to(reference) for p in reference.glob("*/zarr.json"))
    assert sorted(p.relative_to(store) for p in store.glob("*/zarr.json")) == metas
    for meta in metas:
        assert json.loads((store / meta).read_text()) == json.loads(
            (reference / meta).read_text()
        ), meta
    with xr.open_zarr(store, chunks=None) as got, xr.open_zarr(reference, chunks=None) as want:
        assert sorted(got.variables) == sorted(want.variables)
        for name in want.variables:
            a, b = got[name], want[name]
            assert a.dims == b.dims and a.attrs == b.attrs, name
            assert a.values.tobytes() == b.values.tobytes(), name


def _flip_chunk(array: str):
    def edit(store: Path) -> None:
        chunk = next(p for p in (store / array).rglob("*") if p.is_file() and p.name != "zarr.json")
        data = bytearray(chunk.read_bytes())
        data[-1] ^= 0xFF
        chunk.write_bytes(bytes(data))

    return edit


def _meta(array: str, change):
    def edit(store: Path) -> None:
        path = store / array / "zarr.json"
        doc = json.loads(path.read_text())
        change(doc)
        path.write_text(json.dumps(doc, indent=2))

    return edit


def _removed(array: str):
    return lambda store: shutil.rmtree(store / array)


def _added(store: Path) -> None:
    shutil.copytree(store / "r_circ", store / "r_extra")


EDITS = {
    "r_circ values": _flip_chunk("r_circ"),
    "V_min values": _flip_chunk("V_min"),
    "h axis values": _flip_chunk("h"),
    "units": _meta("r_min", lambda d: d["attributes"].update(units="km")),
    "scale_factor": _meta("period", lambda d: d["attributes"].update(scale_factor=2.0)),
    "flag table": _meta("orbit_class", lambda d: d["attributes"].update(flag_values=[0, 1])),
    "fill value": _meta("r_max", lambda d: d.update(fill_value=0.0)),
    "r_circ deleted": _removed("r_circ"),
    "h deleted": _removed("h"),
    "r_min deleted": _removed("r_min"),
    "an array added": _added,
}


@pytest.mark.parametrize("edit", list(EDITS), ids=list(EDITS))
def test_a_resume_commits_nothing_it_did_not_check(work, capsys, reference, partial, edit):
    shutil.copytree(partial, work / "out.zarr.parts")
    EDITS[edit](work / "out.zarr.parts" / "store.zarr")
    status, _, err = cli(capsys, *ARGS)
    assert status == 0, err
    assert "written again" in err or "removed" in err or "recomputing" in err, err
    same_as_reference(work / "out.zarr", reference)
    status, out, _ = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 0 and "complete, verified" in out, out


AFTER = {
    "units": ("r_min", lambda d: d["attributes"].update(units="km")),
    "scale_factor": ("period", lambda d: d["attributes"].update(scale_factor=2.0)),
    "flag meanings": (
        "orbit_class",
        lambda d: d["attributes"].update(flag_meanings="a b c d e f g h"),
    ),
    "fill value attribute": ("r_max", lambda d: d["attributes"].update(_FillValue="AAAA")),
}


@pytest.mark.parametrize("edit", list(AFTER), ids=list(AFTER))
def test_the_checksum_covers_what_a_reader_interprets(work, capsys, reference, edit):
    """Edited in the array's own metadata and in the consolidated metadata alike (a reader
    with or without it sees the edit): DAMAGED."""
    shutil.copytree(reference, work / "out.zarr")
    store = work / "out.zarr"
    array, change = AFTER[edit]
    _meta(array, change)(store)
    root = json.loads((store / "zarr.json").read_text())
    change(root["consolidated_metadata"]["metadata"][array])
    (store / "zarr.json").write_text(json.dumps(root, indent=2))
    status, out, err = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 1 and "DAMAGED" in out, out + err


# --- a store damaged during the run --------------------------------------------------------------

DAMAGE_AT = """
import sys
from pathlib import Path
from engine.cli import main
import engine.runner as runner
real = runner._compute
def compute(store, *args):
    for item in real(store, *args):
        yield item
    meta = Path(store.store) / sys.argv[1] / "zarr.json"  # every block stored: damaged now
    meta.write_text(meta.read_text().replace('":', '" '))
runner._compute = compute
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize("array", ["r_min", "r_circ"])
def test_damaged_metadata_during_the_run_is_not_blamed_on_the_survey(work, capsys, array):
    """An array's zarr.json made invalid JSON once every block is stored: exit 1 naming the
    file, not exit 2 ("bad input, nothing written") naming the survey file; ``info`` says the
    rerun resumes, and it does: the store verifies."""
    proc = subprocess.run([sys.executable, "-c", DAMAGE_AT, array, *ARGS], cwd=work,
                          env=runs.env(), capture_output=True, text=True, timeout=300)  # fmt: skip
    err = proc.stderr
    assert proc.returncode == 1, err
    assert f"{array}/zarr.json" in err and "s.toml" not in err and err.count("\n") == 1, err
    assert "the run is resumable" in err and "Traceback" not in err, err
    status, out, _ = cli(capsys, "info", "out.zarr")
    assert "8/8 blocks stored; rerun to resume" in out, out
    status, _, err = cli(capsys, *ARGS)
    assert status == 0 and f"{array}/zarr.json" in err and "written again" in err, err
    status, out, _ = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 0 and "complete, verified" in out, out


# --- convert of a damaged store --------------------------------------------------------------


def _without(array: str):
    """The array removed from the store and from its consolidated metadata alike (what a
    commit that did not check its arrays could leave)."""

    def edit(store: Path) -> None:
        shutil.rmtree(store / array)
        root = json.loads((store / "zarr.json").read_text())
        del root["consolidated_metadata"]["metadata"][array]
        (store / "zarr.json").write_text(json.dumps(root, indent=2))

    return edit


@pytest.mark.parametrize(
    "damage",
    [_without("h"), _without("r_circ"), _removed("Lz"), _meta("r_min", lambda d: d.pop("shape"))],
    ids=["h gone", "r_circ gone", "Lz directory gone", "r_min without a shape"],
)
def test_convert_of_a_damaged_store_is_one_line(work, capsys, reference, damage):
    shutil.copytree(reference, work / "out.zarr")
    damage(work / "out.zarr")
    status, out, err = cli(capsys, "convert", "out.zarr", "out.nc")
    assert status == 2 and err.startswith("conesurvey: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err and not (work / "out.nc").exists(), err


def test_any_value_error_after_writing_began_is_not_blamed_on_the_survey(work, capsys, monkeypatch):
    """What a damaged store made zarr raise in the commit before the commit checked it (a
    JSONDecodeError is a ValueError): exit 1, resumable, the survey file not named."""
    from engine.io import zarr as zarr_io

    def damaged(*args, **kwargs):
        raise json.JSONDecodeError("Expecting ':' delimiter", "{}", 1)

    monkeypatch.setattr(zarr_io, "commit_store", damaged)
    status, _, err = cli(capsys, *ARGS)
    assert status == 1 and "Expecting ':' delimiter" in err and "s.toml" not in err, err
    assert "the run is resumable" in err and err.count("\n") == 1, err
    monkeypatch.undo()
    monkeypatch.chdir(work)
    status, _, err = cli(capsys, *ARGS)
    assert status == 0, err


def _record_damaged(parts: Path) -> None:
    (parts / "commit.json").write_text("{not json")


def _store_a_file(parts: Path) -> None:
    shutil.rmtree(parts / "store.zarr")
    (parts / "store.zarr").write_text("not a store")


@pytest.mark.parametrize("damage", [_record_damaged, _store_a_file], ids=["record", "store"])
def test_info_says_what_the_rerun_does(work, capsys, partial, damage):
    """An unfinished run the rerun cannot resume: ``info`` says so (and how out), the rerun
    refuses for the same reason, and what ``info`` advises then works."""
    shutil.copytree(partial, work / "out.zarr.parts")
    damage(work / "out.zarr.parts")
    _, out, _ = cli(capsys, "info", "out.zarr")
    assert "cannot be resumed" in out and "--overwrite" in out, out
    status, _, err = cli(capsys, *ARGS)
    assert status == 2 and "cannot resume" in err and "--overwrite" in err, err
    status, _, err = cli(capsys, *ARGS, "--overwrite")
    assert status == 0, err

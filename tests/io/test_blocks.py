"""engine.io.blocks: the block store, its journal of checksums, its scan and the run summary.

Resume, refusal of another survey and recomputation of corrupt blocks through a whole run are
in tests/test_runner.py and tests/test_attacks.py; random interleavings in
tests/io/test_store_machine.py.
"""

from __future__ import annotations

import hashlib
import os

import numpy as np
import pytest
import runs

from engine.grid import Tiling
from engine.io import OutputError
from engine.io.blocks import (
    JOURNAL,
    BlockStore,
    block_file_bytes,
    check_parts_dir,
    estimate_bytes,
    parts_info,
    read_journal,
)
from engine.io.manifest import MANIFEST, Manifest, parts_dir, survey_variables
from engine.io.summary import Summary
from engine.plan import plan_from_survey
from engine.surveyfile import parse_survey

SURVEY = runs.gravity_survey("blocks test", alpha=(0.3, 0.6), energy=5, h=2, lz=3)


@pytest.fixture
def survey():
    return parse_survey(SURVEY)


@pytest.fixture
def store(tmp_path, survey):
    tiling = Tiling(survey.shape, (1, 1, 2, 3), (1, 1, 2, 3))  # 60 points in 10 blocks
    warnings: list[str] = []
    s = BlockStore.create(
        tmp_path / "o.nc.parts", Manifest.new(plan_from_survey(survey), tiling), warnings.append
    )
    s.warnings = warnings
    return s


def block_of(store, index, value=1.0):
    shape = tuple(sl.stop - sl.start for sl in store.tiling.slices(index))
    out = {}
    for name, dt in store.names.items():
        out[name] = np.full(shape, 1 if dt.kind in "iu" else value, dt)
    return out


def names(directory):
    return sorted(os.listdir(directory))


def test_estimate_bytes_counts_every_variable(survey):
    # orbit_class int8 + 6 closed-form floats per point (r_circ and V_min are on (alpha, h,
    # Lz): not in the blocks)
    assert estimate_bytes(plan_from_survey(survey)) == (1 + 8 * 6) * 60
    assert sum(dt.itemsize for dt in survey_variables(plan_from_survey(survey)).values()) == 49


def test_block_file_bytes_bounds_the_real_file(store):
    store.commit(3, block_of(store, 3))
    size = store.path(3).stat().st_size
    points = store.tiling.points(3)
    assert 65 * points < size <= block_file_bytes(store.names, points)


# --- creating and committing ------------------------------------------------------------------


def test_create_makes_a_private_directory_with_manifest_and_journal(store):
    assert names(store.root) == [JOURNAL, MANIFEST]
    assert os.stat(store.root).st_mode & 0o777 == 0o700
    assert (store.root / JOURNAL).read_bytes() == b""
    with pytest.raises(FileExistsError):
        BlockStore.create(
            store.root, Manifest.new(plan_from_survey(parse_survey(SURVEY)), store.tiling)
        )


def test_commit_journals_size_and_sha256_and_casts_to_the_schema_dtypes(store):
    arrays = {n: a.astype(np.float32) for n, a in block_of(store, 0).items()}  # wrong dtypes
    store.commit(0, arrays)
    data = store.path(0).read_bytes()
    line = (store.root / JOURNAL).read_text()
    index, size, digest, check = line.split()
    assert (int(index), int(size), digest) == (0, len(data), hashlib.sha256(data).hexdigest())
    assert len(check) == 16 and line.endswith("\n")
    back = store.load(0)
    assert list(back) == list(store.names)
    assert all(back[n].dtype == dt for n, dt in store.names.items())
    assert names(store.root) == ["b00000000.npz", JOURNAL, MANIFEST]
    assert os.stat(store.path(0)).st_mode & 0o777 == 0o600


def test_open_reads_the_journal_and_scan_verifies_every_block(store):
    for i in range(3):
        store.commit(i, block_of(store, i, value=float(i)))
    again = BlockStore.open(store.root)
    assert again.tiling == store.tiling and again.names == store.names
    assert again.scan().good == {0, 1, 2}


# --- the scan: what does not verify -----------------------------------------------------------


def test_scan_reports_truncated_edited_swapped_unrecorded_and_linked_blocks(store, tmp_path):
    for i in range(7):
        store.commit(i, block_of(store, i, value=float(i)))
    p = store.path
    p(0).write_bytes(p(0).read_bytes()[:100])  # torn
    data = bytearray(p(1).read_bytes())
    data[-200] ^= 1  # one flipped bit in the values
    p(1).write_bytes(bytes(data))
    b2, b3 = p(2).read_bytes(), p(3).read_bytes()
    p(2).write_bytes(b3)  # swapped
    p(3).write_bytes(b2)
    os.unlink(p(4))
    os.symlink(p(5), p(4))  # a link to a good block of the same size
    lines = (store.root / JOURNAL).read_bytes().splitlines(keepends=True)
    (store.root / JOURNAL).write_bytes(b"".join(lines[:6]))  # block 6 lost its line
    found = BlockStore.open(store.root).scan()
    assert found.good == {5}
    assert found.bad == {
        "b00000000.npz": "not a regular file of the recorded size",
        "b00000001.npz": "its checksum does not match the journal",
        "b00000002.npz": "its checksum does not match the journal",
        "b00000003.npz": "its checksum does not match the journal",
        "b00000004.npz": "not a regular file of the recorded size",
        "b00000006.npz": "not recorded in the journal",
    }


def test_stray_files_are_reported_not_blamed_on_the_survey(store):
    store.commit(1, block_of(store, 1))
    for stray in ("b-0000001.npz", "bogus.npz", f"b{store.tiling.nblocks:08d}.npz", "notes"):
        (store.root / stray).write_bytes(b"")
    (store.root / "b00000002.npz.0123456789ab.tmp").write_bytes(b"half")
    found = store.scan()
    assert found.good == {1} and found.bad == {}
    assert found.tmp == ["b00000002.npz.0123456789ab.tmp"]
    assert found.stray == ["b-0000001.npz", "b00000010.npz", "bogus.npz", "notes"]
    store.discard(found)
    assert "b00000002.npz.0123456789ab.tmp" not in names(store.root)
    assert "notes" in names(store.root)  # not ours: reported, left alone
    (warning,) = store.warnings
    assert "not blocks of this run" in warning and "b-0000001.npz" in warning


def test_discard_reports_and_removes_bad_blocks(store):
    for i in range(2):
        store.commit(i, block_of(store, i))
    store.path(0).write_bytes(b"x")
    found = store.scan()
    store.discard(found)
    assert not store.path(0).exists() and store.path(1).exists()
    assert any("b00000000.npz is corrupt" in w and "recomputing" in w for w in store.warnings)


def test_a_torn_or_damaged_journal_line_is_ignored(store):
    store.commit(0, block_of(store, 0))
    store.commit(1, block_of(store, 1))
    raw = (store.root / JOURNAL).read_bytes()
    first, second = raw.splitlines(keepends=True)
    (store.root / JOURNAL).write_bytes(first + second[:30])  # killed mid-append
    assert set(read_journal(store.root, store.tiling.nblocks)) == {0}
    flipped = first.replace(b"0 ", b"1 ", 1)  # index changed: the line check fails
    (store.root / JOURNAL).write_bytes(flipped + second)
    assert set(read_journal(store.root, store.tiling.nblocks)) == {1}


def test_the_last_journal_line_of_a_block_wins(store):
    store.commit(0, block_of(store, 0, value=1.0))
    store.commit(0, block_of(store, 0, value=2.0))  # recomputed after a corruption
    again = BlockStore.open(store.root)
    assert again.scan().good == {0}
    assert np.all(again.load(0)["r_min"] == 2.0)


# --- loading for the merge --------------------------------------------------------------------


def test_blocks_yields_every_block_in_order_or_refuses_a_gap(store):
    n = store.tiling.nblocks
    for i in range(n):
        store.commit(i, block_of(store, i, value=float(i)))
    got = list(store.blocks())
    assert [sl for sl, _ in got] == [store.tiling.slices(i) for i in range(n)]
    assert all(np.all(b["r_min"] == i) for i, (_, b) in enumerate(got))
    store.path(n - 1).unlink()
    with pytest.raises(OutputError, match=f"block file b{n - 1:08d}.npz vanished"):
        list(store.blocks())


def test_a_block_changed_after_the_scan_is_refused_and_deleted(store):
    for i in range(store.tiling.nblocks):
        store.commit(i, block_of(store, i, value=float(i)))
    store.path(4).write_bytes(store.path(3).read_bytes())
    with pytest.raises(OutputError, match="b00000004.npz changed since it was written"):
        list(store.blocks())
    assert not store.path(4).exists()  # so that the next run computes it again


def test_a_journaled_file_of_the_wrong_layout_is_refused(store):
    wrong = {n: np.zeros(7, dt) for n, dt in store.names.items()}
    store.commit(2, wrong)  # journaled, but not the shape of block 2
    with pytest.raises(OutputError, match="wrong orbit_class layout"):
        store.load(2)


# --- the directory ----------------------------------------------------------------------------


def test_check_parts_dir_refuses_links_files_and_shared_directories(tmp_path):
    root = parts_dir(tmp_path / "o.nc")
    assert check_parts_dir(root) is False
    (tmp_path / "elsewhere").mkdir()
    root.symlink_to(tmp_path / "elsewhere")
    with pytest.raises(OutputError, match="symbolic link"):
        check_parts_dir(root)
    root.unlink()
    root.write_bytes(b"")
    with pytest.raises(OutputError, match="not a directory"):
        check_parts_dir(root)
    root.unlink()
    root.mkdir(mode=0o700)
    assert check_parts_dir(root) is True
    os.chmod(root, 0o777)
    with pytest.raises(OutputError, match="writable by other users"):
        check_parts_dir(root)


def test_remove_deletes_the_manifest_first(store, monkeypatch):
    store.commit(0, block_of(store, 0))
    seen = []
    real = os.unlink

    def spy(path, *a, **k):
        seen.append(sorted(os.listdir(store.root)))
        real(path, *a, **k)

    monkeypatch.setattr(os, "unlink", spy)
    store.remove()
    # a kill after the first unlink leaves a store without manifest
    assert seen[:2] == [["b00000000.npz", JOURNAL, "manifest.json"], ["b00000000.npz", JOURNAL]]
    assert not store.root.exists()


def test_parts_info_of_an_unfinished_run(store):
    store.commit(2, block_of(store, 2))
    info = parts_info(store.root)
    assert info["complete"] is False
    assert info["dims"] == {"alpha": 2, "energy": 5, "h": 2, "Lz": 3}
    assert info["blocks_done"] == 1 and info["blocks_total"] == store.tiling.nblocks
    assert info["attrs"]["survey_definition"] == SURVEY


# --- summary ----------------------------------------------------------------------------------


def test_summary_counts_classes_and_finite_ranges():
    s = Summary()
    s.add({"orbit_class": np.array([1, 1, 2], np.int8), "r_min": np.array([np.nan, 2.0, 3.0])})
    s.add({"orbit_class": np.array([0], np.int8), "r_min": np.array([-np.inf])})
    s.add(
        {
            "orbit_class": np.array([5], np.int8),
            "r_min": np.array([0.5]),
            "n_steps": np.ones(1, np.int64),
        }
    )
    np.testing.assert_array_equal(s.counts, [1, 2, 1, 0, 0, 1, 0, 0, 0, 0])
    assert s.ranges == {"r_min": (0.5, 3.0, "m")}
    s.add({"fate": np.array([1, 2, 2], np.int8)})  # every flag variable is counted
    # one slot per fate code of any map kind: 0..6, 7 sliding and 8 spinning (sliding fate maps),
    # 9 lifted_off (surface fate maps)
    np.testing.assert_array_equal(s.flags["fate"], [0, 1, 2, 0, 0, 0, 0, 0, 0, 0])

"""engine.io.blocks: the block store, its manifest, the survey fingerprint and the run summary.

Resume, refusal of another survey and recomputation of corrupt blocks through a whole run are
in tests/test_runner.py.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from engine.grid import Tiling
from engine.io import OutputError, blocks
from engine.io.blocks import (
    MANIFEST,
    BlockStore,
    Manifest,
    Summary,
    estimate_bytes,
    fingerprint,
    parts_dir,
    parts_info,
    read_manifest,
    survey_variables,
    write_manifest,
)
from engine.surveyfile import parse_survey

SURVEY = """\
title = "blocks test"

[axes.alpha]
values = [0.3, 0.6]

[axes.energy]
start = 1e-6
stop = 10.0
num = 5
scale = "log"
relative_to = "V_min"

[axes.h]
values = [-1.0, 1.0]

[axes.Lz]
start = 0.05
stop = 1.0
num = 3
"""


@pytest.fixture
def survey():
    return parse_survey(SURVEY)


@pytest.fixture
def store(tmp_path, survey):
    tiling = Tiling(survey.shape, (1, 1, 2, 3), (1, 1, 2, 3))  # 60 points in 10 blocks
    warnings: list[str] = []
    s = BlockStore(tmp_path, tiling, survey_variables(survey), warnings.append)
    s.warnings = warnings
    return s


def block_of(store, index, value=1.0):
    shape = tuple(sl.stop - sl.start for sl in store.tiling.slices(index))
    out = {}
    for name, dt in store.names.items():
        out[name] = np.full(shape, 1 if dt.kind in "iu" else value, dt)
    return out


# --- fingerprint and sizes --------------------------------------------------------------------


def test_fingerprint_is_stable_and_sees_every_input(survey, monkeypatch):
    fp = fingerprint(survey)
    assert len(fp) == 64 and fp == fingerprint(parse_survey(SURVEY))
    variants = [
        SURVEY.replace("blocks test", "other"),
        SURVEY.replace("num = 5", "num = 6"),
        SURVEY.replace('relative_to = "V_min"\n', ""),
        SURVEY + "\n[scene]\ng = 1.62\n",
        'method = "rk45"\n' + SURVEY,
        "rtol = 1e-8\n" + SURVEY,
    ]
    fps = {fingerprint(parse_survey(text)) for text in variants}
    assert len(fps) == len(variants) and fp not in fps
    monkeypatch.setattr(blocks, "__version__", "9.9.9")
    assert fingerprint(survey) != fp


def test_estimate_bytes_counts_every_variable(survey):
    # orbit_class int8 + 7 closed-form floats + energy_absolute (relative energy axis)
    assert estimate_bytes(survey) == (1 + 8 * 7 + 8) * 60
    assert sum(dt.itemsize for dt in survey_variables(survey).values()) == 65


# --- manifest ---------------------------------------------------------------------------------


def test_manifest_round_trip_and_format(tmp_path, survey):
    tiling = Tiling(survey.shape, (1, 1, 2, 3), (1, 1, 2, 3))
    m = Manifest.new(survey, tiling)
    assert m.fingerprint == fingerprint(survey) and m.engine == blocks.__version__
    write_manifest(tmp_path, m)
    assert read_manifest(tmp_path) == m
    doc = json.loads((tmp_path / MANIFEST).read_text())
    assert doc == {
        "fingerprint": m.fingerprint,
        "engine": m.engine,
        "shape": list(tiling.shape),
        "chunk": list(tiling.chunk),
        "block": list(tiling.block),
        "survey_definition": SURVEY,
    }
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST]


@pytest.mark.parametrize("text", [None, "{not json", '{"fingerprint": "x"}', '{"shape": 3}'])
def test_unreadable_manifest_is_an_output_error(tmp_path, text):
    if text is not None:
        (tmp_path / MANIFEST).write_text(text)
    with pytest.raises(OutputError, match="manifest.json is unreadable"):
        read_manifest(tmp_path)


def test_parts_info_of_an_unfinished_run(tmp_path, survey, store):
    root = parts_dir(tmp_path / "out.nc")
    assert root == tmp_path / "out.nc.parts"
    root.mkdir()
    write_manifest(root, Manifest.new(survey, store.tiling))
    BlockStore(root, store.tiling, store.names).save(2, block_of(store, 2))
    info = parts_info(root)
    assert info["complete"] is False
    assert info["dims"] == {"alpha": 2, "energy": 5, "h": 2, "Lz": 3}
    assert info["blocks_done"] == 1 and info["blocks_total"] == store.tiling.nblocks
    assert info["attrs"]["survey_definition"] == SURVEY


# --- the store --------------------------------------------------------------------------------


def test_save_load_round_trip_casts_to_the_schema_dtypes(store):
    arrays = {n: a.astype(np.float32) for n, a in block_of(store, 0).items()}  # wrong dtypes
    store.save(0, arrays)
    back = store.load(0)
    assert list(back) == list(store.names)
    for name, dt in store.names.items():
        assert back[name].dtype == dt
    assert store.done() == store.verify() == {0}
    assert sorted(p.name for p in store.root.iterdir()) == ["b00000000.npz"]


def test_done_ignores_foreign_files_and_indices_beyond_the_grid(store):
    store.save(1, block_of(store, 1))
    (store.root / "bogus.npz").write_bytes(b"")
    (store.root / f"b{store.tiling.nblocks:08d}.npz").write_bytes(b"")
    assert store.done() == {1}


def test_corrupt_or_misshapen_block_is_reported_removed_and_recomputed(store):
    for i in range(3):
        store.save(i, block_of(store, i))
    p0 = store.path(0)
    p0.write_bytes(p0.read_bytes()[:100])  # a torn write
    wrong = {n: np.zeros(7, dt) for n, dt in store.names.items()}
    np.savez(store.path(1), **wrong)  # right names, wrong shape
    assert store.verify() == {2}
    assert any("corrupt" in w and p0.name in w for w in store.warnings)
    assert any("wrong" in w and store.path(1).name in w for w in store.warnings)
    assert not p0.exists() and not store.path(1).exists()


def test_remove_stale_tmp(store):
    store.save(0, block_of(store, 0))
    (store.root / "b00000001.npz.tmp").write_bytes(b"stale")
    store.remove_stale_tmp()
    assert sorted(p.name for p in store.root.iterdir()) == ["b00000000.npz"]


def test_blocks_yields_every_block_in_order_or_refuses_a_gap(store):
    n = store.tiling.nblocks
    for i in range(n):
        store.save(i, block_of(store, i, value=float(i)))
    got = list(store.blocks())
    assert [sl for sl, _ in got] == [store.tiling.slices(i) for i in range(n)]
    assert all(np.all(b["r_min"] == i) for i, (_, b) in enumerate(got))
    store.path(n - 1).unlink()
    with pytest.raises(OutputError, match=f"block {n - 1} vanished"):
        list(store.blocks())


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
    np.testing.assert_array_equal(s.counts, [1, 2, 1, 0, 0, 1])
    assert s.ranges == {"r_min": (0.5, 3.0, "m")}

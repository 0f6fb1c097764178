"""engine.io.journal: the journal of a run's blocks, and block files stored on their own thread.

Through a whole run: tests/test_runner.py (a run stopped after n stored blocks keeps exactly
n), tests/io/test_chunkfile.py and tests/test_enospc.py.
"""

from __future__ import annotations

import errno
import os
import threading

import numpy as np
import pytest
import runs

from engine.grid import Tiling
from engine.io import atomic
from engine.io.blocks import BlockStore
from engine.io.journal import DEPTH, JOURNAL, journal_line, read_journal
from engine.io.manifest import MANIFEST, Manifest
from engine.plan import plan_from_survey
from engine.surveyfile import parse_survey

SURVEY = runs.gravity_survey("journal test", alpha=(0.3, 0.6), energy=5, h=2, lz=3)


@pytest.fixture
def store(tmp_path):
    survey = parse_survey(SURVEY)
    tiling = Tiling(survey.shape, (1, 1, 2, 3), (1, 1, 2, 3))  # 60 points in 10 blocks
    manifest = Manifest.new(plan_from_survey(survey), tiling)
    return BlockStore.create(tmp_path / "o.nc.parts", manifest)


def block_of(store, index, value=1.0):
    shape = tuple(sl.stop - sl.start for sl in store.tiling.slices(index))
    return {n: np.full(shape, 1 if dt.kind in "iu" else value, dt) for n, dt in store.names.items()}


def journaled(store):
    return set(read_journal(store.root, store.tiling.nblocks))


def files(store):
    return sorted(os.listdir(store.root))


def names_of(store, indices):
    return sorted([MANIFEST, JOURNAL, *(store.path(i).name for i in indices)])


def test_a_torn_or_edited_line_is_ignored(tmp_path):
    (tmp_path / JOURNAL).write_bytes(
        journal_line(0, 10, "ab" * 32)
        + journal_line(1, 11, "cd" * 32).replace(b" 11 ", b" 12 ")  # edited: its check fails
        + journal_line(2, 12, "ef" * 32)[:-9]  # torn: no newline
    )
    assert read_journal(tmp_path, 10) == {0: (10, "ab" * 32)}


def test_blocks_are_journaled_in_order_once_durable(store):
    seen = []

    def on_durable(index):  # the file is in place and its line durable when it is called
        assert index in journaled(store) and store.path(index).is_file()
        seen.append(index)

    with store.behind(on_durable):
        for i in range(6):
            store.commit(i, block_of(store, i, float(i)))
    assert seen == list(range(6))
    assert store.scan().good == set(range(6)) and files(store) == names_of(store, range(6))
    for i in range(6):
        assert np.all(store.load(i)["period"] == float(i))


def test_a_failing_hook_stops_the_blocks_after_it(store):
    def stop(index):
        if index == 1:
            raise KeyboardInterrupt  # stands for a run killed after two stored blocks

    with pytest.raises(KeyboardInterrupt), store.behind(stop):
        for i in range(8):
            store.commit(i, block_of(store, i))
    assert journaled(store) == {0, 1}
    assert files(store) == names_of(store, [0, 1])  # nothing later written, no temporary file


def test_a_full_disk_is_raised_on_the_runs_thread(store, monkeypatch):
    real_fsync = os.fsync

    def fsync(fd):  # the disk fills up as block 2's file is flushed
        if store.path(2).name in os.readlink(f"/proc/self/fd/{fd}"):
            raise OSError(errno.ENOSPC, "No space left on device")
        real_fsync(fd)

    monkeypatch.setattr(atomic.os, "fsync", fsync)
    with pytest.raises(OSError, match="No space left") as info, store.behind():
        for i in range(8):
            store.commit(i, block_of(store, i))
    assert info.value.errno == errno.ENOSPC
    assert journaled(store) == {0, 1} and files(store) == names_of(store, [0, 1])


def test_the_runs_error_still_stores_what_was_committed(store):
    with pytest.raises(RuntimeError, match="compute failed"), store.behind():
        for i in range(3):
            store.commit(i, block_of(store, i))
        raise RuntimeError("compute failed")
    assert journaled(store) == {0, 1, 2} and store.scan().good == {0, 1, 2}


def test_load_waits_for_a_block_on_its_way(store):
    gate = threading.Event()

    def slow(index):
        if index == 0:
            assert gate.wait(10)

    with store.behind(slow):
        store.commit(0, block_of(store, 0))
        store.commit(1, block_of(store, 1, 7.0))
        assert 1 not in store.journal  # the thread is held at block 0
        threading.Timer(0.2, gate.set).start()
        assert np.all(store.load(1)["period"] == 7.0)
    assert journaled(store) == {0, 1}


def test_commit_waits_while_depth_blocks_are_queued(store):
    gate = threading.Event()

    def slow(index):
        if index == 0:
            assert gate.wait(10)

    with store.behind(slow):
        store.commit(0, block_of(store, 0))  # taken by the thread, which waits in the hook
        while 0 not in store.journal:
            threading.Event().wait(0.01)
        for i in range(1, 1 + DEPTH):
            store.commit(i, block_of(store, i))
        late = threading.Thread(target=store.commit, args=(1 + DEPTH, block_of(store, 1 + DEPTH)))
        late.start()
        late.join(0.3)
        assert late.is_alive()  # no room: it waits for the thread
        gate.set()
        late.join(10)
        assert not late.is_alive()
    assert journaled(store) == set(range(2 + DEPTH))

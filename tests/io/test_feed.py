"""engine.io.feed: the writer thread gets every block once, in index order, while the caller
goes on computing; memory stays within the held blocks; failures surface where they should."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import runs

from engine.io import OutputError
from engine.io.feed import BlockFeed, feed
from engine.runner import run_survey
from engine.surveyfile import parse_survey


class FakeStore:
    """A block store of ``n`` one-value blocks; ``take`` counts what is read back."""

    class _Tiling:
        def __init__(self, n: int) -> None:
            self.nblocks = n

    def __init__(self, n: int, committed: tuple[int, ...] = ()) -> None:
        self.tiling = self._Tiling(n)
        self.committed = set(committed)
        self.taken: list[int] = []
        self.lock = threading.Lock()

    def arrays(self, index: int) -> dict[str, np.ndarray]:
        return {"v": np.full(3, float(index))}

    def take(self, index: int) -> dict[str, np.ndarray]:
        with self.lock:
            self.taken.append(index)
            if index not in self.committed:
                raise OutputError(f"block {index} is missing")
        return self.arrays(index)


class Recorder:
    """A ``write`` that records (index, value) and how many handed-over blocks were alive."""

    def __init__(self, delay: float = 0.0, fail_at: int | None = None) -> None:
        self.delay = delay
        self.fail_at = fail_at
        self.written: list[tuple[int, float]] = []
        self.put = 0  # blocks handed over so far (set by the producer)
        self.alive_max = 0

    def __call__(self, index: int, arrays: dict[str, np.ndarray]) -> None:
        if index == self.fail_at:
            raise RuntimeError("NetCDF: HDF error")
        self.alive_max = max(self.alive_max, self.put - len(self.written))
        time.sleep(self.delay)
        self.written.append((index, float(arrays["v"][0])))


def produce(store: FakeStore, order, recorder: Recorder):
    """What the runner's compute yields: each block committed, then handed over."""
    for i in order:
        store.committed.add(i)
        recorder.put += 1
        yield i, store.arrays(i)


def test_blocks_arriving_in_any_order_are_written_once_in_index_order():
    """Blocks handed over out of order (dask) and blocks of an earlier run are all written,
    in order, each once; only those not held are read back from the store, and a block that
    comes ahead is held while there is room (not read back again)."""
    n = 12
    store = FakeStore(n, committed=(0, 1))  # resumed: 0 and 1 stored by an earlier run
    rec = Recorder()
    order = [3, 2, 4, 5, 7, 6, 11, 8, 9, 10]
    feed(store, rec, [i for i in range(n) if i > 1], produce(store, order, rec))
    assert rec.written == [(i, float(i)) for i in range(n)]
    assert {0, 1} <= set(store.taken) and len(store.taken) == len(set(store.taken))
    # 3 came ahead of 2 while nothing was held: held, as 4 (in turn once 2 and 3 were in)
    assert 3 not in store.taken and 4 not in store.taken


def test_memory_is_bounded_by_the_held_blocks_while_the_writer_is_slow():
    """A fast compute and a slow writer: put() waits, so at most `held` blocks wait in memory
    besides the one being written."""
    n, held = 16, 2
    store = FakeStore(n)
    rec = Recorder(delay=0.01)
    feed(store, rec, range(n), produce(store, range(n), rec), held=held)
    assert rec.written == [(i, float(i)) for i in range(n)]
    assert store.taken == []  # every block came from memory
    assert 1 <= rec.alive_max <= held + 1, rec.alive_max


def test_writer_failure_is_raised_by_finish_after_every_block_is_stored():
    """The writer fails at block 3: the compute is not blocked (every block is still stored,
    to be resumed from) and finish() raises the writer's error; nothing after 3 is written."""
    n = 10
    store = FakeStore(n)
    rec = Recorder(fail_at=3)
    with pytest.raises(RuntimeError, match="HDF error"):
        feed(store, rec, range(n), produce(store, range(n), rec), held=1)
    assert store.committed == set(range(n))
    assert [i for i, _ in rec.written] == [0, 1, 2]


def test_a_bad_stored_block_stops_the_feed_with_its_error():
    """A block of an earlier run that fails its checksum (take raises) ends the feed with
    that OutputError, after the blocks before it are written."""
    store = FakeStore(4, committed=(0, 2, 3))  # 1 is "bad": take raises
    rec = Recorder()
    with pytest.raises(OutputError, match="block 1"):
        feed(store, rec, [], iter(()))
    assert [i for i, _ in rec.written] == [0]


def test_an_error_of_the_compute_stops_the_writer_and_is_raised_as_it_is():
    store = FakeStore(6)
    rec = Recorder(delay=0.01)

    def failing():
        yield from produce(store, range(3), rec)
        raise KeyboardInterrupt

    before = threading.active_count()
    with pytest.raises(KeyboardInterrupt):
        feed(store, rec, range(6), failing())
    assert threading.active_count() == before  # the writer thread has ended
    assert [i for i, _ in rec.written] == list(range(len(rec.written)))
    assert len(rec.written) <= 3


def test_finish_reads_ahead_blocks_not_handed_over():
    """Once the compute is over, finish() reads the remaining stored blocks (verifying them)
    ahead of the writer: all are written, each read once."""
    n = 8
    store = FakeStore(n, committed=range(n))
    rec = Recorder(delay=0.005)
    with BlockFeed(store, rec, set(range(n))) as f:
        f.finish()
    assert rec.written == [(i, float(i)) for i in range(n)]
    assert sorted(store.taken) == list(range(n))


def test_a_run_interrupted_while_its_output_is_written_leaves_only_blocks(tmp_path):
    """The output is open while the blocks are computed: an interruption then removes it
    (nothing under the output's name, no temporary file in the store) and the rerun resumes
    from the stored blocks to the same file as an uninterrupted run."""
    # 3 x 40 x 33 x 60 points in 4 blocks
    text = runs.gravity_survey("interrupted", alpha=(0.3, 0.6, 0.9), energy=40, lz=60)
    survey = parse_survey(text)
    out = tmp_path / "out.nc"
    seen: list[int] = []

    def crash(index: int) -> None:
        seen.append(index)
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_survey(survey, out, block_points=1 << 14, on_block=crash)
    assert runs.listing(tmp_path) == ["out.nc.parts"]
    parts = runs.listing(tmp_path / "out.nc.parts")
    assert runs.blocks_in(tmp_path / "out.nc.parts") == 2
    assert not [n for n in parts if n.endswith(".tmp")], parts
    stats = run_survey(survey, out, block_points=1 << 14)
    assert (stats.blocks_reused, stats.blocks_total) == (2, 4)
    run_survey(survey, tmp_path / "ref.nc", block_points=1 << 14)
    runs.same_content(out, tmp_path / "ref.nc")

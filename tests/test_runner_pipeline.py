"""The local backend computes blocks ahead (``AHEAD``): block k + 1 and the ones
after it run on a thread of their own while the run stores and writes block k, errors come out
in block order, and a run that stops early leaves no compute thread behind. Blocks are
computed into reused buffers, a set given out again only once nothing refers to it."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import runs

from engine import backends
from engine.blockbuffers import Buffers
from engine.grid import Tiling
from engine.pipeline import AHEAD, written_behind
from engine.plan import plan_from_survey
from engine.surveyfile import parse_survey


class _NoBuffers:
    def __init__(self, plan, tiling):
        pass

    def take(self, busy=()):
        return None


@pytest.fixture
def no_buffers(monkeypatch):
    """The fakes below compute nothing: no plan to size buffers by."""
    monkeypatch.setattr(backends, "Buffers", _NoBuffers)


def _fake(started: list[int], fail_at: int | None = None):
    def compute_block(plan, tiling, index, out=None):
        started.append(index)
        if index == fail_at:
            raise ZeroDivisionError(f"block {index}")
        return index, {"v": np.full(2, index)}

    return compute_block


def _wait_for(cond, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while not cond() and time.monotonic() < end:
        time.sleep(0.005)
    return cond()


def _compute_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("conesurvey-compute")]


def test_the_next_block_is_computed_while_the_caller_holds_this_one(monkeypatch, no_buffers):
    started: list[int] = []
    monkeypatch.setattr(backends, "compute_block", _fake(started))
    pending = list(range(4, 8))
    blocks = backends.LocalBackend().blocks(None, None, pending)
    assert next(blocks)[0] == 4
    ahead = pending[: 1 + AHEAD]  # AHEAD blocks after it queued, running in turn
    assert _wait_for(lambda: started == ahead), started
    assert [i for i, _ in blocks] == pending[1:]
    assert not _compute_threads()


def test_an_error_comes_out_in_block_order_and_stops_the_compute(monkeypatch, no_buffers):
    started: list[int] = []
    monkeypatch.setattr(backends, "compute_block", _fake(started, fail_at=1))
    got = []
    with pytest.raises(ZeroDivisionError, match="block 1"):
        for i, _ in backends.LocalBackend().blocks(None, None, [0, 1, 2, 3]):
            got.append(i)
    assert got == [0]
    assert 3 not in started  # nothing is computed past the block that failed and the next
    assert not _compute_threads()


def test_a_run_that_stops_early_waits_for_the_block_in_the_compute(monkeypatch, no_buffers):
    started: list[int] = []
    monkeypatch.setattr(backends, "compute_block", _fake(started))
    blocks = backends.LocalBackend().blocks(None, None, list(range(AHEAD + 3)))
    next(blocks)
    blocks.close()  # the runner leaving (an error, KeyboardInterrupt)
    assert not _compute_threads()
    assert AHEAD + 2 not in started  # never queued


# 3 x 20 x 33 x 160 points in 8 blocks of one chunk (3, 20, 33, 20)
SURVEY = runs.gravity_survey("buffers", alpha=(0.3, 0.8, 1.3), energy=20, h=33, lz=160)


def test_blocks_computed_into_reused_buffers_are_the_fresh_blocks():
    """Eight blocks, the caller holding each one's arrays until the next arrives (as the store
    does): every block bit for bit its fresh compute, and 2 + AHEAD sets of buffers serve them
    all (the block the caller holds, the one it is handed next, the ones computed meanwhile)."""
    plan = plan_from_survey(parse_survey(SURVEY))
    tiling = Tiling.for_grid(plan.shape, 16_000)
    assert tiling.nblocks == 8
    made = []

    class Counted(Buffers):
        def take(self, busy=()):
            got = super().take(busy)
            made[:] = [len(self.sets)]
            return got

    real = backends.Buffers
    backends.Buffers = Counted
    try:
        for i, block in backends.LocalBackend().blocks(plan, tiling, list(range(8))):
            _, fresh = backends.compute_block(plan, tiling, i)
            assert set(block) == set(fresh)
            for name, values in fresh.items():
                assert block[name].dtype == values.dtype and block[name].shape == values.shape
                assert np.array_equal(block[name], values, equal_nan=True), (i, name)
            assert all(np.shares_memory(a, b) is False for a, b in zip(block.values(),
                       fresh.values(), strict=True))  # fmt: skip
    finally:
        backends.Buffers = real
    assert made == [2 + AHEAD]


def test_a_set_is_given_out_again_only_once_nothing_refers_to_it():
    plan = plan_from_survey(parse_survey(SURVEY))
    tiling = Tiling.for_grid(plan.shape, 16_000)
    buffers = Buffers(plan, tiling, most=2)
    first = buffers.take()
    name = next(iter(first))
    assert first[name].size == int(np.prod(tiling.block))
    _, block = backends.compute_block(plan, tiling, 1, first)
    assert np.shares_memory(block[name], first[name])
    second = buffers.take()
    assert second is not first  # the block's views hold the first set
    _, other = backends.compute_block(plan, tiling, 2, second)
    held = block[name][0, 0]  # a view of a view: still the first set's memory
    del block
    assert buffers.take() is None  # both in use (at most 2): no third set
    del held
    assert buffers.take() is first
    del other
    assert buffers.take() is first  # not handed to anyone yet: still free


def test_a_set_given_to_a_queued_block_is_busy():
    plan = plan_from_survey(parse_survey(SURVEY))
    buffers = Buffers(plan, Tiling.for_grid(plan.shape, 16_000), most=2)
    first = buffers.take()
    assert buffers.take() is first  # nothing refers to its arrays...
    second = buffers.take(busy=[first])  # ...but a queued block will write them
    assert second is not first
    assert buffers.take(busy=[first, second]) is None


def test_blocks_are_written_behind_in_order_and_a_failed_write_stops_them():
    """engine.pipeline.written_behind: each block's write runs on a thread of its own (the
    blocks after it are taken meanwhile), receipts come out in block order, a failed write
    raises in its turn, at most AHEAD queued writes run after it, and no writer thread
    is left behind."""
    taken: list[int] = []
    wrote: list[tuple[int, str]] = []

    def blocks():
        for i in range(6):
            taken.append(i)
            yield i, {"v": np.full(2, i)}

    def write(i, arrays):
        wrote.append((i, threading.current_thread().name))
        if i == 3:
            raise OSError(28, "No space left on device")
        return f"receipt {int(arrays['v'][0])}"

    got = []
    with pytest.raises(OSError, match="No space"):
        for i, receipt in written_behind(blocks(), write):
            got.append((i, receipt))
    assert got == [(i, f"receipt {i}") for i in range(3)]
    order = [i for i, _ in wrote]  # in order; a write already queued may still run, no more
    assert order == list(range(len(order))) and 4 <= len(order) <= 4 + AHEAD
    assert all(name.startswith("conesurvey-chunks") for _, name in wrote)
    assert 3 + AHEAD in taken or len(taken) == 6  # blocks were taken while earlier ones wrote
    assert not [t for t in threading.enumerate() if t.name.startswith("conesurvey-chunks")]

"""The local backend computes one block ahead: block k + 1 runs on a thread of its own while
the run stores and writes block k, errors come out in block order, and a run that stops early
leaves no compute thread behind."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from engine import backends


def _fake(started: list[int], fail_at: int | None = None):
    def compute_block(plan, tiling, index):
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


def test_the_next_block_is_computed_while_the_caller_holds_this_one(monkeypatch):
    started: list[int] = []
    monkeypatch.setattr(backends, "compute_block", _fake(started))
    blocks = backends.LocalBackend().blocks(None, None, [4, 5, 6])
    assert next(blocks)[0] == 4
    assert _wait_for(lambda: started == [4, 5]), started  # 5 runs before 4 is handed back
    assert [i for i, _ in blocks] == [5, 6]
    assert not _compute_threads()


def test_an_error_comes_out_in_block_order_and_stops_the_compute(monkeypatch):
    started: list[int] = []
    monkeypatch.setattr(backends, "compute_block", _fake(started, fail_at=1))
    got = []
    with pytest.raises(ZeroDivisionError, match="block 1"):
        for i, _ in backends.LocalBackend().blocks(None, None, [0, 1, 2, 3]):
            got.append(i)
    assert got == [0]
    assert 3 not in started  # nothing is computed past the block that failed and the next
    assert not _compute_threads()


def test_a_run_that_stops_early_waits_for_the_block_in_the_compute(monkeypatch):
    started: list[int] = []
    monkeypatch.setattr(backends, "compute_block", _fake(started))
    blocks = backends.LocalBackend().blocks(None, None, [0, 1, 2])
    next(blocks)
    blocks.close()  # the runner leaving (an error, KeyboardInterrupt)
    assert not _compute_threads()
    assert 2 not in started

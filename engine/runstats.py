"""What a survey run reports when it ends (:class:`RunStats`) and the two ways it can fail
(:class:`RunError` before anything is written, :class:`RunFailed` after), for
:func:`engine.runner.run_survey` and the commands that call it."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .schema import DIMS

__all__ = ["AlreadyComplete", "RunError", "RunFailed", "RunStats"]


class RunError(Exception):
    """A run that cannot start or resume (the message says why); nothing was written.
    CLI exit status 2."""


class AlreadyComplete(RunError):
    """The output already holds this very survey, finished: nothing to compute."""


class RunFailed(Exception):
    """A run that stopped after it began to write (a full disk, a lost dask cluster, a block
    that changed on disk); the blocks stored so far are kept and the same run resumes.
    CLI exit status 1."""


@dataclass
class RunStats:
    """What a finished run reports: class counts, value ranges, timings, block counts.
    ``compute_seconds`` ends when the last block is stored (the output is written meanwhile);
    ``write_seconds`` is what writing the output took after that."""

    shape: tuple[int, ...]
    counts: np.ndarray
    ranges: dict[str, tuple[float, float, str]]
    dims: tuple[str, ...] = DIMS
    flags: dict[str, np.ndarray] = field(default_factory=dict)
    compute_seconds: float = 0.0
    write_seconds: float = 0.0
    compile_seconds: float = 0.0
    blocks_total: int = 0
    blocks_reused: int = 0
    path: Path | None = None

    @property
    def points(self) -> int:
        return math.prod(self.shape)

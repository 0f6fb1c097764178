"""The shape of a run plan as :mod:`engine.io` reads it: :class:`RunPlan` and :class:`OutputPlan`,
typing Protocols.

The storage layer sits below the API (docs/architecture.md): it imports nothing above it, and
the API's :class:`engine.plan.RunPlan` (a frozen dataclass built by the API and a survey file's
parser) reaches it as a value. Where a writer, the manifest or a reader needs the plan, it
names these protocols; ``tests/test_architecture.py`` checks that every attribute of a plan
that ``io/`` reads is declared here and that the API's plan satisfies them.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from ..horizon import Horizon
    from ..methods import Method
    from ..scene import Scene

__all__ = ["OutputPlan", "RunPlan"]


@runtime_checkable
class OutputPlan(Protocol):
    """Where and how a run's results are written (:class:`engine.plan.OutputPlan`)."""

    @property
    def path(self) -> Path | None: ...
    @property
    def format(self) -> Any: ...  # its row of engine.io.formats (which imports the writers)
    @property
    def compression(self) -> str: ...
    @property
    def complevel(self) -> int | None: ...
    @property
    def precision(self) -> str: ...
    @property
    def block_points(self) -> int: ...


@runtime_checkable
class RunPlan(Protocol):
    """A validated survey run (:class:`engine.plan.RunPlan`): what is computed, over which
    axes, written how, and its provenance."""

    @property
    def scene(self) -> Scene: ...
    @property
    def method(self) -> Method: ...
    @property
    def map_kind(self) -> str: ...
    @property
    def rtol(self) -> float: ...
    @property
    def circular_tol(self) -> float: ...
    @property
    def horizon(self) -> Horizon | None: ...
    @property
    def variables(self) -> dict[str, np.dtype]: ...
    @property
    def dims(self) -> tuple[str, ...]: ...
    @property
    def axes(self) -> tuple[np.ndarray, ...]: ...
    @property
    def energy_relative(self) -> bool: ...
    @property
    def output(self) -> OutputPlan: ...
    @property
    def title(self) -> str: ...
    @property
    def source_text(self) -> str: ...
    @property
    def shape(self) -> tuple[int, ...]: ...
    @property
    def size(self) -> int: ...

    def axis(self, name: str) -> np.ndarray: ...
    def attrs(self) -> dict[str, Any]: ...

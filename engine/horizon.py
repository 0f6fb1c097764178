"""The horizon of a fate map (:class:`Horizon`): how long each orbit is followed. Its own module
so that :mod:`engine.checks` (which decides when a horizon is required,
:func:`engine.checks.check_horizon`) and :mod:`engine.fates` (which runs fate maps) both
import it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Horizon"]


def _horizon_value(name: str, value: float | None) -> float:
    if value is None:
        return math.inf
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ValueError(f"{name} must be a number; got {value!r}")
    v = float(value)
    if not v > 0.0:
        raise ValueError(f"{name} must be > 0; got {value!r}")
    return v


@dataclass(frozen=True)
class Horizon:
    """How long a fate map follows each orbit: ``time`` [s] and/or ``revolutions`` about the axis
    (whichever comes first; None = no limit of that kind)."""

    time: float | None = None
    revolutions: float | None = None

    def __post_init__(self) -> None:
        _horizon_value("horizon_time", self.time)
        _horizon_value("horizon_revolutions", self.revolutions)

    @property
    def t_max(self) -> float:
        return _horizon_value("horizon_time", self.time)

    @property
    def theta_max(self) -> float:
        return 2.0 * math.pi * _horizon_value("horizon_revolutions", self.revolutions)

    @property
    def given(self) -> bool:
        return self.time is not None or self.revolutions is not None

    def as_attrs(self) -> dict[str, float | str]:
        """netCDF-safe attributes (no None)."""
        out: dict[str, float | str] = {}
        for name, v in (("horizon_time", self.time), ("horizon_revolutions", self.revolutions)):
            out[name] = "none" if v is None else float(v)
        return out

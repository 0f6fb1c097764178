"""The horizon of a fate map (:class:`Horizon`): how long each orbit is followed. Its own module
so that :mod:`engine.checks` (which decides when a horizon is required,
:func:`engine.checks.check_horizon`) and :mod:`engine.fates` (which runs fate maps) both
import it."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errortext import PlanError, real_value

__all__ = ["Horizon", "horizon_value"]


def horizon_value(name: str, value: object) -> float | None:
    """The one rule for a horizon value: None (no limit of that kind) or a finite number > 0."""
    if value is None:
        return None
    v = real_value(name, value)
    if not v > 0.0:
        raise PlanError(name, "must be > 0", value)
    if not math.isfinite(v):
        raise PlanError(name, "must be finite (leave it out for no limit)", value)
    return v


@dataclass(frozen=True)
class Horizon:
    """How long a fate map follows each orbit: ``time`` [s] and/or ``revolutions`` about the axis
    (whichever comes first; None = no limit of that kind)."""

    time: float | None = None
    revolutions: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "time", horizon_value("horizon_time", self.time))
        revolutions = horizon_value("horizon_revolutions", self.revolutions)
        object.__setattr__(self, "revolutions", revolutions)

    @property
    def t_max(self) -> float:
        return math.inf if self.time is None else self.time

    @property
    def theta_max(self) -> float:
        return math.inf if self.revolutions is None else 2.0 * math.pi * self.revolutions

    @property
    def given(self) -> bool:
        return self.time is not None or self.revolutions is not None

    def as_attrs(self) -> dict[str, float | str]:
        """netCDF-safe attributes (no None)."""
        out: dict[str, float | str] = {}
        for name, v in (("horizon_time", self.time), ("horizon_revolutions", self.revolutions)):
            out[name] = "none" if v is None else float(v)
        return out

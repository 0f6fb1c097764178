"""The axes of a survey file: each a list of values or a range (linear or log), checked.

:class:`AxisReader` reads ``[axes.NAME]`` tables into read-only float64 arrays, raising the
reader's error (``fail``) with the key path and the value for every problem (see
:mod:`engine.surveyfile` for the format).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .checks import axis_problem
from .errortext import TomlChecker, toml_repr, toml_type

__all__ = ["AxisReader", "MAX_AXIS_POINTS", "RELATIVE_TO", "SCALES", "frozen"]

#: Accepted values of ``axes.energy.relative_to``.
RELATIVE_TO = ("V_min",)
SCALES = ("linear", "log")
#: Largest ``num`` of a range axis (the axes are held in memory: 8 bytes a point).
MAX_AXIS_POINTS = 10**8
_RANGE_KEYS = ("start", "stop", "num", "scale")
_AXIS_KEYS = ("values", *_RANGE_KEYS)


class AxisReader(TomlChecker):
    """Reads and checks one axis table."""

    def axis(self, axes: dict, name: str) -> np.ndarray:
        path = f"axes.{name}"
        table = self.table(axes, name, "axes", required=True)
        assert table is not None
        allowed = _AXIS_KEYS + (("relative_to",) if name == "energy" else ())
        for key in table:
            if key == "relative_to" and name != "energy":
                raise self.fail(f"{path}.relative_to", "only allowed on axes.energy")
        self.check_keys(table, allowed, path)
        if "relative_to" in table:
            self.choice(table["relative_to"], f"{path}.relative_to", RELATIVE_TO)

        range_keys = [k for k in _RANGE_KEYS if k in table]
        if "values" in table:
            if range_keys:
                raise self.fail(
                    f"{path}.{range_keys[0]}",
                    "give either values = [...] or start/stop/num, not both",
                )
            values = self.values(table["values"], f"{path}.values")
            for i, x in enumerate(values.tolist()):
                self.check_value(name, x, f"{path}.values[{i}]", table["values"][i])
            return values
        if not range_keys:
            raise self.fail(path, "give either values = [...] or start, stop and num")
        for key in ("start", "stop", "num"):
            if key not in table:
                raise self.fail(f"{path}.{key}", "missing (a range needs start, stop and num)")
        start = self.number(table["start"], f"{path}.start")
        stop = self.number(table["stop"], f"{path}.stop")
        num = table["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise self.bad_value(f"{path}.num", num, "must be a positive integer")
        if num > MAX_AXIS_POINTS:
            raise self.bad_value(f"{path}.num", num, f"must be <= {MAX_AXIS_POINTS:.0e} per axis")
        scale = self.choice(table.get("scale", "linear"), f"{path}.scale", SCALES)
        for key, x in (("start", start), ("stop", stop)):
            self.check_value(name, x, f"{path}.{key}", table[key])
        if num == 1 and start != stop:
            raise self.bad_value(f"{path}.num", num, "must be > 1 when start != stop")
        if num > 1 and start == stop:
            raise self.bad_value(
                f"{path}.stop", table["stop"], "must differ from start when num > 1"
            )
        if scale == "log":
            for key, x in (("start", start), ("stop", stop)):
                if x <= 0.0:
                    raise self.bad_value(
                        f"{path}.{key}", table[key], 'must be > 0 with scale = "log"'
                    )
            with np.errstate(over="ignore"):  # 10**log10(stop) may round above DBL_MAX
                grid = np.geomspace(start, stop, num)
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                grid = np.linspace(start, stop, num)
            if not np.isfinite(grid).all():  # stop - start overflowed: halve, exactly
                grid = np.linspace(0.5 * start, 0.5 * stop, num) * 2.0
        grid[0], grid[-1] = start, stop  # exact end points (geomspace rounds them)
        steps = np.diff(grid)
        if not ((steps > 0.0).all() or (steps < 0.0).all()):
            raise self.bad_value(
                f"{path}.num",
                num,
                "is more points than there are distinct doubles between start and stop",
            )
        return frozen(grid)

    def values(self, value: Any, key: str) -> np.ndarray:
        if not isinstance(value, list):
            raise self.fail(
                key, f"must be an array of numbers, got {toml_type(value)} {toml_repr(value)}"
            )
        if not value:
            raise self.fail(key, "must not be empty")
        out = np.array(
            [self.number(v, f"{key}[{i}]") for i, v in enumerate(value)], dtype=np.float64
        )
        seen: dict[float, int] = {}
        for i, x in enumerate(out.tolist()):
            if x in seen:
                raise self.bad_value(f"{key}[{i}]", value[i], f"duplicates {key}[{seen[x]}]")
            seen[x] = i
        return frozen(out)

    def check_value(self, name: str, x: float, key: str, raw: Any) -> None:
        """The value ``x`` of the axis ``name``, by the API's check
        (:func:`engine.checks.axis_problem`)."""
        if problem := axis_problem(name, x):
            raise self.bad_value(key, raw, problem)


def frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    a.setflags(write=False)
    return a

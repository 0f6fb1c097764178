"""Checks of a parsed TOML document and the text of their error messages: values written back as
TOML, type names, key paths and did-you-mean suggestions (used by :mod:`engine.surveyfile`).

:class:`TomlChecker` holds the generic checks (a table, known keys, a number that is not a
boolean or a string, a string, a choice); a reader subclasses it and says, in :meth:`fail`,
which exception a problem becomes.

:class:`PlanError` is the error every input check raises (the API shows it as is, a survey
file under its own key path); :func:`real_value` is the one rule of what counts as a number."""

from __future__ import annotations

import datetime
import difflib
import math
import sys
from numbers import Real
from typing import Any

import numpy as np

__all__ = [
    "PlanError",
    "TomlChecker",
    "install_hint",
    "join_key",
    "real_value",
    "suggest",
    "toml_repr",
    "toml_type",
]


_NO_VALUE = object()


class PlanError(ValueError):
    """An input no run can take. ``field``: the input's name (an API keyword: ``rtol``,
    ``horizon_time``, ``block_points``, an axis name ...); ``problem``: what is wrong, without
    the field and the value (a survey file shows it under its own key path); ``value``: the
    value refused (absent where the problem is not one value's)."""

    def __init__(
        self, field: str, problem: str, value: Any = _NO_VALUE, *, whole: bool = False
    ) -> None:
        self.field = field
        self.problem = problem
        self.value = value
        got = "" if value is _NO_VALUE else f"; got {value!r}"
        # ``whole``: the problem names the field itself ("method 'exact' cannot honour ...")
        super().__init__(problem if whole else f"{field} {problem}{got}")

    @property
    def has_value(self) -> bool:
        return self.value is not _NO_VALUE


def real_value(name: str, value: Any) -> float:
    """``value`` as a float if it is a real number (not a boolean, not text); otherwise a
    :class:`PlanError` naming ``name``."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, Real):
        raise PlanError(name, "must be a number", value)
    try:
        return float(value)
    except OverflowError:  # an integer beyond the doubles: out of every range
        return math.inf if value > 0 else -math.inf


def install_hint(extra: str) -> str:
    """How to install an optional extra the way the README installs conesurvey: from the
    checkout, into the environment that runs this command (conesurvey is not on PyPI)."""
    return f"in the conesurvey checkout, run: {sys.executable} -m pip install '.[{extra}]'"


def toml_repr(value: Any, depth: int = 0) -> str:
    """A value as it would be written in TOML (for error messages)."""
    if depth > 8 and isinstance(value, list | dict):
        return "[...]" if isinstance(value, list) else "{...}"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(toml_repr(v, depth + 1) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_repr(v, depth + 1)}" for k, v in value.items()) + "}"
    if isinstance(value, datetime.date | datetime.time):  # datetime is a date
        return value.isoformat()
    return repr(value) if not isinstance(value, int | float) else str(value)


def toml_type(value: Any) -> str:
    """The TOML type name of a parsed value."""
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a float"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"  # dates and times


def suggest(key: str, candidates: tuple[str, ...]) -> str:
    """A did-you-mean hint for an unknown key (case-insensitive first, then difflib)."""
    for c in candidates:
        if c.lower() == key.lower():
            return f"; did you mean {c!r}?"
    lowered = {c.lower(): c for c in candidates}
    close = difflib.get_close_matches(key.lower(), list(lowered), n=1, cutoff=0.6)
    if close:
        return f"; did you mean {lowered[close[0]]!r}?"
    return f"; expected one of {', '.join(candidates)}"


def join_key(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


class TomlChecker:
    """Generic checks of values of a parsed TOML document; each problem is raised as
    ``self.fail(key path, problem)``."""

    def fail(self, key: str, problem: str) -> Exception:
        """The exception for a problem at ``key`` (subclasses say which)."""
        return ValueError(f"{key}: {problem}" if key else problem)

    def bad_value(self, key: str, value: Any, problem: str) -> Exception:
        return self.fail(key, f"{problem}, got {toml_repr(value)}")

    def table(self, parent: dict, key: str, path: str, *, required: bool) -> dict | None:
        if key not in parent:
            if required:
                raise self.fail(join_key(path, key), "missing (a table is required)")
            return None
        value = parent[key]
        if not isinstance(value, dict):
            raise self.fail(
                join_key(path, key), f"must be a table, got {toml_type(value)} {toml_repr(value)}"
            )
        return value

    def check_keys(self, table: dict, allowed: tuple[str, ...], path: str) -> None:
        for key in table:
            if key not in allowed:
                where = join_key(path, key)
                raise self.fail(where, f"unknown key{suggest(key, allowed)}")

    def number(self, value: Any, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(key, f"must be a number, got {toml_type(value)} {toml_repr(value)}")
        try:
            x = float(value)
        except OverflowError:  # a TOML integer beyond the range of a double
            raise self.bad_value(key, value, "must be finite (|x| < 1.8e308)") from None
        if not math.isfinite(x):
            raise self.bad_value(key, value, "must be finite")
        return x

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str):
            raise self.fail(key, f"must be a string, got {toml_type(value)} {toml_repr(value)}")
        return value

    def choice(self, value: Any, key: str, choices: tuple[str, ...]) -> str:
        s = self.string(value, key)
        if s not in choices:
            hint = suggest(s, choices)
            raise self.fail(key, f"unknown value {toml_repr(s)}{hint}")
        return s

"""Text for error messages about a parsed TOML document: values written back as TOML, type
names, key paths and did-you-mean suggestions (used by :mod:`engine.surveyfile`)."""

from __future__ import annotations

import datetime
import difflib
import math
from typing import Any

__all__ = ["toml_repr", "toml_type", "suggest", "join_key"]


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

"""What a map shows, checked before anything is drawn (no matplotlib here): the variable, the
two axes drawn, an optional facet axis, the values the other axes are fixed at, and the facts
read from the file's attributes (flag tables, labels) and coordinates (log spacing).

Used by :mod:`engine.plot` (``conesurvey plot``) and :mod:`engine.report` (docs/surveys.md, "Look at
the results").
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xarray as xr

__all__ = [
    "AXIS_PREFERENCE",
    "LookError",
    "MapSpec",
    "axis_label",
    "default_axes",
    "fixed_text",
    "flag_table",
    "is_log_spaced",
    "parse_at",
    "plan",
    "variable_label",
]

#: Axis preference when choosing default map axes among equally long ones (first = y).
AXIS_PREFERENCE = ("energy", "Lz", "h", "alpha")


class LookError(ValueError):
    """A map or report that cannot be made as asked; the message names the culprit
    (CLI exit status 2, nothing written)."""


@dataclass
class MapSpec:
    """A checked map request: ``variable`` over ``x`` (horizontal) and ``y``, one panel per
    value of ``facet`` (or one panel), every other axis fixed: ``fixed[axis] = (index, why)``."""

    variable: str
    x: str
    y: str
    facet: str | None = None
    fixed: dict[str, tuple[int, str]] = field(default_factory=dict)

    def selection(self) -> dict[str, int]:
        return {k: i for k, (i, _) in self.fixed.items()}


def parse_at(items: Sequence[str] | None) -> dict[str, float]:
    """``["alpha=0.5,Lz=1.0", "h=0"]`` -> {"alpha": 0.5, "Lz": 1.0, "h": 0.0}; LookError for a
    malformed item, naming it."""
    out: dict[str, float] = {}
    for item in items or ():
        for part in filter(None, (p.strip() for p in item.split(","))):
            name, sep, text = part.partition("=")
            name = name.strip()
            if not sep or not name:
                raise LookError(f"--at {part!r}: expected AXIS=VALUE, e.g. alpha=0.5")
            try:
                value = float(text)
            except ValueError:
                raise LookError(f"--at {name}={text.strip()!r}: not a number") from None
            if not math.isfinite(value):
                raise LookError(f"--at {name}={text.strip()}: must be finite")
            out[name] = value
    return out


def default_axes(sizes: Mapping[str, int], exclude: Sequence[str] = ()) -> list[str]:
    """Axes not in ``exclude``, most points first; equally long ones in AXIS_PREFERENCE order."""
    rank = {a: i for i, a in enumerate(AXIS_PREFERENCE)}
    names = [a for a in sizes if a not in exclude]
    return sorted(names, key=lambda a: (-sizes[a], rank.get(a, len(rank)), a))


def plan(
    ds: xr.Dataset,
    variable: str = "orbit_class",
    x: str | None = None,
    y: str | None = None,
    at: Mapping[str, float] | None = None,
    facet: str | None = None,
) -> MapSpec:
    """Check a map request against ``ds``; LookError names what does not exist or clashes.

    Axes not given default to the longest ones (y prefers energy); axes not drawn are fixed at
    the value nearest to ``at[axis]``, or at their middle value.
    """
    at = dict(at or {})
    if variable not in ds.data_vars:
        raise LookError(f"no variable {variable!r}; variables: {', '.join(map(str, ds.data_vars))}")
    dims = [str(d) for d in ds[variable].dims]
    for role, name in (("--x", x), ("--y", y), ("--facet", facet), *(("--at", a) for a in at)):
        if name is not None and name not in dims:
            raise LookError(f"{role}: no axis {name!r}; axes: {', '.join(dims)}")
    chosen = [a for a in (x, y, facet) if a is not None]
    if len(set(chosen)) < len(chosen):
        raise LookError(f"--x, --y and --facet must be different axes; got {', '.join(chosen)}")
    clash = sorted(set(at) & set(chosen))
    if clash:
        raise LookError(f"--at {clash[0]}: {clash[0]} is drawn, it cannot also be fixed")
    if len(dims) < 2:
        raise LookError(f"{variable} has {len(dims)} dimension(s); a map needs two")
    sizes = {d: int(ds.sizes[d]) for d in dims}
    free = default_axes(sizes, exclude=[*chosen, *at])
    if x is None or y is None:
        pair = [a for a in (x, y) if a is not None]
        pair += free[: 2 - len(pair)]
        if len(pair) < 2:
            raise LookError(
                f"no axis left to draw: {', '.join(chosen + list(at))} are taken by --x, --y, "
                "--facet or --at; fix fewer axes with --at"
            )
        if x is None and y is None:  # y takes the preferred of the two (energy over Lz)
            rank = {a: i for i, a in enumerate(AXIS_PREFERENCE)}
            pair.sort(key=lambda a: rank.get(a, len(rank)))
            y, x = pair
        elif x is None:
            x = pair[1]
        else:
            y = pair[1]
    spec = MapSpec(variable, str(x), str(y), facet)
    for d in dims:
        if d in (spec.x, spec.y, facet):
            continue
        values = np.asarray(ds[d].values, float)
        if d in at:
            _check_in_range(ds[d], d, at[d])
            i = int(np.argmin(np.abs(values - at[d])))
            spec.fixed[d] = (i, f"nearest to {at[d]:g}")
        else:
            spec.fixed[d] = (values.size // 2, "middle value")
    return spec


def _check_in_range(coord: xr.DataArray, name: str, value: float) -> None:
    """LookError for an ``--at`` value outside the axis' range (the nearest value would be a
    silent guess), naming the range and the unit; a hint for degrees given as radians."""
    values = np.asarray(coord.values, float)
    lo, hi = float(np.min(values)), float(np.max(values))
    slack = 1e-9 * max(abs(lo), abs(hi), 1e-300)
    if lo - slack <= value <= hi + slack:
        return
    units = str(coord.attrs.get("units", ""))
    unit = f" {units}" if units and units != "1" else ""
    text = f"--at {name}={value:g} lies outside the axis {name}: {_fmt(lo)} .. {_fmt(hi)}{unit}"
    if units == "radian" and lo <= math.radians(value) <= hi:
        text += f" (in radian: {value:g} degree is {math.radians(value):.4g} radian)"
    raise LookError(text)


def _fmt(value: float) -> str:
    return f"{value:.4g}"


def fixed_text(ds: xr.Dataset, spec: MapSpec) -> str:
    """``alpha = 0.5236 radian (nearest to 0.5), h = 0 m s-1 (middle value)``."""
    parts = []
    for d, (i, why) in spec.fixed.items():
        units = ds[d].attrs.get("units", "")
        unit = f" {units}" if units and units != "1" else ""
        parts.append(f"{d} = {_fmt(float(ds[d].values[i]))}{unit} ({why})")
    return ", ".join(parts)


def is_log_spaced(values: Any) -> bool:
    """True for >= 3 positive values with a constant ratio (not 1) between neighbours."""
    v = np.asarray(values, float).ravel()
    if v.size < 3 or not np.all(np.isfinite(v)) or np.any(v <= 0):
        return False
    ratio = v[1:] / v[:-1]
    return bool(abs(ratio[0] - 1) > 1e-9 and np.allclose(ratio, ratio[0], rtol=1e-6, atol=0))


def axis_label(coord: xr.DataArray, name: str) -> str:
    """``Lz [kg m2 s-1]``; a relative energy axis says what it is relative to."""
    units = coord.attrs.get("units")
    if name == "energy" and units == "1":
        return "energy offset (calE - V_min)/|V_min|"
    return f"{name} [{units}]" if units else name


def variable_label(attrs: Mapping[str, Any], name: str) -> str:
    """``long_name [units] (name)`` from a variable's attributes."""
    units = attrs.get("units")
    long_name = attrs.get("long_name", name)
    return f"{long_name}{f' [{units}]' if units else ''} ({name})"


def flag_table(attrs: Mapping[str, Any]) -> list[tuple[int, str]] | None:
    """(code, meaning) pairs from CF ``flag_values`` / ``flag_meanings``, or None."""
    if "flag_values" not in attrs or "flag_meanings" not in attrs:
        return None
    values = np.atleast_1d(np.asarray(attrs["flag_values"])).tolist()
    names = str(attrs["flag_meanings"]).split()
    if len(values) != len(names):
        raise LookError(f"{len(values)} flag_values but {len(names)} flag_meanings")
    return sorted((int(v), n) for v, n in zip(values, names, strict=True))

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

from .errortext import suggest

__all__ = [
    "AXIS_PREFERENCE",
    "MAX_CELLS",
    "MAX_PANELS",
    "LookError",
    "MapSpec",
    "axis_label",
    "default_axes",
    "default_variable",
    "facet_panels",
    "fixed_text",
    "flag_table",
    "is_log_spaced",
    "parse_at",
    "plan",
    "variable_label",
]

#: Axis preference when choosing default map axes among equally long ones (first = y).
AXIS_PREFERENCE = ("energy", "Lz", "h", "alpha")
#: The variable a map shows when none is named: the first of these the result holds (a fate
#: map's ``fate``: what happened on the scene; else the orbit class).
DEFAULT_VARIABLES = ("fate", "orbit_class")
#: Most cells one figure draws, over all its panels (a 2000 x 2000 map: about 0.4 GB and 12 s
#: to draw on one core); a larger request is refused before anything is read.
MAX_CELLS = 4_000_000
#: Most panels of a small-multiples grid (more values are thinned, and the ones left out named).
MAX_PANELS = 25


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
    contours: tuple[float, ...] = ()

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


def default_variable(ds: xr.Dataset) -> str:
    """The variable a map of ``ds`` shows when none is named: ``fate`` on a fate map, else
    ``orbit_class`` (:data:`DEFAULT_VARIABLES`)."""
    for name in DEFAULT_VARIABLES:
        if name in ds.data_vars:
            return name
    return str(next(iter(ds.data_vars), "orbit_class"))


def _unknown(what: str, name: str, known: Sequence[str]) -> str:
    """``no variable 'precesion_rate'; did you mean 'precession_rate'?`` (or the list)."""
    hint = suggest(name, tuple(known))
    if not hint.startswith("; did you mean"):
        hint = f"; {'variables' if what == 'variable' else 'axes'}: {', '.join(known)}"
    return f"no {what} {name!r}{hint}"


def plan(
    ds: xr.Dataset,
    variable: str | None = None,
    x: str | None = None,
    y: str | None = None,
    at: Mapping[str, float] | None = None,
    facet: str | None = None,
    contours: Sequence[float] = (),
    derived: Sequence[str] = (),
) -> MapSpec:
    """Check a map request against ``ds``; LookError names what does not exist or clashes
    (with a did-you-mean for a misspelt name; ``derived`` names the variables a caller can
    add, offered too).

    The variable defaults to :func:`default_variable`; axes not given default to the longest
    ones (y prefers energy); axes not drawn are fixed at the value nearest to ``at[axis]``, or
    at their middle value. ``contours``: values at which contour lines are drawn over a
    variable that is not a flag.
    """
    at = dict(at or {})
    variable = default_variable(ds) if variable is None else variable
    if variable not in ds.data_vars:
        known = [str(v) for v in ds.data_vars] + [d for d in derived if d not in ds.data_vars]
        raise LookError(_unknown("variable", variable, known))
    dims = [str(d) for d in ds[variable].dims]
    for role, name in (("--x", x), ("--y", y), ("--facet", facet), *(("--at", a) for a in at)):
        if name is not None and name not in dims:
            raise LookError(f"{role}: {_unknown('axis', name, dims)}")
    chosen = [a for a in (x, y, facet) if a is not None]
    if len(set(chosen)) < len(chosen):
        raise LookError(f"--x, --y and --facet must be different axes; got {', '.join(chosen)}")
    clash = sorted(set(at) & set(chosen))
    if clash:
        raise LookError(f"--at {clash[0]}: {clash[0]} is drawn, it cannot also be fixed")
    if len(dims) < 2:
        raise LookError(f"{variable} has {len(dims)} dimension(s); a map needs two")
    levels = tuple(float(c) for c in contours)
    if levels and flag_table(ds[variable].attrs) is not None:
        raise LookError(f"--contour: {variable} is a flag variable; contours need numbers")
    if any(not math.isfinite(c) for c in levels):
        raise LookError(f"--contour must be finite; got {', '.join(map(str, levels))}")
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
    spec = MapSpec(variable, str(x), str(y), facet, contours=levels)
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
    cells = int(ds.sizes[spec.x]) * int(ds.sizes[spec.y])
    panels = len(facet_panels(ds, spec)[0] or [0])
    if cells * panels > MAX_CELLS:
        what = f"{cells:,} cells" + (f" x {panels} panels" if panels > 1 else "")
        raise LookError(
            f"a map of {spec.x} ({ds.sizes[spec.x]:,} values) by {spec.y} "
            f"({ds.sizes[spec.y]:,}) is {what}; a figure draws at most {MAX_CELLS:,}: draw "
            "shorter axes (--x, --y) or fewer panels"
        )
    return spec


def facet_panels(ds: xr.Dataset, spec: MapSpec) -> tuple[list[int] | None, str]:
    """Indices of the facet axis drawn (None: one panel) and, where some are left out, a note
    naming them. Up to :data:`MAX_PANELS` values are all drawn; of more, the first and last,
    0 where the axis holds it and values evenly spaced between them."""
    if spec.facet is None:
        return None, ""
    values = np.asarray(ds[spec.facet].values, float)
    n = values.size
    if n <= MAX_PANELS:
        return list(range(n)), ""
    keep = set(np.round(np.linspace(0, n - 1, MAX_PANELS - 1)).astype(int).tolist())
    zero = np.flatnonzero(values == 0.0)
    if zero.size:
        keep.add(int(zero[0]))
    idx = sorted(keep)
    left = [_fmt(float(values[i])) for i in range(n) if i not in keep]
    shown = ", ".join(left[:12]) + (f" and {len(left) - 12} more" if len(left) > 12 else "")
    return idx, f"{len(idx)} of {n} values of {spec.facet}; left out: {shown}"


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

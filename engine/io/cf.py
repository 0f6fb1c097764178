"""CF-1.11 global attributes of a conesurvey output (every format): Conventions, title,
history (newest first), source, the scene's parameters, ``survey_definition`` = the TOML text
verbatim; and flag variables' ``flag_values`` of the variable's own type.

The scene's parameters (``scene_M``, ``scene_rim``, ...) and the horizon (``horizon_time``,
``horizon_revolutions``) have one type in every file (:func:`typed_parameters`): a number is a
float64, a flag (``scene_attitude``) an int64 0 or 1 (what a JSON integer of a Zarr store reads
back as), and a value that is not set (an infinite
cone's rim, no friction limit, no horizon time) is an absent attribute, never a string.
``parameter_units`` gives the unit of each, ``scene_M: kg, scene_g: m s-2, ...`` (a unit in
brackets on the field's line of :class:`engine.Scene`'s docstring, else 1).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

import numpy as np

from .._jit import threading_layer
from .._version import __version__
from ..scene import Scene

if TYPE_CHECKING:
    import xarray as xr

__all__ = [
    "CONVENTIONS",
    "UNITS_ATTR",
    "cf_attrs",
    "cf_dataset",
    "history_line",
    "parameter_units",
    "typed_flags",
    "typed_parameters",
]

CONVENTIONS = "CF-1.11"
#: The global attribute that names the unit of each scene and horizon attribute.
UNITS_ATTR = "parameter_units"
#: Units of the horizon's attributes.
HORIZON_UNITS = {"horizon_time": "s", "horizon_revolutions": "1"}


def parameter_units() -> dict[str, str]:
    """The unit of every scene and horizon attribute: ``{"scene_M": "kg", ...}``, read from
    the fields of :class:`engine.Scene` and the ``[unit]`` on each field's line of its
    docstring (no unit there: ``1``)."""
    doc: dict[str, str] = {}
    for line in (Scene.__doc__ or "").splitlines():
        m = re.match(r"\s*(\w+) : ([^\n]*)", line)
        if m:
            unit = re.search(r"\[([^\]]+)\]", m.group(2))
            doc[m.group(1)] = unit.group(1) if unit else "1"
    out = {
        f"scene_{f.name}": doc.get(f.name, "1")
        for f in dataclasses.fields(Scene)
        if not f.name.startswith("_")
    }
    return {**out, **HORIZON_UNITS}


def typed_parameters(attrs: Mapping[str, Any]) -> dict[str, Any]:
    """``attrs`` with the scene's and the horizon's attributes of one type each: a value not
    set (``None`` or the string ``"none"`` of older files) left out, a flag (a bool, or the
    scene's ``attitude``) an int64, any other number a float64; and :data:`UNITS_ATTR` naming
    the unit of each one present."""
    units = parameter_units()
    out: dict[str, Any] = {}
    for key, value in attrs.items():
        if key not in units:
            out[key] = value
            continue
        if value is None or (isinstance(value, str) and value.strip().lower() == "none"):
            continue  # not set: an absent attribute (CF), never a string
        if isinstance(value, bool | np.bool_) or key == "scene_attitude":
            out[key] = np.int64(bool(value))
        else:
            out[key] = np.float64(value)
    present = [k for k in units if k in out]
    if present:
        out[UNITS_ATTR] = ", ".join(f"{k}: {units[k]}" for k in present)
    return out


def history_line(command: str, *, now: datetime | None = None) -> str:
    """One CF history entry: ISO-8601 UTC time, the command and numba's threading layer."""
    stamp = (now or datetime.now(UTC)).astimezone(UTC)
    return f"{stamp:%Y-%m-%dT%H:%M:%SZ} {command} (numba threading layer: {threading_layer()})"


def cf_attrs(
    attrs: Mapping[str, Any],
    *,
    title: str,
    survey_definition: str,
    command: str = "conesurvey",
    scene: Scene | None = None,
) -> dict[str, Any]:
    """The global attributes ``attrs`` with the CF ones a conesurvey output carries: the new
    history entry first (newest first, CF), the scene's parameters, the definition last."""
    rest = dict(attrs)
    if scene is not None:
        rest.update(scene.as_attrs())
    old_history = rest.pop("history", "")
    entry = history_line(command)
    for key in ("Conventions", "title", "source", "survey_definition"):
        rest.pop(key, None)
    rest.pop(UNITS_ATTR, None)  # made again from the attributes present
    return {
        "Conventions": CONVENTIONS,
        "title": title,
        "history": f"{entry}\n{old_history}" if old_history else entry,
        "source": f"conesurvey {__version__}",
        **typed_parameters(rest),
        "survey_definition": survey_definition,
    }


def typed_flags(attrs: Mapping[str, Any], dtype: np.dtype) -> dict[str, Any]:
    """``attrs`` with ``flag_values`` of the variable's own type (CF requires it)."""
    out = dict(attrs)
    if "flag_values" in out:
        out["flag_values"] = np.asarray(out["flag_values"], dtype=dtype)
    return out


def cf_dataset(
    ds: xr.Dataset,
    *,
    title: str,
    survey_definition: str,
    command: str = "conesurvey",
    scene: Scene | None = None,
) -> xr.Dataset:
    """A shallow copy of ``ds`` with the CF global attributes (:func:`cf_attrs`); the
    ``flag_values`` of flag variables (``orbit_class``, ``status``) get the variable's type."""
    out = ds.copy(deep=False)
    out.attrs = cf_attrs(
        ds.attrs, title=title, survey_definition=survey_definition, command=command, scene=scene
    )
    for var in out.data_vars.values():
        var.attrs = typed_flags(var.attrs, var.dtype)
    return out

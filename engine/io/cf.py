"""CF-1.11 global attributes of a conesurvey output (every format): Conventions, title,
history (newest first), source, the scene's parameters, ``survey_definition`` = the TOML text
verbatim; and flag variables' ``flag_values`` of the variable's own type."""

from __future__ import annotations

from collections.abc import Mapping
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

import numpy as np

from .._jit import threading_layer
from .._version import __version__

if TYPE_CHECKING:
    import xarray as xr

    from ..scene import Scene

__all__ = ["CONVENTIONS", "cf_attrs", "cf_dataset", "history_line", "typed_flags"]

CONVENTIONS = "CF-1.11"


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
    return {
        "Conventions": CONVENTIONS,
        "title": title,
        "history": f"{entry}\n{old_history}" if old_history else entry,
        "source": f"conesurvey {__version__}",
        **rest,
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

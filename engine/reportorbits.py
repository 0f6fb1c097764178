"""The report's sample orbits: for each flag of a result's ``fate`` (a fate map) or
``orbit_class``, the first computed grid point that has it, drawn as ``conesurvey orbit`` draws
it (:mod:`engine.orbitplot`; from above and r(t)); a flag without an orbit (forbidden,
no_orbit, ...) or one that cannot be drawn is named with the reason."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .io.results import Result
from .mapspec import LookError, default_variable, flag_table
from .orbitplot import orbit_thumbnail
from .orbitview import orbit_of_result

__all__ = ["NO_ORBIT", "Sample", "sample_orbits"]

#: Flags whose points have no orbit to draw.
NO_ORBIT = ("forbidden", "out_of_range", "off_cone", "no_orbit", "failed")
#: Samples of a report's orbit (a small picture).
SAMPLES = 400


@dataclass
class Sample:
    """The sample of one flag: the grid point (None: none computed has it), and the figure
    drawn (None: why not, in ``reason``)."""

    variable: str
    flag: str
    point: dict[str, float] | None
    figure: Any = None
    reason: str = ""


def _first_points(result: Result, variable: str) -> dict[int, dict[str, float]]:
    """Code -> the first computed grid point (axis -> value) with that code, tile by tile."""
    ds = result.ds
    dims = [str(d) for d in ds[variable].dims]
    found: dict[int, dict[str, float]] = {}
    for tile in result.tiles():
        sub = np.asarray(ds[variable].isel({d: tile[d] for d in dims if d in tile}).values)
        for code in np.unique(sub[np.isfinite(sub)] if sub.dtype.kind == "f" else sub):
            if int(code) in found:
                continue
            idx = np.unravel_index(int(np.flatnonzero(sub == code)[0]), sub.shape)
            found[int(code)] = {
                d: float(ds[d].values[tile[d].start + int(i)])
                for d, i in zip(dims, idx, strict=True)
            }
    return found


def sample_orbits(result: Result) -> list[Sample]:
    """One :class:`Sample` per flag of the result's ``fate`` or ``orbit_class``."""
    ds = result.ds
    variable = default_variable(ds)
    table = flag_table(ds[variable].attrs) or []
    found = _first_points(result, variable)
    out = []
    for code, name in table:
        point = found.get(code)
        sample = Sample(variable, name, point)
        if point is None:
            continue
        if name in NO_ORBIT:
            sample.reason = "no orbit to draw"
        else:
            try:
                o, _ = orbit_of_result(ds, point, samples=SAMPLES)
            except (LookError, ValueError) as exc:
                sample.reason = str(exc)
            else:
                where = ", ".join(f"{k} = {v:.4g}" for k, v in point.items())
                sample.figure = orbit_thumbnail(o, f"{variable} {name}: {where}")
        out.append(sample)
    return out

"""The ``[surface]`` table of a survey file: a survey over launches on a surface of revolution.

::

    [surface]
    kind = "funnel"          # cone, bowl, paraboloid, funnel, power_law, cylinder, profile
    scale = 0.1              # the kind's parameters (engine.surfaces), each > 0
    hole = 0.02
    # profile = "meridian.csv"   # kind = "profile": a text file of two columns, rho and z [m],
    #                            # beside the survey file (or an absolute path)

    [axes.rho0]              # the centre's distance from the axis [m] (the cylinder: axes.z0)
    values = [0.05, 0.1, 0.2]
    [axes.v0]                # speed along the parallel [m s-1]
    start = 0.2
    stop = 1.0
    num = 9
    [axes.w0]                # spin a omega . nu [m s-1]
    values = [0.0]
    [axes.scale]             # optional: sweep a parameter of the surface (then not in [surface])
    values = [0.05, 0.1]

The scene's rim (``scene.rim``) is what the surface's row says it measures
(``engine.surfaces``: the edge's distance from the axis; the cylinder's height).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .surfaces import SURFACES, Profile, Surface

__all__ = ["read_surface", "SURFACE_KEYS"]

#: Keys of a ``[surface]`` table besides the kind's parameters.
SURFACE_KEYS = ("kind", "profile")


def read_surface(reader: Any, table: dict, axes: dict, origin: str) -> tuple[Surface, tuple]:
    """The surface of a ``[surface]`` table and the parameters the survey's axes sweep; every
    problem the reader's error at its key path (``reader``: the survey file's reader)."""
    kind = reader.choice(table.get("kind"), "surface.kind", tuple(SURFACES))
    cls = SURFACES[kind]
    params = tuple(cls.parameters)
    reader.check_keys(table, (*SURFACE_KEYS, *params), "surface")
    swept = tuple(p for p in params if p in axes)
    values: dict[str, Any] = {}
    for name in params:
        if name in table and name in swept:
            raise reader.fail(f"surface.{name}", f"is swept by axes.{name}: give it there only")
        if name in swept:
            values[name] = float(reader.axis(axes, name)[0])  # the survey's first surface
        elif name in table:
            values[name] = reader.number(table[name], f"surface.{name}")
        else:
            raise reader.fail(
                f"surface.{name}", f"missing: the {kind}'s {name} [{cls.parameters[name]}]"
            )
    if cls is Profile:
        if "profile" not in table:
            raise reader.fail("surface.profile", "missing: a text file of rho and z [m] columns")
        path = Path(reader.string(table["profile"], "surface.profile"))
        if not path.is_absolute() and origin not in ("", "<string>"):
            path = Path(origin).parent / path
        try:
            data = np.loadtxt(path, ndmin=2, delimiter="," if path.suffix == ".csv" else None)
        except (OSError, ValueError) as exc:
            raise reader.fail("surface.profile", f"cannot read {path}: {exc}") from None
        if data.shape[1] != 2:
            raise reader.fail("surface.profile", f"{path} must hold two columns (rho, z)")
        values = {"rho": tuple(data[:, 0]), "z": tuple(data[:, 1])}
    elif "profile" in table:
        raise reader.fail("surface.profile", f'only for kind = "profile", not {kind!r}')
    try:
        return cls(**values), swept
    except ValueError as exc:
        raise reader.fail("surface", str(exc)) from None

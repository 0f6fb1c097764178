"""Evaluating maps on a surface of revolution: one block of a survey over launches.

A surface survey's axes (:func:`engine.schema.surface_dims`) are the surface's parameters that
the survey sweeps, then the launch: its position (``rho0``, the cylinder's ``z0``), ``v0`` and
``w0``. Every map holds the exact orbit (Routh's reduction, :func:`engine.routh.exact_map`: the
class, the turning points, the period, the apsidal angle, the precession rate and Routh's two
integrals); an integrator adds one integrated radial period of each bounded orbit (which
replaces the period, apsidal angle and precession rate; an orbit that lifts off is integrated
too, from its launch to where it does: status ``lifted_off``; a launch with no speed along the
parallel is not integrated, as on any map) or follows every launch to its fate
(:mod:`engine.surface_maps`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .kernels.protocol import NOT_BOUNDED
from .kernels.routh import BOUNDED, LIFTS
from .routh import exact_map
from .schema import FATE_KINDS, INTEGRATED, REPLACED_BY_INTEGRATION
from .surface_maps import surface_fates, surface_params, surface_period, surface_points

if TYPE_CHECKING:
    from .plan import RunPlan
    from .surfaces import Surface

__all__ = ["surface_block", "launch_columns"]

#: The exact map's classes of an orbit that an integrator follows for one period.
_INTEGRATED = (BOUNDED, LIFTS)


def launch_columns(surface: Surface, dims: tuple[str, ...], sub: list[np.ndarray]) -> np.ndarray:
    """The points array of the grid of the axes ``sub`` (named ``dims``: the surface's swept
    parameters, the position, v0, w0), in the grid's C order."""
    grids = dict(zip(dims, (g.reshape(-1) for g in np.meshgrid(*sub, indexing="ij")),
                     strict=True))  # fmt: skip
    n = math.prod(x.size for x in sub)
    names = list(surface.parameters)
    fixed = surface.shape
    shape = [grids.get(names[j], np.full(n, fixed[j])) if j < len(names) else np.full(n, fixed[j])
             for j in range(2)]  # fmt: skip
    return surface_points(shape[0], shape[1], grids[surface.position], grids["v0"], grids["w0"])


def surface_block(plan: RunPlan, sub: list[np.ndarray]) -> dict[str, np.ndarray]:
    """The plan's variables on the grid of the axes ``sub`` (flat arrays in the grid's C
    order)."""
    surface = plan.surface
    assert surface is not None
    X = launch_columns(surface, plan.dims, sub)
    params = surface_params(plan.scene, surface)
    res = exact_map(params, X)
    kind = plan.map_kind
    if kind == "surface one period":
        bounded = np.isin(res["orbit_class"], _INTEGRATED)
        run = surface_period(np.ascontiguousarray(X[:, bounded]), params, plan.scene,
                             plan.method, plan.rtol, 1_000_000)  # fmt: skip
        for name in REPLACED_BY_INTEGRATION:
            col = np.full(X.shape[1], math.nan)
            col[bounded] = run[name]
            res[name] = col
        for name in INTEGRATED:
            col = np.zeros(X.shape[1], run[name].dtype)
            if name == "status":
                col[:] = NOT_BOUNDED
            elif run[name].dtype.kind == "f":
                col[:] = math.nan
            col[bounded] = run[name]
            res[name] = col
    elif kind in FATE_KINDS:
        horizon = plan.horizon
        assert horizon is not None
        res.update(surface_fates(X, params, plan.scene, plan.method, plan.rtol, horizon.t_max,
                                 horizon.theta_max))  # fmt: skip
    return {n: res[n] for n in plan.variables}

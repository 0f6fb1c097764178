"""Evaluating maps: the kernels over flat arrays of points, and over one block of a survey grid.

:func:`evaluate_flat` is what :func:`engine.evaluate` and every survey block call: the closed
form for every point, then (for an integrator method) one integrated radial period for the
points that have one. :func:`evaluate_block` evaluates one hyperslab of a 4-D survey grid, so
the in-memory survey, local streamed runs and dask workers compute the very same blocks.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .fates import Horizon, fates, require_horizon
from .integrated import evaluate_integrated
from .kernels.batch import (
    BATCH_ROWS,
    empty_outputs,
    minimum_energy_batch,
    orbit_batch,
    orbit_grid,
)
from .kernels.geometry import BOUNDED, CIRCULAR_TOL
from .methods import DEFAULT_RTOL
from .scene import Scene
from .schema import (
    DIMS,
    INTEGRATED,
    REPLACED_BY_INTEGRATION,
    RESULTS,
    map_kind,
    result_variables,
)

__all__ = ["evaluate_flat", "evaluate_block", "minimum_energy_flat"]


def evaluate_flat(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    scene: Scene,
    method: str = "exact",
    *,
    circular_tol: float = CIRCULAR_TOL,
    rtol: float = DEFAULT_RTOL,
    horizon: Horizon | None = None,
) -> dict[str, np.ndarray]:
    """Kernel call on equal-length 1-D float64 arrays (validated by the caller).

    Returns a dict of 1-D arrays: the variables of :func:`engine.schema.result_variables` but
    ``energy_absolute``. Every map holds the closed form; what else depends on the kind of map
    (:func:`engine.schema.map_kind`): where rolling ends on a cone with a rim or a friction
    limit (closed form), one integrated radial period, or each orbit's fate (integrated up to
    ``horizon``; then the closed form describes the launch orbit on the ideal cone).
    """
    a = np.ascontiguousarray(alpha, np.float64)
    e = np.ascontiguousarray(energy, np.float64)
    hh = np.ascontiguousarray(h, np.float64)
    lz = np.ascontiguousarray(Lz, np.float64)
    kind = map_kind(method, scene)
    wanted = result_variables(method, scene)
    cls, f = empty_outputs(a.shape[0])
    rim, mu = scene.rim_or_inf, scene.mu_or_inf
    if kind == "fate":  # the launch orbit on the ideal cone; the integration follows the scene
        rim, mu = math.inf, math.inf
    orbit_batch(a, e, hh, lz, scene.M, scene.g, scene.k, scene.a, rim, mu, circular_tol, cls, f)
    out: dict[str, np.ndarray] = {"orbit_class": cls}
    for i, name in enumerate(BATCH_ROWS):
        if name in wanted:
            out[name] = f[i]
    if kind == "one period":
        out.update(_integrate_bounded(a, e, hh, lz, scene, method, rtol, cls))
    elif kind == "fate":
        out.update(fates(a, e, hh, lz, f[0], scene, method, rtol, require_horizon(horizon),
                         classes=cls))  # fmt: skip
    return out


def _integrate_bounded(a, e, hh, lz, scene, method, rtol, cls) -> dict[str, np.ndarray]:
    """The one-period variables for every point: bounded points integrated, the others NaN,
    no steps, status 0."""
    n = a.shape[0]
    sel = np.flatnonzero(cls == BOUNDED)
    res = evaluate_integrated(a[sel], e[sel], hh[sel], lz[sel], scene, method, rtol)
    upd: dict[str, np.ndarray] = {}
    for name in (*REPLACED_BY_INTEGRATION, *INTEGRATED):
        dtype = np.dtype(RESULTS[name].dtype)
        col = np.full(n, np.nan if dtype.kind == "f" else 0, dtype)
        col[sel] = res[name]
        upd[name] = col
    return upd


def minimum_energy_flat(alpha: np.ndarray, h: np.ndarray, Lz: np.ndarray, scene: Scene):
    """V_min [J] at each (alpha, h, Lz) of 1-D float64 arrays; NaN where V has no minimum."""
    out = np.empty(alpha.size)
    minimum_energy_batch(alpha, h, Lz, scene.M, scene.g, scene.k, out)
    return out


def evaluate_block(spec: dict[str, Any], slices: tuple[slice, ...]) -> dict[str, np.ndarray]:
    """Results on one hyperslab of the grid, each array shaped like the slab.

    ``spec``: axes ``alpha``, ``energy``, ``h``, ``Lz`` (1-D float64), ``scene`` (Scene),
    ``method``, ``energy_relative``, ``circular_tol``, ``rtol``, ``horizon`` (fate maps).
    With a relative energy axis the absolute energy (``energy_absolute``) is V_min + offset
    |V_min| from the slab's own V_min; where V has no minimum it is NaN and the point is
    classed forbidden. A closed-form map runs the grid kernel, which computes what does not
    depend on the energy once per (alpha, h, L_z); its numbers equal :func:`evaluate_flat`'s
    on the same points bit for bit.
    """
    sub = [
        np.ascontiguousarray(np.asarray(spec[d])[s], np.float64)
        for d, s in zip(DIMS, slices, strict=False)
    ]
    shape = tuple(x.size for x in sub)
    scene = spec["scene"]
    if map_kind(spec["method"], scene) == "closed form":
        res = _closed_form_grid(sub, scene, spec)
    else:
        res = _flat_block(sub, scene, spec)
    return {name: col.reshape(shape) for name, col in res.items()}


def _closed_form_grid(sub: list[np.ndarray], scene: Scene, spec: dict[str, Any]):
    """The closed form on the grid of the axes ``sub`` (flat arrays in the grid's C order)."""
    n = math.prod(x.size for x in sub)
    relative = bool(spec["energy_relative"])
    cls, f = empty_outputs(n)
    e_abs = np.empty(n)
    orbit_grid(*sub, relative, scene.M, scene.g, scene.k, scene.a, scene.rim_or_inf,
               scene.mu_or_inf, spec["circular_tol"], cls, f, e_abs)  # fmt: skip
    wanted = result_variables(spec["method"], scene)
    out: dict[str, np.ndarray] = {"orbit_class": cls}
    for i, name in enumerate(BATCH_ROWS):
        if name in wanted:
            out[name] = f[i]
    if relative:
        out["energy_absolute"] = e_abs
    return out


def _flat_block(sub: list[np.ndarray], scene: Scene, spec: dict[str, Any]):
    """Any map on the grid of the axes ``sub``, through :func:`evaluate_flat` on its points."""
    A, E, H, L = (x.reshape(-1) for x in np.meshgrid(*sub, indexing="ij"))
    e_abs = None
    if spec["energy_relative"]:
        vmin = minimum_energy_flat(A, H, L, scene)
        e_abs = vmin + E * np.abs(vmin)
        E = e_abs
    res = evaluate_flat(
        A,
        E,
        H,
        L,
        scene,
        spec["method"],
        circular_tol=spec["circular_tol"],
        rtol=spec["rtol"],
        horizon=spec.get("horizon"),
    )
    if e_abs is not None:
        undefined = np.isnan(e_abs)
        if undefined.any():
            res["orbit_class"][undefined] = 0
            for name, col in res.items():
                if name != "r_circ" and col.dtype.kind == "f":
                    col[undefined] = np.nan
            if "fate" in res:
                res["fate"][undefined] = 0  # no orbit
        res["energy_absolute"] = e_abs
    return res

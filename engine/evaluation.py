"""Evaluating maps: the kernels over flat arrays of points, and over one block of a survey grid.

:func:`evaluate_flat` is what :func:`engine.evaluate` and every survey block call: the closed
form for every point, then (for an integrator method) one integrated radial period for the
points that have one. :func:`evaluate_block` evaluates one hyperslab of a 4-D survey grid, so
the in-memory survey, local streamed runs and dask workers compute the very same blocks.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .integrated import evaluate_integrated
from .kernels.geometry import (
    BOUNDED,
    CIRCULAR_TOL,
    SPILLS,
    empty_outputs,
    minimum_energy_batch,
    orbit_batch,
)
from .methods import DEFAULT_RTOL, get_method
from .scene import Scene
from .schema import CLOSED_FORM, DIMS, REPLACED_BY_INTEGRATION, result_variables

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
) -> dict[str, np.ndarray]:
    """Kernel call on equal-length 1-D float64 arrays (validated by the caller).

    Returns a dict of 1-D arrays, the variables of :func:`engine.schema.result_variables` but
    ``energy_absolute``: ``orbit_class`` (int8) and the closed form's floats; an integrator
    method adds its own and takes period, apsidal angle and precession rate from the
    integration (bounded points only).
    """
    a = np.ascontiguousarray(alpha, np.float64)
    e = np.ascontiguousarray(energy, np.float64)
    hh = np.ascontiguousarray(h, np.float64)
    lz = np.ascontiguousarray(Lz, np.float64)
    cls, f = empty_outputs(a.shape[0])
    orbit_batch(a, e, hh, lz, scene.M, scene.g, scene.k, scene.rim_or_inf, circular_tol, cls, f)
    out: dict[str, np.ndarray] = {"orbit_class": cls}
    for i, name in enumerate(CLOSED_FORM[1:]):
        out[name] = f[i]
    if get_method(method).integrates:
        out.update(_integrate_bounded(a, e, hh, lz, scene, method, rtol, cls))
    return out


def _integrate_bounded(a, e, hh, lz, scene, method, rtol, cls) -> dict[str, np.ndarray]:
    """The integrator's variables for every point: bounded (and spilling) points integrated,
    the others NaN, no steps, status 0."""
    n = a.shape[0]
    sel = np.flatnonzero((cls == BOUNDED) | (cls == SPILLS))
    res = evaluate_integrated(a[sel], e[sel], hh[sel], lz[sel], scene, method, rtol)
    upd: dict[str, np.ndarray] = {}
    for name, dtype in result_variables(method, scene).items():
        if name not in res:
            continue
        fill = np.nan if dtype.kind == "f" else 0
        col = np.full(n, fill, dtype)
        col[sel] = res[name]
        upd[name] = col
    assert set(REPLACED_BY_INTEGRATION) <= set(upd)
    return upd


def minimum_energy_flat(alpha: np.ndarray, h: np.ndarray, Lz: np.ndarray, scene: Scene):
    """V_min [J] at each (alpha, h, Lz) of 1-D float64 arrays; NaN where V has no minimum."""
    out = np.empty(alpha.size)
    minimum_energy_batch(alpha, h, Lz, scene.M, scene.g, scene.k, out)
    return out


def evaluate_block(spec: dict[str, Any], slices: tuple[slice, ...]) -> dict[str, np.ndarray]:
    """Results on one hyperslab of the grid, each array shaped like the slab.

    ``spec``: axes ``alpha``, ``energy``, ``h``, ``Lz`` (1-D float64), ``scene`` (Scene),
    ``method``, ``energy_relative``, ``circular_tol``, ``rtol``. With a relative energy axis the
    absolute energy (``energy_absolute``) is V_min + offset |V_min| from the slab's own V_min;
    where V has no minimum it is NaN and the point is classed forbidden.
    """
    sub = [np.asarray(spec[d])[s] for d, s in zip(DIMS, slices, strict=False)]
    shape = tuple(x.size for x in sub)
    A, E, H, L = (x.reshape(-1) for x in np.meshgrid(*sub, indexing="ij"))
    scene = spec["scene"]
    e_abs = None
    if spec["energy_relative"]:
        vmin = minimum_energy_flat(A, H, L, scene)
        e_abs = vmin + E * np.abs(vmin)
        E = e_abs
    res = evaluate_flat(
        A, E, H, L, scene, spec["method"], circular_tol=spec["circular_tol"], rtol=spec["rtol"]
    )
    if e_abs is not None:
        undefined = np.isnan(e_abs)
        if undefined.any():
            res["orbit_class"][undefined] = 0
            for name in CLOSED_FORM[1:]:
                if name != "r_circ":
                    res[name][undefined] = np.nan
        res["energy_absolute"] = e_abs
    return {name: col.reshape(shape) for name, col in res.items()}

"""Integrated maps on any surface of revolution: the model interface's second model
(``engine.kernels.surface``) through the same kernels as the cone's integrated maps.

A point is a launch on a surface (:mod:`engine.surfaces`): the surface's two shape parameters,
the launch position (rho0, or the cylinder's z0), v0, w0 and u0. :func:`surface_period`
integrates one radial period from each launch (a turning point: u0 = 0), :func:`surface_fates`
follows each launch to its fate; both take the parameter array of :func:`surface_params` and
the points array of :func:`surface_points`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._jit import call_specialized
from .kernels.effects import REVOLUTIONS
from .kernels.fate import FATE_ROWS
from .kernels.fate import fate_points as _fate_points_kernel
from .kernels.lanes import integrate_points_lanes as _lanes_kernel
from .kernels.lanes_fate import fate_points_lanes as _fate_lanes_kernel
from .kernels.layouts import P_THETA_MAX, SLOTS
from .kernels.meridian import P_KIND
from .kernels.model import SURFACE, make_params, scene_key
from .kernels.orbit import PERIOD_ROWS
from .kernels.orbit import integrate_points as _integrate_points_kernel
from .kernels.protocol import LITERAL, UNSUPPORTED
from .methods import Method
from .scene import Scene
from .surfaces import Surface

__all__ = ["surface_params", "surface_points", "surface_period", "surface_fates"]


def surface_params(scene: Scene, surface: Surface) -> np.ndarray:
    """The kernels' parameter array of ``scene`` on ``surface`` (its shape set per point by the
    kernels from the points array; a profile's coefficients here)."""
    slots, values = [], []
    for name, value in scene.effect_slots().items():
        slots.append(SLOTS[name])
        values.append(value)
    p = make_params(scene.M, scene.g, scene.k, scene.a, np.array(slots, np.int64),
                    np.array(values, np.float64))  # fmt: skip
    p[P_KIND] = surface.code
    for index, value in surface.slots().items():
        p[index] = value
    return p


def surface_points(
    shape1: np.ndarray,
    shape2: np.ndarray,
    position: np.ndarray,
    v0: np.ndarray,
    w0: np.ndarray,
    u0: np.ndarray | None = None,
) -> np.ndarray:
    """The points array (rows: shape1, shape2, the launch position, v0, w0, u0; one column per
    launch), from 1-D arrays of one length (``u0`` None: 0)."""
    n = np.asarray(position).shape[0]
    u = np.zeros(n) if u0 is None else np.asarray(u0, np.float64)
    rows = [np.broadcast_to(np.asarray(r, np.float64), (n,)) for r in (shape1, shape2)]
    rows += [np.asarray(r, np.float64) for r in (position, v0, w0)] + [u]
    return np.ascontiguousarray(np.stack(rows))


def surface_period(
    X: np.ndarray,
    params: np.ndarray,
    scene: Scene,
    method: Method,
    rtol: float,
    max_steps: int,
    model: int = SURFACE,
) -> dict[str, np.ndarray]:
    """One radial period of each launch of the points array X (a turning point), by the
    integrator ``method`` (checked already): the rows of ``engine.kernels.orbit.PERIOD_ROWS``,
    ``n_steps`` and ``status``. ``model``: the model's id (``engine.kernels.model.MODELS``;
    any model whose points are launches)."""
    n = X.shape[1]
    out_f = np.empty((len(PERIOD_ROWS), n))
    out_n = np.empty(n, np.int64)
    out_status = np.empty(n, np.int8)
    key = scene_key(model, scene.effects_mask)
    if method.family != "runge-kutta":
        out_f[:] = math.nan
        out_n[:] = 0
        out_status[:] = UNSUPPORTED
    elif n:
        args = (X, params, method.kernel_id, key, rtol, max_steps, numba.get_num_threads(), out_f,
                out_n, out_status)  # fmt: skip
        call_specialized(_lanes_kernel, args, LITERAL)
    res = {name: out_f[i] for i, name in enumerate(PERIOD_ROWS)}
    res["n_steps"] = out_n
    res["status"] = out_status
    return res


def surface_period_scalar(
    X: np.ndarray, params: np.ndarray, scene: Scene, method: Method, rtol: float, max_steps: int
) -> dict[str, np.ndarray]:
    """:func:`surface_period` one orbit per thread (the lanes' reference, for the tests)."""
    n = X.shape[1]
    out_f = np.empty((len(PERIOD_ROWS), n))
    out_n = np.empty(n, np.int64)
    out_status = np.empty(n, np.int8)
    key = scene_key(SURFACE, scene.effects_mask)
    args = (X, params, method.kernel_id, key, rtol, max_steps, out_f, out_n, out_status)
    call_specialized(_integrate_points_kernel, args, LITERAL)
    res = {name: out_f[i] for i, name in enumerate(PERIOD_ROWS)}
    res["n_steps"] = out_n
    res["status"] = out_status
    return res


def surface_fates(
    X: np.ndarray,
    params: np.ndarray,
    scene: Scene,
    method: Method,
    rtol: float,
    t_horizon: float,
    theta_max: float = math.inf,
    max_steps: int = 1_000_000,
    *,
    lanes: bool = True,
    model: int = SURFACE,
) -> dict[str, np.ndarray]:
    """Each launch of the points array X followed to its fate by the integrator ``method``
    (checked already): ``fate``, the rows of ``engine.kernels.fate.FATE_ROWS`` and
    ``n_steps``."""
    n = X.shape[1]
    p = params.copy()
    p[P_THETA_MAX] = theta_max
    key = scene_key(model, scene.effects_mask | (REVOLUTIONS if math.isfinite(theta_max) else 0))
    out_fate = np.zeros(n, np.int8)
    out_f = np.empty((len(FATE_ROWS), n))
    out_n = np.zeros(n, np.int64)
    if n:
        args = (X, p, method.kernel_id, key, rtol, t_horizon, max_steps)
        if lanes and method.family == "runge-kutta":
            args += (numba.get_num_threads(), out_fate, out_f, out_n)
            call_specialized(_fate_lanes_kernel, args, LITERAL)
        else:
            call_specialized(
                _fate_points_kernel, args + (out_fate, out_f, out_n), ("method", "effects")
            )
    res = {"fate": out_fate}
    res.update({name: out_f[i] for i, name in enumerate(FATE_ROWS)})
    res["n_steps"] = out_n
    return res

"""Fate maps: what the scene does to each orbit, integrated from its start to its first terminal
event (spill, slip, rest, the vertex region) or a horizon (:class:`Horizon`, from
:mod:`engine.horizon`) (the Python side of :mod:`engine.kernels.fate`)."""

from __future__ import annotations

import math

import numpy as np

from .checks import check_horizon, check_max_steps, check_method, check_rtol, check_scene
from .horizon import Horizon
from .hybrid import HYBRID_VARIABLES, hybrid_fates
from .integrated import fate_points
from .kernels.effects import REVOLUTIONS
from .kernels.fate import FATE_ROWS
from .kernels.geometry import BOUNDED, CIRCULAR, HYPERBOLIC, RADIAL
from .kernels.layouts import P_THETA_MAX
from .methods import Method
from .scene import Scene
from .schema import FATE_KINDS

__all__ = ["Horizon", "fates", "fate_map", "require_horizon", "DEFAULT_MAX_STEPS"]

#: Step budget of one orbit's fate run (accepted + rejected steps).
DEFAULT_MAX_STEPS = 10_000_000


def require_horizon(horizon: Horizon | None) -> Horizon:
    """The horizon of a fate map, by the one rule (:func:`engine.checks.check_horizon`, in
    the API's words); a :class:`engine.checks.PlanError` (a ValueError) when none is given."""
    given = horizon or Horizon()
    checked = check_horizon(FATE_KINDS[0], given.time, given.revolutions)
    assert checked is not None  # a fate map's horizon, or check_horizon raised
    return checked


def fates(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    r_start: np.ndarray,
    scene: Scene,
    method: str,
    rtol: float,
    horizon: Horizon,
    *,
    classes: np.ndarray | None = None,
    max_steps: int = DEFAULT_MAX_STEPS,
    release: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """The fate of each orbit, started at rest radially at ``r_start`` (its r_min on an
    invariant grid, the launch radius on a launch grid; NaN: no orbit).

    Returns ``fate`` (int8, :data:`engine.kernels.fate.FATE_NAMES`), the float rows of
    :data:`engine.kernels.fate.FATE_ROWS` and ``n_steps``. On a scene with kinetic friction
    (``Scene.mu_k``) a slip is a transition: the whole story of each orbit
    (:func:`engine.hybrid.hybrid_fates`, its fates and variables), ``release`` = (u0, slip_u,
    slip_v) [m/s] the radial speed and slip velocity at the start (None: rolling at rest
    radially), ``energy`` the rolling orbit's calE through the start with that radial speed.
    """
    scene = check_scene(scene)
    m = check_method(method, scene, integrator=True)
    return fate_map(alpha, energy, h, Lz, r_start, scene, m, check_rtol(rtol, m),
                    require_horizon(horizon), classes=classes,
                    max_steps=check_max_steps(max_steps), release=release)  # fmt: skip


def fate_map(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    r_start: np.ndarray,
    scene: Scene,
    method: Method,
    rtol: float,
    horizon: Horizon,
    *,
    classes: np.ndarray | None = None,
    max_steps: int = DEFAULT_MAX_STEPS,
    release: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """:func:`fates` on inputs checked already (a survey's plan holds them: an integrator
    ``method``, its registry row, that honours the scene; its ``rtol``; a given ``horizon``)."""
    if release is not None and "sliding" not in scene.effects:
        raise ValueError("a launch that is not rolling (u0, slip_u, slip_v) needs Scene.mu_k")
    n = alpha.shape[0]
    params = scene.params()
    params[P_THETA_MAX] = horizon.theta_max
    effects = scene.effects_mask | (REVOLUTIONS if math.isfinite(horizon.theta_max) else 0)
    start = np.ascontiguousarray(r_start, np.float64)
    if classes is not None:  # points without an orbit have no start
        has_orbit = np.isin(classes, (BOUNDED, CIRCULAR, HYPERBOLIC, RADIAL))
        start = np.where(has_orbit, start, np.nan)
    if "sliding" in scene.effects:
        u0, slip_u, slip_v = (None, None, None) if release is None else release
        e_rest = energy if u0 is None else energy - 0.5 * scene.M * u0 * u0  # the kernel's
        res = hybrid_fates(alpha, e_rest, h, Lz, start, scene, method.name, rtol, horizon.t_max,
                           horizon.theta_max, u0=u0, slip_u=slip_u, slip_v=slip_v,
                           max_steps=max_steps)  # fmt: skip
        return {name: res[name] for name in ("fate", *FATE_ROWS, *HYBRID_VARIABLES, "n_steps")}
    out_fate = np.zeros(n, np.int8)
    out_f = np.empty((len(FATE_ROWS), n))
    out_n = np.zeros(n, np.int64)
    if n:
        fate_points(alpha, energy, h, Lz, start, params, method.kernel_id, effects, rtol,
                    horizon.t_max, int(max_steps), out_fate, out_f, out_n)  # fmt: skip
    res = {"fate": out_fate}
    res.update({name: out_f[i] for i, name in enumerate(FATE_ROWS)})
    res["n_steps"] = out_n
    return res

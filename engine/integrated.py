"""Orbit geometry by integration: one radial period per point, in a parallel numba kernel.

:func:`evaluate_integrated` integrates each point's orbit from its inner turning point r_min
(u = 0, theta = 0) and reports the radial period, the apsidal angle (azimuth swept from r_min
to the next r_max), the precession rate, the work done (accepted steps), the energy drift and a
status code. A conservative scene's radial motion is symmetric under time reversal (r_max back
to r_min mirrors r_min to r_max), so it is integrated to r_max only and the time doubled: half
the work of the whole period, the same period and apsidal angle. With rolling resistance the
motion is not symmetric: the first (decaying) radial period is integrated to the next r_min,
and the energy lost over it is reported too.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from ._jit import call_specialized
from .checks import check_max_steps, check_method, check_rtol, check_scene
from .kernels.fate import fate_points as _fate_points_kernel
from .kernels.lanes import integrate_points_lanes as _lanes_kernel
from .kernels.lanes_fate import fate_points_lanes as _fate_lanes_kernel
from .kernels.orbit import PERIOD_ROWS
from .kernels.orbit import integrate_points as _integrate_points_kernel
from .kernels.protocol import LITERAL, STATUS_MESSAGES, UNSUPPORTED
from .methods import DEFAULT_RTOL, METHODS, Method
from .scene import Scene
from .schema import period_variables

__all__ = [
    "evaluate_integrated",
    "integrate_period",
    "integrate_points",
    "fate_points",
    "STATUS_MESSAGES",
    "DEFAULT_MAX_STEPS",
]

#: Step budget per orbit (accepted + rejected steps); beyond it the status is MAX_STEPS.
DEFAULT_MAX_STEPS = 1_000_000
_BY_ID = {m.kernel_id: m for m in METHODS.values() if m.integrates}
#: Each integrator's refused effects as a kernel mask (computed once, not per call).
_REFUSED = {m.kernel_id: m.refused_mask for m in _BY_ID.values()}


@functools.lru_cache(maxsize=64)
def _checked_method(name: str, scene: Scene) -> Method:
    return check_method(name, scene, integrator=True)


@functools.lru_cache(maxsize=64)
def _scene_parts(scene: Scene) -> tuple[np.ndarray, int, tuple[str, ...]]:
    """What a call needs of a scene (its parameter array, effects mask and outputs), once per
    scene: a call's Python work is time the threads cannot share (the serial share)."""
    return scene.params(), scene.effects_mask, period_variables(scene)


def points(*columns: np.ndarray) -> np.ndarray:
    """The points array of the kernels: one row per input (the model's columns: the cone's
    alpha, calE, h, L_z and a fate map's r_start), one column per point (float64, C order)."""
    return np.ascontiguousarray(np.stack([np.asarray(c, np.float64) for c in columns]))


def integrate_points(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    params: np.ndarray,
    method: int,
    effects: int,
    rtol: float,
    max_steps: int,
    out_f: np.ndarray,
    out_n: np.ndarray,
    out_status: np.ndarray,
) -> None:
    """One radial period from r_min for every point, in parallel (numba prange): to r_max and
    doubled for a conservative ``effects``, to the next r_min with rolling resistance.

    alpha, energy, h, Lz: 1-D float64 [rad, J, m/s, kg m^2/s]; ``params`` the scene's parameter
    array (:meth:`engine.Scene.params`; alpha is replaced per point); ``method`` a kernel id
    (:attr:`engine.methods.Method.kernel_id`) and ``effects`` a bit mask (each pair is compiled
    once, then cached). Writes ``out_f`` float64[5, n] (rows
    :data:`engine.kernels.orbit.PERIOD_ROWS`: period [s], apsidal angle [rad], precession rate
    [rad/s], energy drift [1], energy loss [J]), ``out_n`` int64[n] accepted steps and
    ``out_status`` int8[n]. Never raises on bad points: they get a status code and NaN. A
    method that cannot honour the effects gives every point the status UNSUPPORTED, without
    compiling anything.
    """
    m = _BY_ID[method]
    if effects & _REFUSED[method]:
        out_f[:] = math.nan
        out_n[:] = 0
        out_status[:] = UNSUPPORTED
        return
    X = points(alpha, energy, h, Lz)
    if m.family == "runge-kutta":  # several orbits at once on the SIMD lanes
        args = (X, params, method, effects, rtol, max_steps, numba.get_num_threads(), out_f,
                out_n, out_status)  # fmt: skip
        call_specialized(_lanes_kernel, args, LITERAL)
        return
    args = (X, params, method, effects, rtol, max_steps, out_f, out_n, out_status)
    call_specialized(_integrate_points_kernel, args, LITERAL)


def fate_points(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    r_start: np.ndarray,
    params: np.ndarray,
    method: int,
    effects: int,
    rtol: float,
    t_horizon: float,
    max_steps: int,
    out_fate: np.ndarray,
    out_f: np.ndarray,
    out_n: np.ndarray,
    *,
    lanes: bool = True,
) -> None:
    """Every point's fate (:func:`engine.kernels.fate.fate_points`, same arguments and outputs),
    in parallel: a Runge-Kutta ``method`` runs several orbits at once on the SIMD lanes
    (:mod:`engine.kernels.lanes_fate`, the same results bit for bit; ``lanes=False`` runs one
    orbit per thread, for comparison), other methods one orbit per thread."""
    args = (points(alpha, energy, h, Lz, r_start), params, method, effects, rtol, t_horizon,
            max_steps)  # fmt: skip
    if lanes and _BY_ID[method].family == "runge-kutta":
        args += (numba.get_num_threads(), out_fate, out_f, out_n)
        call_specialized(_fate_lanes_kernel, args, LITERAL)
        return
    call_specialized(_fate_points_kernel, args + (out_fate, out_f, out_n), LITERAL)


def evaluate_integrated(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    scene: Scene,
    method: str = "rk45",
    rtol: float = DEFAULT_RTOL,
    *,
    max_steps: int = DEFAULT_MAX_STEPS,
) -> dict[str, np.ndarray]:
    """One radial period from r_min for each point, by integration (module docstring: to r_max
    and doubled where the scene is conservative, the whole period with rolling resistance).

    Parameters
    ----------
    alpha, energy, h, Lz : equal-length 1-D float64 arrays: half-aperture [rad], radial energy
        calE [J], spin invariant [m/s], axial angular momentum [kg m^2/s].
    scene : the scene (its effects are compiled in).
    method : an integrator of :data:`engine.methods.METHODS` ("rk45", "dop853", "symplectic").
    rtol : relative tolerance, in [1e-14, 1e-3]. The integrated period and apsidal angle are
        within 100 rtol kappa relative, kappa = max(1, (A/r1^2)/|calE|) the amplification of a
        velocity error at the pericentre into the radial energy: ~1 for most orbits, (1+e)/(1-e)
        for the period of a free-fall ellipse of eccentricity e (tests/kernels/test_rk.py).
        For "symplectic" rtol sets the fixed step in the fictitious time (same target).
    max_steps : step budget per orbit.

    Returns
    -------
    dict of 1-D arrays: "period" [s], "apsidal_angle" [rad], "precession_rate" [rad/s],
    "n_steps" (int64, accepted steps: the work done), "energy_drift" (|E(t) - E(0)| /
    max(|E(0)|, KE(0)) at the end t of the integration, r_max or the next r_min, KE the kinetic
    energy at the start: relative to the total energy E, or to the kinetic energy where E ~ 0),
    "status" (int8, meanings in ``STATUS_MESSAGES``); with rolling resistance also
    "energy_loss" [J] = E(0) - E(T) (and "energy_drift" is then that physical loss, scaled).
    Failed points have NaN and a nonzero status; a sphere that rolling resistance brings to rest
    within the period ends with "step size fell below 16 eps |t|" (the friction force turns
    discontinuously at zero speed).
    """
    # a (method, scene) checked once; an unhashable method name goes to the check's message
    scene = check_scene(scene)
    m = (_checked_method(method, scene) if isinstance(method, str)
         else check_method(method, scene, integrator=True))  # fmt: skip
    r = check_rtol(rtol, m)
    arrays = []
    for name, arr in (("alpha", alpha), ("energy", energy), ("h", h), ("Lz", Lz)):
        a = np.ascontiguousarray(arr, dtype=np.float64)
        if a.ndim != 1:
            raise ValueError(f"{name} must be a 1-D array; got shape {a.shape}")
        arrays.append(a)
    n = arrays[0].shape[0]
    for name, a in zip(("energy", "h", "Lz"), arrays[1:], strict=True):
        if a.shape[0] != n:
            raise ValueError(f"{name} has length {a.shape[0]}, alpha has {n}")
    return integrate_period(*arrays, scene, m, r, check_max_steps(max_steps))


def integrate_period(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    scene: Scene,
    method: Method,
    rtol: float,
    max_steps: int = DEFAULT_MAX_STEPS,
) -> dict[str, np.ndarray]:
    """:func:`evaluate_integrated` on inputs checked already: equal-length contiguous 1-D
    float64 arrays, an integrator ``method`` (its registry row) that honours the scene and an
    ``rtol`` in its range (a survey's plan, :class:`engine.plan.MapPlan`, holds them)."""
    n = alpha.shape[0]
    # Written (and first touched) by the parallel kernel, point by point: no serial pass here.
    out_f = np.empty((len(PERIOD_ROWS), n))
    out_n = np.empty(n, np.int64)
    out_status = np.empty(n, np.int8)
    params, effects, produced = _scene_parts(scene)
    if n:
        integrate_points(alpha, energy, h, Lz, params.copy(), method.kernel_id, effects, rtol,
                         max_steps, out_f, out_n, out_status)  # fmt: skip
    res = {name: out_f[i] for i, name in enumerate(PERIOD_ROWS) if name in produced}
    res["n_steps"] = out_n
    res["status"] = out_status
    return res

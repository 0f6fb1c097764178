"""The ball's whole story (the Python side of :mod:`engine.kernels.hybrid`): fate maps of a scene
with kinetic friction ``mu_k`` (a slip is a transition: the sphere slides, and may roll again)
and spin friction ``c_spin``, from rolling launches or launches with a radial speed and a slip
velocity; and one launch followed with each mode change reported.

docs/physics.md "Sliding, rolling again, and spin friction" has the model and the rules.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._jit import call_specialized
from .checks import check_method, check_scene
from .kernels.contact import contact_key
from .kernels.effects import REVOLUTIONS, ROLLING_EFFECTS
from .kernels.hybrid import (
    HYBRID_ROWS,
    hybrid_fate_points,
    hybrid_story,
)
from .kernels.lanes_hybrid import hybrid_fate_points_lanes
from .kernels.layouts import P_THETA_MAX
from .kernels.model import CONE, model_of_key, scene_key
from .kernels.protocol import LITERAL as RUN_LITERAL
from .kernels.sliding import HYBRID_STATE  # the components of an event's ``state``
from .scene import Scene

__all__ = ["HYBRID_VARIABLES", "HYBRID_STATE", "hybrid_fates", "hybrid_model", "hybrid_setup",
           "whole_story"]  # fmt: skip

#: Variables a fate map of a sliding scene adds to today's fate variables.
HYBRID_VARIABLES = HYBRID_ROWS[6:]
#: The hybrid kernels' literal parameters (:func:`._jit.call_specialized`): a run's, the
#: contact key (the model whose contact frame the hybrid steps read and the applied effects:
#: :func:`hybrid_model`), and whether spin friction is on.
LITERAL = (*RUN_LITERAL, "model", "spin")
#: Step budget of one launch (accepted + rejected steps, both modes).
MAX_STEPS = 10_000_000


def hybrid_setup(
    scene: Scene, theta_max: float, params: np.ndarray | None = None, model: int = CONE
) -> tuple[np.ndarray, int, int]:
    """(params, the rolling scene's literal effects, the spin literal) of a hybrid run of
    ``scene`` with the horizon ``theta_max`` [rad] (inf: none), on the cone or on the model
    ``model`` with its parameter array ``params``."""
    check_scene(scene, sliding=True)
    params = scene.params() if params is None else params
    params[P_THETA_MAX] = theta_max
    effects = (scene.effects_mask & ROLLING_EFFECTS) | (
        REVOLUTIONS if math.isfinite(theta_max) else 0
    )
    return params, scene_key(model, effects), 1 if scene.c_spin > 0 else 0


def hybrid_model(effects: int) -> int:
    """The hybrid kernels' literal ``model`` of a rolling scene's ``effects`` literal: its model
    and the applied effects the sliding equations ask of the effects' terms
    (:func:`.kernels.contact.contact_key`)."""
    return contact_key(model_of_key(effects), effects)


def whole_story(
    method_id: int,
    params: np.ndarray,
    effects: int,
    spin: int,
    scene: Scene,
    start: tuple[float, ...],
    rtol: float,
    t_horizon: float,
    max_steps: int = MAX_STEPS,
    capacity: int = 64,
) -> tuple:
    """:func:`.kernels.hybrid.hybrid_story` of one launch (``start``: the model's launch tuple,
    :func:`.kernels.contact.story_start`; the cone's (calE, h, L_z, r_start, u0, slip_u,
    slip_v)) with every event and mark it records: a story with more than ``capacity`` of them
    counts them all (kernels/protocol ``push_event``) and is told again with room for that
    count (the story is deterministic: the same events again). Returns the kernel's tuple
    (fate, floats, steps, n_events, times, kinds, states), the arrays cut to n_events."""
    cap = max(int(capacity), 1)
    while True:
        res = hybrid_story(method_id, effects, hybrid_model(effects), spin, params,
                           float(scene.mu_k), float(scene.c_spin), *map(float, start),
                           float(rtol), float(t_horizon), int(max_steps), cap)  # fmt: skip
        if res[3] <= cap:
            break
        cap = int(res[3])
    fate, f, steps, n_ev, ev_t, ev_kind, ev_y = res
    return fate, f, steps, n_ev, ev_t[:n_ev], ev_kind[:n_ev], ev_y[:n_ev]


def hybrid_fates(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    r_start: np.ndarray,
    scene: Scene,
    method: str,
    rtol: float,
    t_max: float,
    theta_max: float,
    *,
    u0: np.ndarray | None = None,
    slip_u: np.ndarray | None = None,
    slip_v: np.ndarray | None = None,
    max_steps: int = MAX_STEPS,
    lanes: bool = True,
) -> dict[str, np.ndarray]:
    """The whole story of each launch (1-D arrays): at ``r_start`` [m] on the rolling orbit
    (calE [J], h [m/s], L_z) with radial speed ``u0`` [m/s] and slip velocity (``slip_u``,
    ``slip_v``) [m/s] (default 0: rolling from rest radially, as a fate map starts).

    Returns ``fate`` (int8, :data:`engine.kernels.hybrid.HYBRID_FATE_NAMES`), the float rows of
    :data:`engine.kernels.hybrid.HYBRID_ROWS` (``slip_episodes`` as int32) and ``n_steps``.
    Without spin friction the launches run several at once on the SIMD lanes
    (:mod:`engine.kernels.lanes_hybrid`: their rolling stretches on the vector step; the same
    results bit for bit; ``lanes=False`` runs one launch per thread, for comparison). With
    spin friction every stretch is on the hybrid steps, which the lanes would run in scalar
    code anyway (measured no faster): one launch per thread.
    """
    m = check_method(method, scene, integrator=True)
    params, effects, spin = hybrid_setup(scene, theta_max)
    n = alpha.shape[0]
    zero = np.zeros(n)
    cols = [np.ascontiguousarray(c, np.float64) for c in (alpha, energy, h, Lz, r_start)]
    extra = [np.ascontiguousarray(zero if c is None else c, np.float64) for c in
             (u0, slip_u, slip_v)]  # fmt: skip
    launch = (*cols, *extra)  # kernels/story_parts.LAUNCH_COLUMNS
    out_fate = np.zeros(n, np.int8)
    out_f = np.empty((len(HYBRID_ROWS), n))
    out_n = np.zeros(n, np.int64)
    if n:
        args = (launch, params, float(scene.mu_k), float(scene.c_spin), m.kernel_id, effects,
                hybrid_model(effects), spin, float(rtol), float(t_max),
                int(max_steps))  # fmt: skip
        if lanes and m.family == "runge-kutta" and spin == 0:
            args += (numba.get_num_threads(), out_fate, out_f, out_n)
            call_specialized(hybrid_fate_points_lanes, args, LITERAL)
        else:
            call_specialized(hybrid_fate_points, args + (out_fate, out_f, out_n), LITERAL)
    res: dict[str, np.ndarray] = {"fate": out_fate}
    for i, name in enumerate(HYBRID_ROWS):
        res[name] = out_f[i]
    res["slip_episodes"] = np.where(np.isnan(out_f[7]), -1, out_f[7]).astype(np.int32)
    res["n_steps"] = out_n
    return res

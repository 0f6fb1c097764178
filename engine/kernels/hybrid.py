"""The ball's whole story: rolling, slipping, sliding, rolling again, spilling, stopping
(docs/physics.md "Sliding, rolling again, and spin friction").

:func:`hybrid_fate_of` follows one launch through its modes. Rolling without spin friction runs
on the rolling integrators exactly as a fate map does (:func:`.fate.fate_run`: the same steps,
events and stop), so an orbit that never slips gets today's fate bit for bit; sliding, and
rolling with spin friction, run on the hybrid steps of :mod:`.hybrid_step`. A switch is an
event of the mode it leaves (the slip, the return to rolling); each is recorded.

``spin`` (a literal: 0 or 1) compiles spin friction in; ``effects`` is the rolling scene's
literal effect set (with :data:`.model.SLIP_CHECK`: the static friction limit). The pieces of a
story are in :mod:`.story_parts`, its loop up to each rolling stretch here
(:func:`story_until_rolling`), both shared with the lanes (:mod:`.lanes_hybrid`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, prange

from .._jit import kernel, parallel_kernel
from .cone import set_alpha
from .fate import fate_run
from .layouts import state_size
from .rk_codegen import tableau
from .sliding import MODE_ROLLING, N_HYBRID, N_HYBRID_PARAMS
from .story_parts import (
    HI_FATE,
    HI_MODE,
    HI_NEV,
    HI_STEPS,
    HS_T,
    HYBRID_FATE_NAMES,
    HYBRID_ROWS,
    L_ALPHA,
    L_ENERGY,
    L_H,
    L_LZ,
    L_R_START,
    L_SLIP_U,
    L_SLIP_V,
    L_U0,
    N_HI,
    N_HS,
    SLIDING,
    hybrid_stretch,
    rolled,
    rolling_stretch,
    story_begin,
    story_result,
    story_runs_out,
)
from .story_switches import stretch_start

__all__ = ["HYBRID_FATE_NAMES", "HYBRID_ROWS", "SLIDING", "hybrid_fate_of", "hybrid_fate_points",
           "hybrid_story"]  # fmt: skip


@kernel
def story_until_rolling(method, effects, model, spin, p, y, y0, atol, hp, hatol, rtol, t_horizon,
                        max_steps, hw, rolling, hs, hi, events):  # fmt: skip
    """Go on with a story until its next rolling stretch without spin friction, a fate run,
    or its end: the story's loop, one description for the scalar kernel (which runs the
    stretch with :func:`.fate.fate_run`) and the lanes (which run it on the vector step,
    :mod:`.lanes_hybrid`); each takes the stretch's end with :func:`.story_parts.rolled`.

    Each stretch starts with what its start decides (:func:`.story_switches.stretch_start`);
    a story out of steps or restarts has failed (:func:`.story_parts.story_runs_out`); any
    stretch but a rolling one without spin friction runs here on the hybrid steps
    (:func:`.story_parts.hybrid_stretch`). ``hw``: the hybrid steps' scratch (stages K and
    three states); ``rolling``: the stretch's start and tolerances (yr, ra), written where one
    starts (:func:`.story_parts.rolling_stretch`); ``events``: the story's buffers (ev_t,
    ev_kind, ev_y). Returns (True, the stretch's orbit (calE, h, L_z)) where a rolling
    stretch starts, (False, NaNs) where the story has ended (its fate in ``hi``).
    """
    ev_t, ev_kind, ev_y = events
    yr, ra = rolling
    while hi[HI_FATE] < 0:
        if story_runs_out(max_steps, hi):
            break
        stretch_start(model, p, y, hp, t_horizon, hs, hi, ev_t, ev_kind, ev_y)  # at its start
        if hi[HI_FATE] >= 0:
            break
        if hi[HI_MODE] == MODE_ROLLING and spin == 0:
            return True, rolling_stretch(effects, model, p, y, y0, atol, rtol, hs, hi, yr, ra)
        hybrid_stretch(method, model, p, y, hp, rtol, hatol, t_horizon, max_steps, hw[0], hw[1],
                       hw[2], hw[3], hs, hi, ev_t, ev_kind, ev_y)  # fmt: skip
    nan = math.nan
    return False, (nan, nan, nan)


@kernel
def hybrid_fate_of(method, effects, model, spin, p, mu_k, c_spin, energy, h, Lz, r_start, u0,
                   slip_u, slip_v, rtol, t_horizon, max_steps, ev_t, ev_kind, ev_y):  # fmt: skip
    """The whole story of the launch at ``r_start`` [m] on the rolling orbit (calE, h, L_z) (its
    v and w), with radial speed u0 [m/s] and the contact point's slip velocity (slip_u along
    the generatrix, slip_v along the parallel) [m/s] (0, 0: rolling).

    Returns (fate, floats (the rows :data:`HYBRID_ROWS`), steps, events recorded); the events
    (kind of :data:`.hybrid_step.HYBRID_EVENT_NAMES`, time, hybrid state) go to the buffers.
    The story runs from :func:`story_begin` to :func:`story_result`: the story's loop
    (:func:`story_until_rolling`, the lanes' too) up to each rolling stretch without spin
    friction, which :func:`.fate.fate_run` runs and :func:`rolled` ends.
    """
    out = np.full(len(HYBRID_ROWS), math.nan)
    nr = state_size(effects)
    y0 = np.empty(nr)
    atol = np.empty(nr)
    hp = np.empty(N_HYBRID_PARAMS)
    y = np.zeros(N_HYBRID)
    hatol = np.empty(N_HYBRID)
    hs = np.zeros(N_HS)
    hi = np.zeros(N_HI, np.int64)
    start = (energy, h, Lz, r_start, u0, slip_u, slip_v)
    fate = story_begin(effects, model, spin, p, mu_k, c_spin, start, rtol, out, y0, atol, hp, y,
                       hatol, hs, hi)  # fmt: skip
    if fate >= 0:
        return fate, out, 0, 0
    S = tableau(method)[6]
    K = np.empty((S, N_HYBRID))
    ytmp = np.empty(N_HYBRID)
    ynew = np.empty(N_HYBRID)
    yev = np.empty(N_HYBRID)
    yr = np.empty(nr)
    ra = np.empty(nr)
    hw = (K, ytmp, ynew, yev)
    events = (ev_t, ev_kind, ev_y)
    while True:
        rolls, orb = story_until_rolling(method, effects, model, spin, p, y, y0, atol, hp, hatol,
                                         rtol, t_horizon, max_steps, hw, (yr, ra), hs, hi,
                                         events)  # fmt: skip
        if not rolls:
            break
        f, dt, yf, st = fate_run(method, effects, p, yr, orb, rtol, ra, t_horizon - hs[HS_T],
                                 max_steps - hi[HI_STEPS])  # fmt: skip
        rolled(effects, f, dt, yf, st, y, hs, hi, ev_t, ev_kind, ev_y)
    fate = story_result(effects, model, spin, p, y, y0, hp, hs, hi, out)
    return fate, out, hi[HI_STEPS], hi[HI_NEV]


@parallel_kernel
def hybrid_fate_points(launch, params, mu_k, c_spin, method, effects, model, spin, rtol, t_horizon,
                       max_steps, out_fate, out_f, out_n):  # fmt: skip
    """:func:`hybrid_fate_of` for every point of ``launch`` (the ``L_*`` tuple of
    :mod:`.story_parts`), in parallel (``method``, ``effects``, ``spin``: literal ints). Writes
    ``out_fate`` int8[n], ``out_f`` float64[len(HYBRID_ROWS), n] and ``out_n`` int64[n] steps."""
    literally(method)
    literally(effects)
    literally(model)
    literally(spin)
    for i in prange(launch[L_ALPHA].shape[0]):
        p = params.copy()
        set_alpha(p, launch[L_ALPHA][i])
        ev_t = np.empty(0)
        ev_kind = np.empty(0, np.int8)
        ev_y = np.empty((0, N_HYBRID))
        fate, f, steps, _ = hybrid_fate_of(method, effects, model, spin, p, mu_k, c_spin,
                                           launch[L_ENERGY][i], launch[L_H][i], launch[L_LZ][i],
                                           launch[L_R_START][i], launch[L_U0][i],
                                           launch[L_SLIP_U][i], launch[L_SLIP_V][i], rtol,
                                           t_horizon, max_steps, ev_t, ev_kind,
                                           ev_y)  # fmt: skip
        out_fate[i] = fate
        for j in range(f.shape[0]):
            out_f[j, i] = f[j]
        out_n[i] = steps


@kernel
def hybrid_story(method, effects, model, spin, p, mu_k, c_spin, energy, h, Lz, r_start, u0, slip_u,
                 slip_v, rtol, t_horizon, max_steps, capacity):  # fmt: skip
    """:func:`hybrid_fate_of` of one launch with its events kept (at most ``capacity``):
    (fate, floats, steps, n_events, event times, kinds, states)."""
    literally(method)
    literally(effects)
    literally(model)
    literally(spin)
    ev_t = np.empty(capacity)
    ev_kind = np.empty(capacity, np.int8)
    ev_y = np.empty((capacity, N_HYBRID))
    fate, f, steps, n_ev = hybrid_fate_of(method, effects, model, spin, p, mu_k, c_spin, energy, h,
                                          Lz, r_start, u0, slip_u, slip_v, rtol, t_horizon,
                                          max_steps, ev_t, ev_kind, ev_y)  # fmt: skip
    return fate, f, steps, n_ev, ev_t, ev_kind, ev_y

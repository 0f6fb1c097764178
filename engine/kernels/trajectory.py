"""Kernels of the single trajectory (:func:`engine.simulate`): a rolling run across stops
(:func:`solve_restarting`, the fate maps' own rest/restart loop) and the sampled trajectory
of a hybrid story (a scene with ``mu_k``).

A story (:func:`.hybrid.hybrid_story`) gives the mode changes: their times and states. Between
two of them the mode (rolling or sliding) and the spin stick do not change, so each stretch is
integrated again here from the state after its opening change, in its mode, on the hybrid
steps of :func:`.hybrid_rk.advance` (the story's steps and rules, no events: the story has
located them), landing exactly on the sample times (every ``dt_out`` seconds)
or recording every accepted step. Each stretch starts from the story's state, so the samples
agree with the story to the integrator's tolerance and errors do not carry across changes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally

from .._jit import kernel
from .fate import run_restarting
from .hybrid_rk import (
    ADV_MAX_STEPS,
    ADV_REACHED,
    ADV_TOO_SMALL,
    advance,
    arm,
    first_step,
    step_controller,
)
from .protocol import BUFFER_FULL, MAX_STEPS, NONFINITE, OK, STEP_TOO_SMALL
from .rk_codegen import tableau
from .sliding import N_HYBRID


@kernel
def _record(tr_t, tr_y, tr_mode, n, t, y, mode):
    if n < tr_t.shape[0]:
        tr_t[n] = t
        tr_mode[n] = mode
        for j in range(N_HYBRID):
            tr_y[n, j] = y[j]
    return n + 1


@kernel
def trace_stretches(method, model, hp, seg_t0, seg_t1, seg_y, seg_mode, seg_stuck, seg_keep, rtol,
                    atol, dt_out, max_steps, tr_t, tr_y, tr_mode):  # fmt: skip
    """Integrate stretch i from (seg_t0[i], seg_y[i]) to seg_t1[i] [s] in mode seg_mode[i]
    (spin stuck: seg_stuck[i]), recording each stretch's start, then every accepted step
    (``dt_out`` = 0) or the multiples of ``dt_out`` [s] inside it, and the last stretch's end.
    The steps are the story's (:func:`.hybrid_rk.advance`), with the stops armed as the story
    arms them: the bits of ``armed`` kept across the change that opens stretch i are
    seg_keep[i] (0 for the first).

    Returns (status: OK, :data:`.protocol.BUFFER_FULL` (the buffers were too small: nothing
    is lost by calling again with larger ones) or the failure's status (step budget, step-size
    underflow, a non-finite state); samples recorded; step attempts)."""
    literally(method)
    literally(model)
    ns = tableau(method)[5]
    S = tableau(method)[6]
    ctl = step_controller(method)
    K = np.empty((S, N_HYBRID))
    ytmp = np.empty(N_HYBRID)
    ynew = np.empty(N_HYBRID)
    cap = tr_t.shape[0]
    n_rec = 0
    steps = 0
    armed = 0
    n_seg = seg_t0.shape[0]
    for i in range(n_seg):
        y = seg_y[i].copy()
        mode = seg_mode[i]
        stuck = seg_stuck[i]
        t = seg_t0[i]
        t1 = seg_t1[i]
        armed &= seg_keep[i]
        n_rec = _record(tr_t, tr_y, tr_mode, n_rec, t, y, mode)
        if not t1 > t:
            continue
        h = first_step(model, y, hp, mode, stuck, K, rtol, atol)
        err_old = 1e-4
        rejected = False
        ts = math.inf
        if dt_out > 0.0:
            ts = (math.floor(t / dt_out) + 1.0) * dt_out
        while True:
            target = min(t1, ts)
            st, h_try, h_next, err_old, rejected, steps = advance(
                method, model, y, t, target, h, hp, mode, stuck, armed, K, ytmp, ynew, rtol, atol,
                ctl, err_old, rejected, steps, max_steps)  # fmt: skip
            if st == ADV_REACHED:  # a sample within rounding of t
                t = target
            elif st == ADV_MAX_STEPS:
                return MAX_STEPS, min(n_rec, cap), steps
            elif st == ADV_TOO_SMALL:
                return STEP_TOO_SMALL, min(n_rec, cap), steps
            else:
                for j in range(N_HYBRID):
                    y[j] = ynew[j]
                    K[0, j] = K[ns, j]
                    if not math.isfinite(y[j]):
                        return NONFINITE, min(n_rec, cap), steps
                t = target if h_try == target - t else t + h_try
                h = h_next
                armed = arm(y, hp, mode, stuck, armed)
            if t >= t1:
                break
            if dt_out == 0.0 or t >= ts:
                n_rec = _record(tr_t, tr_y, tr_mode, n_rec, t, y, mode)
            if t >= ts:
                ts += dt_out
        if i == n_seg - 1:
            n_rec = _record(tr_t, tr_y, tr_mode, n_rec, t1, y, mode)
    if n_rec > cap:
        return BUFFER_FULL, cap, steps
    return OK, n_rec, steps


@kernel
def solve_restarting(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps,
                     record, dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
    """:func:`.fate.run_restarting` (the run protocol across stops by rolling resistance)
    compiled for a literal method and effect set: the entry point of a rolling trajectory."""
    literally(method)
    literally(effects)
    return run_restarting(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides,
                          max_steps, record, dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y,
                          tr_rate)  # fmt: skip

"""Kernels of the single trajectory (:func:`engine.simulate`): a rolling run across stops
(:func:`solve_restarting`, the fate maps' own rest/restart loop) and the sampled trajectory
of a hybrid story (a scene with ``mu_k``).

A story (:func:`.hybrid.hybrid_story`) gives the mode changes: their times and states. Between
two of them the mode (rolling or sliding) and the spin stick do not change, so each stretch is
integrated again here from the state after its opening change, in its mode, on the hybrid
steps of :mod:`.hybrid_step` (the same tableaux, error norm and step controller, no events:
the story has located them), landing exactly on the sample times (every ``dt_out`` seconds)
or recording every accepted step. Each stretch starts from the story's state, so the samples
agree with the story to the integrator's tolerance and errors do not carry across changes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally

from .._jit import kernel
from .fate import run_restarting
from .hybrid_step import decide, hybrid_attempt, step_controller
from .protocol import BUFFER_FULL, EPS, MAX_STEPS, NONFINITE, OK, STEP_TOO_SMALL
from .rk_codegen import tableau
from .sliding import N_HYBRID, hybrid_rhs


@kernel
def _record(tr_t, tr_y, tr_mode, n, t, y, mode):
    if n < tr_t.shape[0]:
        tr_t[n] = t
        tr_mode[n] = mode
        for j in range(N_HYBRID):
            tr_y[n, j] = y[j]
    return n + 1


@kernel
def trace_stretches(method, hp, seg_t0, seg_t1, seg_y, seg_mode, seg_stuck, rtol, atol, dt_out,
                    max_steps, tr_t, tr_y, tr_mode):  # fmt: skip
    """Integrate stretch i from (seg_t0[i], seg_y[i]) to seg_t1[i] [s] in mode seg_mode[i]
    (spin stuck: seg_stuck[i]), recording each stretch's start, then every accepted step
    (``dt_out`` = 0) or the multiples of ``dt_out`` [s] inside it, and the last stretch's end.

    Returns (status: OK, :data:`.protocol.BUFFER_FULL` (the buffers were too small: nothing
    is lost by calling again with larger ones) or the failure's status (step budget, step-size
    underflow, a non-finite state); samples recorded; step attempts)."""
    literally(method)
    ns = tableau(method)[5]
    S = tableau(method)[6]
    ctl = step_controller(method)
    K = np.empty((S, N_HYBRID))
    ytmp = np.empty(N_HYBRID)
    ynew = np.empty(N_HYBRID)
    cap = tr_t.shape[0]
    n_rec = 0
    steps = 0
    n_seg = seg_t0.shape[0]
    for i in range(n_seg):
        y = seg_y[i].copy()
        mode = seg_mode[i]
        stuck = seg_stuck[i]
        t = seg_t0[i]
        t1 = seg_t1[i]
        n_rec = _record(tr_t, tr_y, tr_mode, n_rec, t, y, mode)
        if not t1 > t:
            continue
        hybrid_rhs(y, hp, mode, stuck, K[0])
        d0 = 0.0
        d1 = 0.0
        for j in range(N_HYBRID):
            sc = atol[j] + rtol * abs(y[j])
            d0 += (y[j] / sc) ** 2
            d1 += (K[0, j] / sc) ** 2
        h = 0.01 * math.sqrt(d0 / d1) if d1 > 1e-10 and d0 > 1e-10 else 1e-6
        h = min(h, t1 - t)
        err_old = 1e-4
        rejected = False
        ts = math.inf
        if dt_out > 0.0:
            ts = (math.floor(t / dt_out) + 1.0) * dt_out
        while True:
            target = min(t1, ts)
            h_try = min(h, target - t)
            if not h_try > 16.0 * EPS * abs(t):
                if target - t <= 16.0 * EPS * abs(t):  # a sample within rounding of t
                    t = target
                else:
                    return STEP_TOO_SMALL, min(n_rec, cap), steps
            else:
                if steps >= max_steps:
                    return MAX_STEPS, min(n_rec, cap), steps
                err = hybrid_attempt(method, y, h_try, hp, mode, stuck, K, ytmp, ynew, rtol,
                                     atol)  # fmt: skip
                steps += 1
                dec = decide(err, ynew[0], h_try, err_old, rejected, ctl)
                accepted, h_used, h_next, err_old, rejected = dec
                if not accepted:
                    h = h_used
                    continue
                for j in range(N_HYBRID):
                    y[j] = ynew[j]
                    K[0, j] = K[ns, j]
                    if not math.isfinite(y[j]):
                        return NONFINITE, min(n_rec, cap), steps
                t = target if h_try == target - t else t + h_try
                h = h_next
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

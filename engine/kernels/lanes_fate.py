"""Fate maps on the SIMD lanes: :func:`.fate.fate_points` for the Runge-Kutta methods, its
results bit for bit.

Each lane follows one orbit to its fate the way :func:`.fate.fate_of` does, with the same
pieces: its start (the model's :func:`.model.fate_start`: the rest threshold, a radial
orbit's way out of the vertex region), a start at rest (:func:`.fate.starts_at_rest`), runs as
:func:`.rk.rk_run` takes them (:func:`.lanes.lane_begin`, the vectorised step and a step-size
control that looks for no apsides and clips the last step to the horizon as rk_run clips it to
t_end: :func:`.lanes_step.lanes_control_fate`), what follows a run (:func:`.fate.next_run`,
the one restart rule: a stop by rolling resistance ends the fate or restarts the run from rest
in the same lane, :func:`lane_run_ended`) and
the result (:func:`.fate.fate_result`). A lane whose orbit has its fate takes the next point
from the queue the threads share (tests/kernels/test_lanes_fate.py checks every output
against the scalar kernel's).
"""

from __future__ import annotations

import numpy as np
from numba import literally, prange

from .._jit import kernel, parallel_kernel
from .fate import (
    ended_at_start,
    fate_of_status,
    fate_result,
    next_run,
    starts_at_rest,
    store_fate,
)
from .fate_codes import ROLLING, RUNS
from .lanes import (
    ORBIT,
    lane_advance,
    lane_begin,
    lane_load_step,
    lane_params,
    lane_workspace,
)
from .lanes_step import (
    LANES,
    borrow,
    fetch_add,
    lanes_attempt,
    lanes_control_fate,
    lanes_layout,
)
from .model import N_PARAMS, fate_start, set_point
from .protocol import BUFFER_FULL, OK, terminal_between, terminal_events
from .rk import clip_step, step_allowed
from .rk_events import rk_dense, step_events

#: Columns of a fate lane's floats: the time its run started at (restarts), the time and work
#: of the way out of the vertex region, and the horizon counted from there (:func:`.fate.fate_of`).
F_T0, F_TV, F_WORK0, F_HORIZON = 0, 1, 2, 3
#: Column of the int array after :data:`.lanes.ORBIT` ... :data:`.lanes.N_EV`: restarts so far.
RESTARTS = 3
#: A worker's lane runs travel as one tuple (numba's own type: a class of this package in a
#: cached signature would stop another version from reading that cache), with these places:
#: the lanes (:func:`.lanes.lane_workspace`: the vector state W, ints I, floats F, event buffers
#: LEV, LEVK) and the scalar arrays their runs share (stages K, a state buf, the located events'
#: buffers). :mod:`.lanes_hybrid` runs its rolling stretches with the same tuple.
R_W, R_I, R_F, R_LEV, R_LEVK, R_K, R_BUF, R_EV_T, R_EV_KIND, R_EV_Y = range(10)
#: Where the points' results go (a tuple): fates, float rows, steps.
OUT_FATE, OUT_F, OUT_N = range(3)


@kernel(inline="always")
def _clip(method, effects, l, W):
    """Clip lane l's next attempt to its T_END as :func:`.rk.rk_run` clips it (LAST set)."""
    ly = lanes_layout(method, effects)
    L = LANES
    h, last = clip_step(W[ly.T * L + l], W[ly.H * L + l], W[ly.T_END * L + l])
    W[ly.H * L + l] = h
    W[ly.LAST * L + l] = 1.0 if last else 0.0


@kernel(inline="always")
def lane_run_from(method, effects, l, y, t_left, atol, p, rtol, max_steps, runs):
    """Start lane l's run from state y with t_left [s] to its horizon and tolerances atol
    (:func:`.lanes.lane_begin`), its first attempt clipped as :func:`.rk.rk_run` clips it; the
    status of the start (OK: the lane runs). Every start and restart of a fate-run lane (here
    and in :mod:`.lanes_hybrid`); ``runs``: the ``R_*`` tuple."""
    ly = lanes_layout(method, effects)
    W = runs[R_W]
    W[ly.T_END * LANES + l] = t_left
    status = lane_begin(method, effects, l, y, atol, p, rtol, max_steps, W, runs[R_I],
                        runs[R_LEV], runs[R_LEVK], runs[R_K], runs[R_BUF], runs[R_EV_T],
                        runs[R_EV_KIND], runs[R_EV_Y])  # fmt: skip
    if status == OK:
        _clip(method, effects, l, W)
    return status


@kernel(inline="always")
def _finish(method, effects, l, fate, t, y, steps, runs, LY0, p, out):
    """Write lane l's point (its fate at state y, t [s] into its run) and idle the lane."""
    ly = lanes_layout(method, effects)
    L = LANES
    W, I, F = runs[R_W], runs[R_I], runs[R_F]
    i = I[l, ORBIT]
    res = fate_result(effects, p, LY0[l], F[l, F_TV], F[l, F_WORK0], fate, t, y, steps)
    store_fate(out[OUT_FATE], out[OUT_F], out[OUT_N], i, res)
    I[l, ORBIT] = -1
    W[ly.ACTIVE * L + l] = 0.0
    W[ly.H * L + l] = 0.0


@kernel(inline="always")
def lane_run_ended(method, effects, l, status, t_run, y, rtol, max_steps, runs, p, at):
    """Lane l's run ended with ``status`` at state y (in place), t_run [s] into the run (p: its
    parameters; ``at``: scratch for its tolerances): what follows (:func:`.fate.next_run`, the
    rule of :func:`.fate.run_restarting`), a restart from rest in the same lane, until a run
    goes on or the lane's orbit ends. Returns (runs again, fate, t [s] since the run's first
    start, steps); an ended lane is idle. Every fate-run lane's (here and in
    :mod:`.lanes_hybrid`)."""
    ly = lanes_layout(method, effects)
    L = LANES
    W, I, F = runs[R_W], runs[R_I], runs[R_F]
    while True:
        steps = np.int64(W[ly.N_ACC * L + l] + W[ly.N_REJ * L + l])
        ended, status, t = next_run(effects, status, y, p, F[l, F_T0] + t_run, I[l, RESTARTS],
                                    steps, max_steps)  # fmt: skip
        if ended:
            W[ly.ACTIVE * L + l] = 0.0
            W[ly.H * L + l] = 0.0
            return False, fate_of_status(status), t, steps
        F[l, F_T0] = t
        I[l, RESTARTS] += 1
        for j in range(ly.n):
            at[j] = W[(ly.ATOL + j) * L + l]
        status = lane_run_from(method, effects, l, y, F[l, F_HORIZON] - t, at, p, rtol, max_steps,
                               runs)  # fmt: skip
        if status == OK:
            return True, ROLLING, t, steps
        t_run = 0.0


@kernel(inline="always")
def lane_fate_run(method, effects, l, y, t_left, steps0, atol, p, rtol, max_steps, runs, at):
    """Begin a fate run (:func:`.fate.fate_run`) in lane l from state y (in place), t_left [s]
    to its horizon, with tolerances atol, after ``steps0`` steps (the budget is max_steps in
    all): a sphere at rest where the resistance holds it or friction cannot ends at once
    (:func:`.fate.starts_at_rest`, as the scalar run), else the lane runs
    (:func:`lane_run_from`; a run that ends at its start is followed by
    :func:`lane_run_ended`). Returns as :func:`lane_run_ended` does (``at``: scratch). Every
    fate-run lane's start (here and in :mod:`.lanes_hybrid`)."""
    ly = lanes_layout(method, effects)
    L = LANES
    W, I, F = runs[R_W], runs[R_I], runs[R_F]
    W[ly.N_ACC * L + l] = steps0
    W[ly.N_REJ * L + l] = 0.0
    W[ly.ACTIVE * L + l] = 0.0
    I[l, RESTARTS] = 0
    F[l, F_T0] = 0.0
    F[l, F_HORIZON] = t_left
    ended, status = starts_at_rest(effects, y, p)
    if ended:
        return False, fate_of_status(status), 0.0, steps0
    status = lane_run_from(method, effects, l, y, t_left - 0.0, atol, p, rtol, max_steps, runs)
    if status == OK:
        return True, ROLLING, 0.0, steps0
    return lane_run_ended(method, effects, l, status, 0.0, y, rtol, max_steps, runs, p, at)


@kernel(inline="always")
def _run_ended(method, effects, l, status, t_run, y, rtol, max_steps, runs, LY0, p, at, out):
    """Lane l's run ended with ``status`` (:func:`lane_run_ended`). Returns True when the lane
    runs again (a restart from rest), False when its point is written into ``out`` (the
    ``OUT_*`` tuple)."""
    again, fate, t, steps = lane_run_ended(method, effects, l, status, t_run, y, rtol, max_steps,
                                           runs, p, at)  # fmt: skip
    if not again:
        _finish(method, effects, l, fate, t, y, steps, runs, LY0, p, out)
    return again


@kernel(inline="always")
def _lane_start(method, effects, l, i, X, params, rtol, t_horizon, max_steps, runs, LY0, p, y,
                out):  # fmt: skip
    """Start point i (``X[:, i]``) in lane l as :func:`.fate.fate_of` starts it. Returns True
    when it runs; False when its point is written (it ended at its start)."""
    ly = lanes_layout(method, effects)
    I, F = runs[R_I], runs[R_F]
    for k in range(N_PARAMS):
        p[k] = params[k]
    set_point(p, X, i, effects)
    I[l, ORBIT] = i
    start, r, y0, t0, work0, atol, orbit = fate_start(effects, p, X, i, rtol)
    if start != RUNS:
        store_fate(out[OUT_FATE], out[OUT_F], out[OUT_N], i, ended_at_start(start, r))
        I[l, ORBIT] = -1
        return False
    for j in range(ly.n):
        LY0[l, j] = y0[j]
        y[j] = y0[j]
    F[l, F_TV] = t0
    F[l, F_WORK0] = work0
    again, fate, t, steps = lane_fate_run(method, effects, l, y, t_horizon - t0, np.int64(0), atol,
                                          p, rtol, max_steps, runs, atol)  # fmt: skip
    if not again:
        _finish(method, effects, l, fate, t, y, steps, runs, LY0, p, out)
    return again


@kernel(inline="always")
def _lane_flagged(method, effects, l, max_steps, W, p, K, K2, ys, yn, y, buf, brent, ev_t,
                  ev_kind, ev_y):  # fmt: skip
    """Finish lane l's attempt the control flagged, as :func:`.rk.rk_run` finishes a step of a
    run that looks for no apsides: FLAG 2, no further attempt allowed; FLAG 1, an accepted
    step with a terminal event (the run stops there, its state the dense output's) or the
    last step to the horizon. Returns (ended, status, t [s] into the run), the state in y."""
    ly = lanes_layout(method, effects)
    n = ly.n
    L = LANES
    t = W[ly.T * L + l]
    if W[ly.FLAG * L + l] != 2.0:
        lane_params(method, effects, l, W, p)
        h = lane_load_step(method, effects, l, W, p, K, ys, yn, buf)
        if terminal_events(effects) and terminal_between(effects, ys, yn, p):
            ok, th_stop, stop_status, g_aps, n_aps, n_ev, i_aps, th_aps = step_events(
                method, effects, ys, yn, K, h, t, p, buf, brent, K2, 1.0, 0, -1, ev_t, ev_kind,
                ev_y, 0, True, False)  # fmt: skip
            if not ok:
                for j in range(n):
                    y[j] = ys[j]
                return True, BUFFER_FULL, t
            if th_stop <= 1.0:
                rk_dense(method, ys, K, h, th_stop, y)
                return True, stop_status, t + th_stop * h
        if W[ly.LAST * L + l] != 0.0:
            for j in range(n):
                y[j] = yn[j]
            return True, OK, W[ly.T_END * L + l]
        status = lane_advance(method, effects, l, max_steps, W)
        if status == OK:
            _clip(method, effects, l, W)
            return False, OK, t
        t = W[ly.T * L + l]
    else:
        n_steps = W[ly.N_ACC * L + l] + W[ly.N_REJ * L + l]
        status = step_allowed(n_steps, max_steps, W[ly.H * L + l], t)
    for j in range(n):
        y[j] = W[(ly.Y + j) * L + l]
    return True, status, t


@kernel
def lanes_fate_worker(method, effects, X, params, rtol, t_horizon, max_steps, queue, out_fate,
                      out_f, out_n):  # fmt: skip
    """Follow points LANES at a time to their fates (:func:`.fate.fate_of`), into out_fate,
    out_f (rows :data:`.fate.FATE_ROWS`) and out_n (steps); a lane whose point has its fate
    takes the next from ``queue`` (int64[1], shared by the workers)."""
    ly = lanes_layout(method, effects)
    L = LANES
    owners, W, LY0, LEV, p, K, K2, V, brent, ev_t, ev_kind, ev_y, F, I, LEVK = lane_workspace(
        method, effects, 5, 4, 4)  # fmt: skip
    ys, yn, y, at, buf = V[0], V[1], V[2], V[3], V[4]
    X, params = borrow(X), borrow(params)
    out = (borrow(out_fate), borrow(out_f), borrow(out_n))
    runs = (W, I, F, LEV, LEVK, K, buf, ev_t, ev_kind, ev_y)  # R_*
    n_points = X.shape[1]
    while True:
        running = 0
        for l in range(L):  # refill idle lanes; points that end at their start are written
            while I[l, ORBIT] < 0:
                i = fetch_add(queue, 1)
                if i >= n_points:
                    break
                _lane_start(method, effects, l, i, X, params, rtol, t_horizon, max_steps, runs,
                            LY0, p, y, out)  # fmt: skip
            running += I[l, ORBIT] >= 0
        if running == 0:
            break
        lanes_attempt(method, effects, W, rtol)
        lanes_control_fate(method, effects, W, max_steps)
        for l in range(L):
            if W[ly.FLAG * L + l] == 0.0:
                continue
            ended, status, t = _lane_flagged(method, effects, l, max_steps, W, p, K, K2, ys, yn,
                                             y, buf, brent, ev_t, ev_kind, ev_y)  # fmt: skip
            if ended:
                lane_params(method, effects, l, W, p)
                _run_ended(method, effects, l, status, t, y, rtol, max_steps, runs, LY0, p, at,
                           out)  # fmt: skip
    # The owners live to here: the borrowed views above hold no reference of their own.
    owners[0][0] = owners[1][0] + owners[2][0]


@parallel_kernel
def fate_points_lanes(X, params, method, effects, rtol, t_horizon, max_steps, n_workers, out_fate,
                      out_f, out_n):  # fmt: skip
    """:func:`.fate.fate_points` for a Runge-Kutta ``method`` (literal, like ``effects``), its
    results bit for bit: ``n_workers`` :func:`lanes_fate_worker` (one per thread) taking points
    from one queue."""
    literally(method)
    literally(effects)
    queue = np.zeros(1, np.int64)
    for _ in prange(max(1, min(n_workers, X.shape[1]))):
        lanes_fate_worker(method, effects, X, params, rtol, t_horizon, max_steps, queue, out_fate,
                          out_f, out_n)  # fmt: skip


@kernel(inline="always")
def lane_flagged_run(method, effects, l, max_steps, W, p, K, K2, ys, yn, y, buf, brent, ev_t,
                     ev_kind, ev_y):  # fmt: skip
    """Finish lane l's flagged attempt of a fate run (:func:`_lane_flagged`, the same
    arguments and results), for other fate-run lanes (:mod:`.lanes_hybrid`)."""
    return _lane_flagged(method, effects, l, max_steps, W, p, K, K2, ys, yn, y, buf, brent, ev_t,
                         ev_kind, ev_y)  # fmt: skip

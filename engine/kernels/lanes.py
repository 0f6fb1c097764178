"""Runge-Kutta orbits in lock-step on the CPU's SIMD lanes: the batch path of the RK methods.

One orbit is a chain of dependent stages: a scalar step waits on the latency of every add,
multiply and division (DOP853: ~400 ns a step, most of it idle). :data:`.lanes_step.LANES`
orbits run side by side instead, each with its own step size, state and tolerances, and every
line of the step is one vector instruction over the lanes (AVX2: 4 doubles): ~60 ns per orbit
and step. :mod:`.lanes_step` generates the vectorised step and step-size control; this module
is the scalar rest, per lane and only where needed:

- the start of an orbit (the model's :func:`.model.period_start`, then
  :func:`.rk.run_begin`, the scalar run's start: as :func:`.orbit.one_period`);
- the events of a step (:func:`.rk_events.step_events` on a scalar copy of the lane: apsides,
  rim, slip) and the result (:func:`.orbit.reduce_period`: half a period for a conservative
  scene, :func:`.orbit.period_apsides`);
- the queue: a lane whose orbit ends takes the next point of its worker's guided piece of a
  queue the threads share (:func:`.lanes_step.piece_starts`): no lane idles until the end.

Results are those of :func:`.orbit.integrate_points` bit for bit, whichever lane or thread
computes a point (tests/kernels/test_lanes.py): this is how the RK methods run in a batch, not
a method of its own. The worker's arrays are borrowed views (:func:`lane_workspace`): the
per-orbit helpers bind about a hundred arrays, each an atomic reference count otherwise."""

from __future__ import annotations

import numpy as np
from numba import literally, prange

from .._jit import kernel, parallel_kernel
from .lanes_step import (
    LANES,
    borrow,
    lanes_attempt,
    lanes_control,
    lanes_layout,
    piece_starts,
    split_owned,
    take_point,
)
from .layouts import Y_U
from .model import N_PARAMS, period_start, set_point
from .orbit import (
    RUN_EVENTS,
    period_apsides,
    reduce_period,
    store_period,
)
from .protocol import (
    BUFFER_FULL,
    NOT_BOUNDED,
    OK,
    RECORD_NONE,
    terminal_between,
    terminal_events,
)
from .rk import ERR_FLOOR, run_begin, step_allowed
from .rk_codegen import rk_dense_stages
from .rk_events import apsis_crossed, apsis_newton, step_events

#: Events a lane can hold: a run's (:data:`.orbit.RUN_EVENTS`).
EV_CAP = RUN_EVENTS
#: Columns of the int array I: the lane's point (-1: idle), its apsides and events so far.
ORBIT, N_APS, N_EV = 0, 1, 2


@kernel(inline="always")
def _lane_start(method, effects, l, i, X, params, rtol, max_steps, W, I, LY0, LEV, LEVK, p, K, buf,
                ev_t, ev_kind, ev_y):  # fmt: skip
    """Start point i (``X[:, i]``) in lane l the way :func:`.orbit.one_period` starts it.
    Returns OK when it runs, else the status it ends with at once (its parameters are then in
    p, its events in ev_*)."""
    ly = lanes_layout(method, effects)
    L = LANES
    for k in range(N_PARAMS):
        p[k] = params[k]
    set_point(p, X, i, effects)
    I[l, ORBIT] = i
    I[l, N_APS] = 0
    I[l, N_EV] = 0
    for s in (ly.T, ly.REJECTED, ly.N_ACC, ly.N_REJ, ly.ACTIVE, ly.POLISH):
        W[s * L + l] = 0.0
    ok, y0, atol, orbit = period_start(effects, p, X, i, rtol)
    if not ok:
        return NOT_BOUNDED
    for j in range(ly.n):
        LY0[l, j] = y0[j]
    return lane_begin(method, effects, l, y0, atol, p, rtol, max_steps, W, I, LEV, LEVK, K, buf,
                      ev_t, ev_kind, ev_y)  # fmt: skip


@kernel(inline="always")
def lane_begin(method, effects, l, y0, atol, p, rtol, max_steps, W, I, LEV, LEVK, K, buf, ev_t,
               ev_kind, ev_y):  # fmt: skip
    """Begin a run of lane l from y0 at t = 0 with :func:`.rk.rk_run`'s start
    (:func:`.rk.run_begin`: the terminal events at the start, the first step): its parameters
    p and tolerances atol into W, its step counts as they are (a fate run's restarts go on
    counting). Returns OK when it runs,
    else the status it ends with at once (its events in ev_* and the lane's events)."""
    ly = lanes_layout(method, effects)
    n = ly.n
    L = LANES
    for k in range(N_PARAMS):
        W[(ly.P + k) * L + l] = p[k]
    for j in range(n):
        W[(ly.ATOL + j) * L + l] = atol[j]
    W[ly.T * L + l] = 0.0
    W[ly.REJECTED * L + l] = 0.0
    W[ly.POLISH * L + l] = 0.0
    status, n_ev, _, h, g_aps = run_begin(method, effects, y0, p, rtol, atol, K, buf, RECORD_NONE,
                                          ev_t, ev_kind, ev_y, ev_t, ev_y)  # fmt: skip
    save_events(l, n_ev, ev_t, ev_kind, ev_y, LEV, LEVK)
    I[l, N_EV] = n_ev
    if status != OK:
        return status
    for j in range(n):
        W[(ly.Y + j) * L + l] = y0[j]
        W[(ly.K + j) * L + l] = K[0, j]
    W[ly.H * L + l] = h
    W[ly.ERR_OLD * L + l] = ERR_FLOOR
    W[ly.G_APS * L + l] = g_aps
    W[ly.ACTIVE * L + l] = 1.0
    return step_allowed(W[ly.N_ACC * L + l] + W[ly.N_REJ * L + l], max_steps, h, 0.0)


@kernel(inline="always")
def save_events(l, n_ev, ev_t, ev_kind, ev_y, LEV, LEVK):
    """Copy the first n_ev events of the scratch buffers into lane l's row of LEV, LEVK."""
    n = ev_y.shape[1]
    for e in range(n_ev):
        LEV[l, e * (n + 1)] = ev_t[e]
        LEVK[l, e] = ev_kind[e]
        for j in range(n):
            LEV[l, e * (n + 1) + 1 + j] = ev_y[e, j]


@kernel(inline="always")
def load_events(l, n_ev, LEV, LEVK, ev_t, ev_kind, ev_y):
    """Copy lane l's first n_ev events into the scratch buffers."""
    n = ev_y.shape[1]
    for e in range(n_ev):
        ev_t[e] = LEV[l, e * (n + 1)]
        ev_kind[e] = LEVK[l, e]
        for j in range(n):
            ev_y[e, j] = LEV[l, e * (n + 1) + 1 + j]


@kernel(inline="always")
def lane_params(method, effects, l, W, p):
    """Lane l's parameter array, into p."""
    oP = lanes_layout(method, effects).P
    for k in range(N_PARAMS):
        p[k] = W[(oP + k) * LANES + l]


@kernel(inline="always")
def _lane_finish(method, effects, l, status, W, I, LY0, p, ev_t, ev_kind, ev_y, out_f, out_n,
                 out_status):  # fmt: skip
    """Write the result of lane l's point (ended with ``status``; its parameters in p, its
    events in ev_*) and idle the lane: one period as :func:`.orbit.one_period` reduces it."""
    ly = lanes_layout(method, effects)
    L = LANES
    i = I[l, ORBIT]
    n_ev = I[l, N_EV]
    y0 = LY0[l]
    n_acc = np.int64(W[ly.N_ACC * L + l])
    res = (status, n_acc, np.int64(W[ly.N_REJ * L + l]), W[ly.T * L + l], y0, n_ev, 0)
    store_period(out_f, out_n, out_status, i, reduce_period(effects, p, y0, res, ev_t, ev_kind,
                                                            ev_y))  # fmt: skip
    I[l, ORBIT] = -1
    W[ly.ACTIVE * L + l] = 0.0
    W[ly.H * L + l] = 0.0


@kernel(inline="always")
def lane_load_step(method, effects, l, W, p, K, ys, yn, buf):
    """Lane l's accepted step on scalar copies (p holds its parameters): y into ys, y_new into
    yn, the stages into K with the dense output's extra stages. Returns the step size."""
    ly = lanes_layout(method, effects)
    n, S, ns = ly.n, ly.S, ly.ns
    L = LANES
    h = W[ly.H * L + l]
    for j in range(n):
        ys[j] = W[(ly.Y + j) * L + l]
        yn[j] = W[(ly.YN + j) * L + l]
    for i in range(ns + 1):
        for j in range(n):
            K[i, j] = W[(ly.K + i * n + j) * L + l]
    if S > ns + 1:
        rk_dense_stages(method, effects, ys, h, p, K, buf)
    return h


@kernel(inline="always")
def _lane_events(method, effects, l, term_cross, W, I, LEV, LEVK, p, K, K2, ys, yn,
                 buf, brent, ev_t, ev_kind, ev_y):  # fmt: skip
    """The events of lane l's accepted step (:func:`.rk_events.step_events` on a scalar copy
    of the lane; p holds its parameters). Returns (stops, status); an apsis found here sets
    the lane up to polish it on its next vector step (:func:`_lane_polished` ends the step)."""
    ly = lanes_layout(method, effects)
    n, ns = ly.n, ly.ns
    L = LANES
    h = lane_load_step(method, effects, l, W, p, K, ys, yn, buf)
    n_ev0 = I[l, N_EV]
    load_events(l, n_ev0, LEV, LEVK, ev_t, ev_kind, ev_y)
    ok, th_stop, stop_status, g_aps, n_aps, n_ev, i_aps, th_aps = step_events(
        method, effects, ys, yn, K, h, W[ly.T * L + l], p, buf, brent, K2,
        W[ly.G_APS * L + l], I[l, N_APS], period_apsides(effects), ev_t, ev_kind, ev_y, n_ev0,
        term_cross, False)  # fmt: skip
    W[ly.G_APS * L + l] = g_aps
    I[l, N_APS] = n_aps
    if not ok:
        I[l, N_EV] = EV_CAP
        save_events(l, EV_CAP, ev_t, ev_kind, ev_y, LEV, LEVK)
        return True, BUFFER_FULL
    I[l, N_EV] = n_ev
    save_events(l, n_ev, ev_t, ev_kind, ev_y, LEV, LEVK)
    stops = th_stop <= 1.0
    if i_aps >= 0:  # polish the apsis on the next vector step: from y, a step of th h
        for j in range(n):
            W[(ly.SAVE_Y + j) * L + l] = yn[j]
            W[(ly.SAVE_K + j) * L + l] = W[(ly.K + ns * n + j) * L + l]
        W[ly.H_STEP * L + l] = h
        W[ly.H * L + l] = th_aps * h
        W[ly.I_APS * L + l] = i_aps
        W[ly.STOP * L + l] = stop_status if stops else -1.0
        W[ly.POLISH * L + l] = 1.0
        return False, OK
    return stops, stop_status


@kernel(inline="always")
def _lane_polished(method, effects, l, max_steps, W, LEV, out, f):
    """After lane l's polishing step: the apsis's state and time as
    :func:`.rk_events.polish_apsis` makes them (into the lane's event I_APS; the dense
    output's stands where the correction is not small), then the lane ends (STOP) or goes on
    from the end of the step the apsis lies in. Returns (stops, status)."""
    ly = lanes_layout(method, effects)
    n, ns = ly.n, ly.ns
    L = LANES
    for j in range(n):
        out[j] = W[(ly.YN + j) * L + l]
        f[j] = W[(ly.K + ns * n + j) * L + l]
    h = W[ly.H_STEP * L + l]
    t = W[ly.T * L + l]
    applied, t_aps = apsis_newton(out, f, h, t + W[ly.H * L + l])
    if applied:
        e = np.int64(W[ly.I_APS * L + l]) * (n + 1)
        LEV[l, e] = t_aps
        for j in range(n):
            LEV[l, e + 1 + j] = out[j]
    W[ly.POLISH * L + l] = 0.0
    stop = W[ly.STOP * L + l]
    if stop >= 0.0:
        return True, np.int64(stop)
    for j in range(n):
        W[(ly.YN + j) * L + l] = W[(ly.SAVE_Y + j) * L + l]
        W[(ly.K + ns * n + j) * L + l] = W[(ly.SAVE_K + j) * L + l]
    W[ly.H * L + l] = h
    status = lane_advance(method, effects, l, max_steps, W)
    return status != OK, status


@kernel(inline="always")
def lane_advance(method, effects, l, max_steps, W):
    """Move lane l to the end of its accepted step (y, f(y), t, the next step size); returns
    the status of the next attempt (:func:`.rk.step_allowed`)."""
    ly = lanes_layout(method, effects)
    n, ns = ly.n, ly.ns
    L = LANES
    W[ly.T * L + l] += W[ly.H * L + l]
    for j in range(n):
        W[(ly.Y + j) * L + l] = W[(ly.YN + j) * L + l]
        W[(ly.K + j) * L + l] = W[(ly.K + ns * n + j) * L + l]
    h = W[ly.H_NEXT * L + l]
    W[ly.H * L + l] = h
    n_steps = W[ly.N_ACC * L + l] + W[ly.N_REJ * L + l]
    return step_allowed(n_steps, max_steps, h, W[ly.T * L + l])


@kernel(inline="always")
def _lane_flagged(method, effects, l, max_steps, W, I, LEV, LEVK, p, K, K2, ys, yn,
                  buf, brent, ev_t, ev_kind, ev_y):  # fmt: skip
    """Finish lane l's attempt the control flagged (:func:`.lanes_step.control_source`):
    FLAG 1, an accepted step with an apsis or a terminal event to look at, then the move to its
    end; FLAG 2, no further attempt allowed. Returns (stops, status)."""
    ly = lanes_layout(method, effects)
    L = LANES
    if W[ly.FLAG * L + l] == 2.0:
        n_steps = W[ly.N_ACC * L + l] + W[ly.N_REJ * L + l]
        return True, step_allowed(n_steps, max_steps, W[ly.H * L + l], W[ly.T * L + l])
    term = False
    if terminal_events(effects):
        lane_params(method, effects, l, W, p)
        for j in range(ly.n):
            ys[j] = W[(ly.Y + j) * L + l]
            yn[j] = W[(ly.YN + j) * L + l]
        term = terminal_between(effects, ys, yn, p)
    if W[ly.FLAG * L + l] == 3.0:
        return _lane_polished(method, effects, l, max_steps, W, LEV, ys, yn)
    if term or apsis_crossed(W[ly.G_APS * L + l], W[(ly.YN + Y_U) * L + l]):
        lane_params(method, effects, l, W, p)
        stops, status = _lane_events(method, effects, l, term, W, I, LEV, LEVK, p, K,
                                     K2, ys, yn, buf, brent, ev_t, ev_kind, ev_y)  # fmt: skip
        if stops or W[ly.POLISH * L + l] != 0.0:
            return stops, status
    status = lane_advance(method, effects, l, max_steps, W)
    return status != OK, status


@kernel(inline="always")
def lane_workspace(method, effects, n_vec, n_int, n_float):
    """A lanes worker's arrays, borrowed views (:func:`.lanes_step.borrow`) of one owner per
    dtype: (owners, to keep alive while the views are used; W; LY0, each lane's start state;
    LEV; p; K; K2; V, n_vec scratch states; brent; ev_t; ev_kind; ev_y; F, n_float floats per
    lane; I, n_int ints per lane (-1); LEVK)."""
    ly = lanes_layout(method, effects)
    n, S = ly.n, ly.S
    L = LANES
    sizes = (ly.n_slots * L, n * L, EV_CAP * (n + 1) * L, N_PARAMS, 2 * S * n, n_vec * n, 8, EV_CAP,
             EV_CAP * n, n_float * L)  # fmt: skip
    own_f = np.zeros(sum(sizes))
    own_i = np.full(n_int * L, -1, np.int64)
    own_k = np.zeros((L + 1) * EV_CAP, np.int8)
    parts = split_owned(own_f, sizes)
    K, LE = parts[4], L * EV_CAP
    return ((own_f, own_i, own_k), parts[0], parts[1].reshape((L, n)),
            parts[2].reshape((L, EV_CAP * (n + 1))), parts[3], K[: S * n].reshape((S, n)),
            K[S * n :].reshape((S, n)), parts[5].reshape((n_vec, n)), parts[6], parts[7],
            borrow(own_k[LE:]), parts[8].reshape((EV_CAP, n)), parts[9].reshape((L, n_float)),
            borrow(own_i.reshape((L, n_int))), borrow(own_k[:LE].reshape((L, EV_CAP))))  # fmt: skip


@kernel
def lanes_worker(method, effects, X, params, rtol, max_steps, queue, starts, out_f, out_n,
                 out_status):  # fmt: skip
    """Integrate points LANES at a time, each over one radial period as
    :func:`.orbit.one_period` does (to r_max and doubled for a conservative scene), into out_f
    (rows of :data:`.orbit.PERIOD_ROWS`), out_n (accepted steps), out_status. A lane whose
    point ends takes the next point of the worker's piece, or a piece of ``starts`` from
    ``queue`` (int64[1], shared: :func:`.lanes_step.take_point`), until none is left."""
    ly, L = lanes_layout(method, effects), LANES
    owners, W, LY0, LEV, p, K, K2, V, brent, ev_t, ev_kind, ev_y, _, I, LEVK = lane_workspace(
        method, effects, 3, 3, 0)  # fmt: skip
    ys, yn, buf, nxt, end = V[0], V[1], V[2], 0, 0
    X = borrow(X)
    params, out_f, out_n, out_status = (borrow(params), borrow(out_f), borrow(out_n),
                                        borrow(out_status))  # fmt: skip
    while True:
        running = 0
        for l in range(L):  # refill idle lanes; points that end at their start are written
            while I[l, ORBIT] < 0:
                i, nxt, end = take_point(queue, starts, nxt, end)
                if i < 0:
                    break
                status = _lane_start(method, effects, l, i, X, params, rtol, max_steps, W, I,
                                     LY0, LEV, LEVK, p, K, buf, ev_t, ev_kind, ev_y)  # fmt: skip
                if status != OK:
                    _lane_finish(method, effects, l, status, W, I, LY0, p, ev_t, ev_kind, ev_y,
                                 out_f, out_n, out_status)  # fmt: skip
            running += I[l, ORBIT] >= 0
        if running == 0:
            break
        lanes_attempt(method, effects, W, rtol)
        lanes_control(method, effects, W, max_steps)
        for l in range(L):
            if W[ly.FLAG * L + l] == 0.0:
                continue
            stops, status = _lane_flagged(method, effects, l, max_steps, W, I, LEV,
                                          LEVK, p, K, K2, ys, yn, buf, brent, ev_t, ev_kind,
                                          ev_y)  # fmt: skip
            if stops:
                lane_params(method, effects, l, W, p)
                load_events(l, I[l, N_EV], LEV, LEVK, ev_t, ev_kind, ev_y)
                _lane_finish(method, effects, l, status, W, I, LY0, p, ev_t, ev_kind, ev_y, out_f,
                             out_n, out_status)  # fmt: skip
    # The owners live to here: the borrowed views above hold no reference of their own.
    owners[0][0] = owners[1][0] + owners[2][0]


@parallel_kernel
def integrate_points_lanes(X, params, method, effects, rtol, max_steps, n_workers, out_f, out_n,
                           out_status):  # fmt: skip
    """:func:`.orbit.integrate_points` for a Runge-Kutta ``method`` (literal, like ``effects``),
    its results bit for bit: ``n_workers`` :func:`lanes_worker` (one per thread:
    ``numba.get_num_threads()``, which a cached kernel cannot call) taking pieces of the
    points from one queue."""
    literally(method)
    literally(effects)
    queue, workers = np.zeros(1, np.int64), max(1, min(n_workers, X.shape[1]))
    starts = piece_starts(X.shape[1], workers)
    for _ in prange(workers):
        lanes_worker(method, effects, X, params, rtol, max_steps, queue, starts, out_f, out_n,
                     out_status)  # fmt: skip

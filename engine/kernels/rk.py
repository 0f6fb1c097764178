"""Adaptive explicit Runge-Kutta integration of a scene, on the run protocol of :mod:`.protocol`.

- :func:`step_error`, :func:`step_decide`, :func:`step_allowed` the PI step-size control
  (:data:`SAFETY`, :data:`MIN_FACTOR`, per-tableau exponents and largest growth) and the step
  budget;
- :func:`initial_step` the starting step of Hairer, Norsett & Wanner I, section II.4;
- :func:`rk_run` the adaptive loop: events (apsides u = 0, the rim, slip onset, located on
  the dense output by :mod:`.rk_events`; apsides polished to the accuracy of a step), optional
  recording of the trajectory, status codes instead of exceptions.

The step itself, the extra dense stages and the tableau constants are generated from the
tableau data for the literal ``method`` id (:mod:`.rk_codegen`); :mod:`.lanes` runs the same
steps on several orbits at once.

Error control: a step is accepted when the RMS over components of err_i / (atol_i + rtol
max(|y_i|, |y_new_i|)) is <= 1 (with a 3rd-order companion estimate: Hairer's stretched
norm). The absolute tolerances come from :func:`.cone_starts.tolerance_scales`. Measured accuracy
(tests/kernels/test_rk.py): period and apsidal angle within 100 rtol kappa relative, kappa =
max(1, (A/r1^2)/|calE|) the amplification of a velocity error at the pericentre into the
radial energy ((1+e)/(1-e) for a free-fall ellipse, ~1 otherwise).

``method`` and ``effects`` must reach these kernels as numba literals (the entry points call
``numba.literally``); everything else (tolerances, parameters, initial state) is a runtime value.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally

from .._jit import kernel
from .branchless import pick, power
from .layouts import ATTITUDE, Y_R, Y_U, state_size
from .model import domain_floor, param_tuple
from .protocol import (
    BUFFER_FULL,
    EPS,
    MAX_STEPS,
    OK,
    RECORD_EVERY_DT,
    RECORD_STEPS,
    STEP_TOO_SMALL,
    copy_into,
    copy_row,
    push_state,
    start_protocol,
    terminal_between,
    terminal_events,
)
from .rates import rhs
from .rk_codegen import controller, rk_attempt, rk_dense_stages, tableau
from .rk_events import apsis_crossed, rk_dense, rk_dense_rate, step_events

# Step-size control.
SAFETY = 0.9
MIN_FACTOR = 0.2
#: Floor of the previous error in the PI controller.
ERR_FLOOR = 1e-4


@kernel(inline="always")
def _root(x, k1, k_rej):
    """x ** -k1 for x <= 1, else x ** -k_rej (x >= 0): three square roots for k1 = k_rej = 1/8
    (DOP853), else :func:`.branchless.power` (arithmetic only: a library pow would keep the
    lanes' loops scalar)."""
    if k1 == 0.125 and k_rej == 0.125:
        return 1.0 / math.sqrt(math.sqrt(math.sqrt(x)))
    return power(x, -pick(x <= 1.0, k1, k_rej))


@kernel(inline="always")
def _shrink(err, root):
    """Step factor after a rejected step with error err (> 1, or not finite); root =
    err ** -k_rej."""
    return pick(math.isfinite(err), max(MIN_FACTOR, SAFETY * root), MIN_FACTOR)


@kernel(inline="always")
def _grow(err, root, err_old, beta, rejected, fmax):
    """PI controller: factor of the next step after an accepted one with error err, root =
    err ** -k1 (at most fmax; never growing right after a rejection)."""
    weight = 1.0 if beta == 0.0 else power(err_old, beta)
    fac = min(fmax, max(MIN_FACTOR, SAFETY * root * weight))
    fac = pick(err == 0.0, fmax, fac)
    return pick(rejected, min(fac, 1.0), fac)


@kernel(inline="always")
def step_error(err, r_new, ctl):
    """(error the controller sees, its root: e ** -k1 if the step is accepted (e <= 1), else
    e ** -k_rej) after an attempt with scaled error err whose new state lies r_new inside the
    model's domain (:func:`.model.domain_floor`); a step that leaves it has an infinite error.
    Pure arithmetic, so the lanes compute it for all lanes at once (:mod:`.lanes`)."""
    k1, k_rej, beta, fmax = ctl
    e = pick(r_new > 0.0, err, math.inf)
    return e, _root(e, k1, k_rej)


@kernel(inline="always")
def step_decide(e, h, err_old, rejected, ctl):
    """The step-size decision after an attempt of size h [s] (``e``: :func:`step_error`,
    ``ctl``: :func:`.rk_codegen.controller`): (accepted, h [s] to retry with or taken, h_next [s],
    err_old, rejected). Both outcomes are computed and one is selected: no branch, so the lanes'
    control is one vector loop."""
    k1, k_rej, beta, fmax = ctl
    err, root = e
    acc = err <= 1.0
    h_retry = h * _shrink(err, root)
    h_next = h * _grow(err, root, err_old, beta, rejected, fmax)
    return (
        acc,
        h if acc else h_retry,
        h_next if acc else h,
        max(err, ERR_FLOOR) if acc else err_old,
        not acc,
    )


@kernel(inline="always")
def step_allowed(n_steps, max_steps, h, t):
    """OK if another attempt of size h [s] at t [s] may be taken after n_steps attempts, else
    MAX_STEPS or STEP_TOO_SMALL (no branch: the lanes' control)."""
    too_small = (not h >= 16.0 * EPS * abs(t)) | (not h > 0.0)
    return pick(n_steps >= max_steps, MAX_STEPS, pick(too_small, STEP_TOO_SMALL, OK))


@kernel(inline="always")
def clip_step(t, h, t_end):
    """(h, last): the attempt of size h [s] from t [s], cut to end at t_end [s] where it would
    reach it (then the run's last step). One rule for :func:`rk_run` and the lanes."""
    last = t + h >= t_end
    return pick(last, t_end - t, h), last


@kernel
def initial_step(method, effects, y0, K, p, rtol, atol, ytmp):
    """Starting step [s] (Hairer, Norsett & Wanner I, II.4, as in scipy's select_initial_step).

    Needs f(y0) in K[0]; uses K[1] as scratch.
    """
    A, C, E, E3, P, ns, S, q, beta, bw, fmax = tableau(method)
    n = y0.shape[0]
    d0 = 0.0
    d1 = 0.0
    for j in range(n):
        sc = atol[j] + rtol * abs(y0[j])
        d0 += (y0[j] / sc) ** 2
        d1 += (K[0, j] / sc) ** 2
    d0 = math.sqrt(d0 / n)
    d1 = math.sqrt(d1 / n)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    for j in range(n):
        ytmp[j] = y0[j] + h0 * K[0, j]
    if not ytmp[Y_R] - domain_floor(p, effects) > 0.0:
        return h0
    rhs(ytmp, p, effects, K, 1)
    d2 = 0.0
    for j in range(n):
        sc = atol[j] + rtol * abs(y0[j])
        d2 += ((K[1, j] - K[0, j]) / sc) ** 2
    d2 = math.sqrt(d2 / n) / h0
    dmax = max(d1, d2)
    if dmax <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / dmax) ** (1.0 / (q + 1))
    return min(100.0 * h0, h1)


@kernel(inline="always")
def run_begin(method, effects, y, p, rtol, atol, K, buf, record, ev_t, ev_kind, ev_y, tr_t, tr_y):
    """The start of a run from y at t = 0, the scalar run's (:func:`rk_run`) and every lane's
    (:func:`.lanes.lane_begin`): f(y) into K[0], the run protocol's start
    (:func:`.protocol.start_protocol`: the terminal events at the start, the first state
    recorded), the first step size (:func:`initial_step`, ``buf`` its scratch) and the apsis
    function's sign (u; at an apsis, u = 0, the sign of du/dt). Returns (status, n_ev, n_tr,
    h, g_aps), h and g_aps 0 where the run ends at its start (status not OK)."""
    rhs(y, p, effects, K, 0)
    status, n_ev, n_tr = start_protocol(effects, y, p, record, ev_t, ev_kind, ev_y, tr_t, tr_y)
    if status != OK:
        return status, n_ev, n_tr, 0.0, 0.0
    g_aps = y[Y_U] if y[Y_U] != 0.0 else K[0, Y_U]
    h = initial_step(method, effects, y, K, p, rtol, atol, buf)
    return status, n_ev, n_tr, h, g_aps


@kernel
def rk_fixed(method, effects, y0, p, h, n_steps):
    """y after ``n_steps`` steps of constant size h [s] (no error control; for order tests)."""
    literally(method)
    literally(effects)
    A, C, E, E3, P, ns, S, q, beta, bw, fmax = tableau(method)
    n = y0.shape[0]
    K = np.empty((S, n))
    y = y0.copy()
    ynew = np.empty(n)
    rhs(y, p, effects, K, 0)
    atol = np.ones(n)
    pt = param_tuple(p)
    for _ in range(n_steps):
        rk_attempt(method, effects, y, h, pt, K, ynew, 1.0, atol)
        for j in range(n):
            y[j] = ynew[j]
        for j in range(n):
            K[0, j] = K[ns, j]
    return y


@kernel
def _samples(method, effects, y, K, h, t, t_lim, t_end, dt_out, next_out, tr_t, tr_y, tr_rate,
             n_tr, buf):  # fmt: skip
    """Record the dense output every ``dt_out`` seconds up to t_lim; returns (n_tr, next_out);
    n_tr < 0 when the trajectory buffers are full."""
    cap_tr = tr_t.shape[0]
    while next_out <= t_lim and next_out < t_end and n_tr < cap_tr:
        th = (next_out - t) / h
        rk_dense(method, y, K, h, th, buf)
        n_tr = push_state(tr_t, tr_y, n_tr, next_out, buf)
        if effects & ATTITUDE:
            rk_dense_rate(method, K, th, buf)
            copy_row(buf, tr_rate, n_tr - 1)
        next_out = n_tr * dt_out
    if n_tr == cap_tr:
        return -1, next_out
    return n_tr, next_out


@kernel
def _stop_state(method, effects, y, K, h, t, th_stop, at_apsis, p, ev_t, ev_y, n_ev, out,
                rate):  # fmt: skip
    """The state (into ``out``, and its rate with the attitude) and time [s] where a run stops
    inside the step (t, t + h]: its last apsis as recorded (polished) when it stops there, else
    the dense output at the terminal event (the horizon included)."""
    n = y.shape[0]
    if at_apsis:
        for j in range(n):
            out[j] = ev_y[n_ev - 1, j]
        if effects & ATTITUDE:
            rhs(out, p, effects, K, 0)
            for j in range(n):
                rate[j] = K[0, j]
        return ev_t[n_ev - 1]
    rk_dense(method, y, K, h, th_stop, out)
    if effects & ATTITUDE:
        rk_dense_rate(method, K, th_stop, rate)
    return t + th_stop * h


@kernel
def rk_run(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps, record,
           dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
    """Integrate from t = 0 until t_end [s], the ``n_apsides``-th apsis (if > 0; apsides are
    not even looked for if < 0), a terminal event or a failure (the run protocol,
    :mod:`.protocol`).

    Events go to the preallocated ``ev_t`` [s], ``ev_kind`` (int8), ``ev_y`` (state). ``record``:
    RECORD_NONE, RECORD_STEPS (every accepted step) or RECORD_EVERY_DT (every ``dt_out``
    seconds on the dense output), into ``tr_t``, ``tr_y`` and, with the attitude, ``tr_rate``
    (dy/dt); the first and last states are recorded in both modes. A full buffer stops the run
    with status BUFFER_FULL (the caller retries with more room). ``orbit`` (calE, h, L_z) is
    not needed by this method. Returns (status, n_accepted, n_rejected, t, y, n_ev, n_tr).
    """
    A, C, E, E3, P, ns, S, q, beta, bw, fmax = tableau(method)
    n = state_size(effects)
    n_rate = n if effects & ATTITUDE else 0
    work = np.empty(2 * S * n + 3 * n + n_rate + 8)  # one allocation for all work arrays
    K = work[: S * n].reshape((S, n))
    K2 = work[S * n : 2 * S * n].reshape((S, n))  # stages of the step that polishes an apsis
    w = work[2 * S * n :]
    y = w[:n]
    ynew = w[n : 2 * n]
    buf = w[2 * n : 3 * n]  # scratch: extra stages, dense output, first step
    rate = w[3 * n : 3 * n + n_rate]
    st = w[3 * n + n_rate :]
    copy_into(y0, y)
    ctl = controller(method)
    t = 0.0
    status, n_ev, n_tr, h, g_aps = run_begin(method, effects, y, p, rtol, atol, K, buf, record,
                                             ev_t, ev_kind, ev_y, tr_t, tr_y)  # fmt: skip
    if effects & ATTITUDE and n_tr > 0:
        for j in range(n):
            tr_rate[0, j] = K[0, j]
    if status != OK:
        return status, 0, 0, t, y, n_ev, n_tr
    n_acc = 0
    n_rej = 0
    n_aps = 0
    next_out = dt_out
    pt = param_tuple(p)
    err_old = ERR_FLOOR
    rejected = False
    while True:
        status = step_allowed(n_acc + n_rej, max_steps, h, t)
        if status != OK:
            break
        h, last = clip_step(t, h, t_end)
        err = rk_attempt(method, effects, y, h, pt, K, ynew, rtol, atol)
        e = step_error(err, ynew[Y_R] - domain_floor(pt, effects), ctl)
        accepted, h, h_next, err_old, rejected = step_decide(e, h, err_old, rejected, ctl)
        if not accepted:
            n_rej += 1
            continue
        n_acc += 1
        aps_cross = n_apsides >= 0 and apsis_crossed(g_aps, ynew[Y_U])
        term_cross = False
        if terminal_events(effects):
            term_cross = terminal_between(effects, y, ynew, p)
        sample = record == RECORD_EVERY_DT and next_out <= t + h and next_out < t_end
        if S > ns + 1 and (aps_cross or term_cross or sample):
            rk_dense_stages(method, effects, y, h, p, K, buf)
        th_stop = 2.0
        stop_status = OK
        at_apsis = False
        if aps_cross or term_cross:  # a call only when needed: its array arguments cost refcounts
            ok, th_stop, stop_status, g_aps, n_aps, n_ev, i_aps, th_aps = step_events(
                method, effects, y, ynew, K, h, t, p, buf, st, K2, g_aps, n_aps, n_apsides,
                ev_t, ev_kind, ev_y, n_ev, term_cross, True)  # fmt: skip
            if not ok:
                n_ev = ev_t.shape[0]
                status = BUFFER_FULL
                break
            at_apsis = i_aps >= 0 and th_stop == th_aps and stop_status == OK
        stopping = th_stop <= 1.0 or last
        if sample:
            t_lim = t + min(th_stop, 1.0) * h
            n_tr, next_out = _samples(method, effects, y, K, h, t, t_lim, t_end, dt_out,
                                      next_out, tr_t, tr_y, tr_rate, n_tr, buf)  # fmt: skip
            if n_tr < 0:
                n_tr = tr_t.shape[0]
                status = BUFFER_FULL
                break
        if th_stop <= 1.0:
            t = _stop_state(method, effects, y, K, h, t, th_stop, at_apsis, p, ev_t, ev_y,
                            n_ev, ynew, rate)  # fmt: skip
        else:
            t = t_end if last else t + h
            if effects & ATTITUDE:
                for j in range(n):
                    rate[j] = K[ns, j]
        for j in range(n):
            y[j] = ynew[j]
        for j in range(n):
            K[0, j] = K[ns, j]
        if record == RECORD_STEPS or (record == RECORD_EVERY_DT and stopping):
            n_tr = push_state(tr_t, tr_y, n_tr, t, y)
            if n_tr < 0:
                n_tr = tr_t.shape[0]
                status = BUFFER_FULL
                break
            if effects & ATTITUDE:
                copy_row(rate, tr_rate, n_tr - 1)
        if stopping:
            status = stop_status
            break
        h = h_next
    return status, n_acc, n_rej, t, y, n_ev, n_tr

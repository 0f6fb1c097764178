"""Adaptive explicit Runge-Kutta integration of a scene, on the run protocol of :mod:`.protocol`.

- :func:`rk_dense` / :func:`rk_dense_rate` the continuous extension of a step and its derivative
  (the polynomial weights ``P`` of the tableau);
- :func:`initial_step` the starting step of Hairer, Norsett & Wanner I, section II.4;
- :func:`rk_locate` event location on the dense output by Brent's method (xtol 4 eps);
- :func:`rk_run` the adaptive loop: PI step-size control (:data:`SAFETY`, :data:`MIN_FACTOR`,
  :data:`MAX_FACTOR`, per-tableau exponents), events (apsides u = 0, the rim, slip onset),
  optional recording of the trajectory, status codes instead of exceptions.

The step itself, the extra dense stages and the tableau constants are generated from the
tableau data for the literal ``method`` id (:mod:`.rk_codegen`).

Error control: a step is accepted when the RMS over components of err_i / (atol_i + rtol
max(|y_i|, |y_new_i|)) is <= 1 (with a 3rd-order companion estimate: Hairer's stretched
norm). The absolute tolerances come from :func:`.orbit.tolerance_scales`. Measured accuracy
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
from .model import ATTITUDE, P_RIM, param_tuple, rhs, state_size
from .protocol import (
    BUFFER_FULL,
    EPS,
    FIRST_TERMINAL,
    LAST_TERMINAL,
    MAX_STEPS,
    OK,
    PERICENTRE,
    RECORD_EVERY_DT,
    RECORD_STEPS,
    SPILL,
    STEP_TOO_SMALL,
    TERMINAL_EFFECTS,
    brent_next,
    brent_start,
    brent_update,
    copy_into,
    copy_row,
    event_value,
    kind_enabled,
    push_event,
    push_state,
    record_apsis,
    start_protocol,
    status_of,
    terminal_between,
    terminal_crossed,
)
from .rk_codegen import rk_attempt, rk_dense_component, rk_dense_stages, tableau

# Step-size control.
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
#: Floor of the previous error in the PI controller.
ERR_FLOOR = 1e-4


@kernel
def _shrink(err, k_rej):
    """Step factor after a rejected step with error err (> 1, or not finite)."""
    if math.isnan(err) or math.isinf(err):
        return MIN_FACTOR
    return max(MIN_FACTOR, SAFETY * err ** (-k_rej))


@kernel
def _grow(err, err_old, k1, beta, rejected):
    """PI controller: factor of the next step after an accepted one (never growing right after
    a rejection)."""
    if err == 0.0:
        fac = MAX_FACTOR
    else:
        fac = min(MAX_FACTOR, max(MIN_FACTOR, SAFETY * err ** (-k1) * err_old**beta))
    if rejected:
        fac = min(fac, 1.0)
    return fac


@kernel
def rk_dense(method, y, K, h, theta, out):
    """Dense output y(t + theta h), theta in [0, 1], into ``out``."""
    A, C, E, E3, P, ns, S, q, beta, bw = tableau(method)
    n = y.shape[0]
    deg = P.shape[1]
    for j in range(n):
        out[j] = y[j]
    for i in range(S):
        wi = 0.0
        for m in range(deg - 1, -1, -1):
            wi = (wi + P[i, m]) * theta
        if wi != 0.0:
            wi *= h
            for j in range(n):
                out[j] += wi * K[i, j]


@kernel
def rk_dense_rate(method, K, theta, out):
    """Time derivative [per s] of the dense output at theta, into ``out``."""
    A, C, E, E3, P, ns, S, q, beta, bw = tableau(method)
    n = K.shape[1]
    deg = P.shape[1]
    for j in range(n):
        out[j] = 0.0
    for i in range(S):
        wi = 0.0
        for m in range(deg - 1, -1, -1):
            wi = wi * theta + (m + 1) * P[i, m]
        if wi != 0.0:
            for j in range(n):
                out[j] += wi * K[i, j]


@kernel
def initial_step(method, effects, y0, K, p, rtol, atol, ytmp):
    """Starting step [s] (Hairer, Norsett & Wanner I, II.4, as in scipy's select_initial_step).

    Needs f(y0) in K[0]; uses K[1] as scratch.
    """
    A, C, E, E3, P, ns, S, q, beta, bw = tableau(method)
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
    if not ytmp[0] > 0.0:
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


@kernel
def rk_fixed(method, effects, y0, p, h, n_steps):
    """y after ``n_steps`` steps of constant size h [s] (no error control; for order tests)."""
    literally(method)
    literally(effects)
    A, C, E, E3, P, ns, S, q, beta, bw = tableau(method)
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
def rk_locate(method, effects, kind, y, K, h, p, g0, g1, buf, st):
    """theta in [0, 1] where the event function crosses 0 on the step's dense output (Brent,
    xtol 4 eps)."""
    brent_start(st, 0.0, 1.0, g0, g1)
    theta = 1.0
    for _ in range(100):
        done, theta = brent_next(st, 4.0 * EPS)
        if done:
            break
        if kind == SPILL:
            g = rk_dense_component(method, y, K, h, theta, 0) - p[P_RIM]
        elif kind == PERICENTRE:
            g = rk_dense_component(method, y, K, h, theta, 2)
        else:
            rk_dense(method, y, K, h, theta, buf)
            g = event_value(kind, buf, p, effects)
        brent_update(st, g)
    return min(max(theta, 0.0), 1.0)


@kernel
def _step_events(method, effects, y, ynew, K, h, t, p, buf, st, g_aps, n_aps, n_apsides,
                 ev_t, ev_kind, ev_y, n_ev, term_cross):  # fmt: skip
    """Events inside the accepted step (t, t + h]: the first terminal event, then the apsis
    before it (recorded; it may end the run after ``n_apsides`` apsides), then the terminal
    event itself. Returns (ok, theta of the stop (2 = none), stop status, g_aps, n_aps, n_ev);
    ok is False when the event buffers are full."""
    th_stop = 2.0
    stop_status = OK
    stop_kind = 0
    if term_cross:
        for kind in range(FIRST_TERMINAL, LAST_TERMINAL + 1):
            if not kind_enabled(effects, kind):
                continue
            g1 = event_value(kind, ynew, p, effects)
            g0 = event_value(kind, y, p, effects)
            if terminal_crossed(kind, g0, g1):
                th = rk_locate(method, effects, kind, y, K, h, p, g0, g1, buf, st)
                if th < th_stop:
                    th_stop = th
                    stop_kind = kind
                    stop_status = status_of(kind)
    g_new = ynew[2]
    if n_apsides >= 0 and ((g_aps > 0.0 and g_new <= 0.0) or (g_aps < 0.0 and g_new >= 0.0)):
        th = rk_locate(method, effects, np.int64(PERICENTRE), y, K, h, p, y[2], g_new, buf,
                       st)  # fmt: skip
        if th <= th_stop:
            rk_dense(method, y, K, h, th, buf)
            n_ev, g_aps, n_aps, reached = record_apsis(ev_t, ev_kind, ev_y, n_ev, t + th * h,
                                                       buf, g_aps, n_aps, n_apsides)  # fmt: skip
            if n_ev < 0:
                return False, th_stop, stop_status, g_aps, n_aps, n_ev
            if reached:
                th_stop = th
                stop_status = OK
    if th_stop <= 1.0 and stop_status != OK:
        rk_dense(method, y, K, h, th_stop, buf)
        n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, t + th_stop * h, stop_kind, buf)
        if n_ev < 0:
            return False, th_stop, stop_status, g_aps, n_aps, n_ev
    return True, th_stop, stop_status, g_aps, n_aps, n_ev


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
    A, C, E, E3, P, ns, S, q, beta, bw = tableau(method)
    n = state_size(effects)
    n_rate = n if effects & ATTITUDE else 0
    work = np.empty(S * n + 3 * n + n_rate + 8)  # one allocation for all work arrays
    K = work[: S * n].reshape((S, n))
    y = work[S * n : S * n + n]
    ynew = work[S * n + n : S * n + 2 * n]
    buf = work[S * n + 2 * n : S * n + 3 * n]  # scratch: extra stages, dense output, first step
    rate = work[S * n + 3 * n : S * n + 3 * n + n_rate]
    st = work[S * n + 3 * n + n_rate :]
    copy_into(y0, y)
    k1 = 1.0 / (q + 1) - bw * beta
    k_rej = 1.0 / (q + 1)
    t = 0.0
    rhs(y, p, effects, K, 0)
    status, n_ev, n_tr = start_protocol(effects, y, p, record, ev_t, ev_kind, ev_y, tr_t, tr_y)
    if effects & ATTITUDE and n_tr > 0:
        for j in range(n):
            tr_rate[0, j] = K[0, j]
    if status != OK:
        return status, 0, 0, t, y, n_ev, n_tr
    n_acc = 0
    n_rej = 0
    n_aps = 0
    next_out = dt_out
    # Sign of the apsis function: at an apsis (u = 0) use the sign of udot.
    g_aps = y[2] if y[2] != 0.0 else K[0, 2]
    h = initial_step(method, effects, y, K, p, rtol, atol, buf)
    pt = param_tuple(p)
    err_old = ERR_FLOOR
    rejected = False
    while True:
        if n_acc + n_rej >= max_steps:
            status = MAX_STEPS
            break
        if not h >= 16.0 * EPS * abs(t) or not h > 0.0:
            status = STEP_TOO_SMALL
            break
        last = False
        if t + h >= t_end:
            h = t_end - t
            last = True
        err = rk_attempt(method, effects, y, h, pt, K, ynew, rtol, atol)
        if not ynew[0] > 0.0:
            err = math.inf
        if not err <= 1.0:
            n_rej += 1
            h *= _shrink(err, k_rej)
            rejected = True
            continue
        n_acc += 1
        h_next = h * _grow(err, err_old, k1, beta, rejected)
        rejected = False
        err_old = max(err, ERR_FLOOR)

        g_new = ynew[2]
        aps_cross = n_apsides >= 0 and (
            (g_aps > 0.0 and g_new <= 0.0) or (g_aps < 0.0 and g_new >= 0.0)
        )
        term_cross = False
        if effects & TERMINAL_EFFECTS:
            term_cross = terminal_between(effects, y, ynew, p)
        sample = record == RECORD_EVERY_DT and next_out <= t + h and next_out < t_end
        if S > ns + 1 and (aps_cross or term_cross or sample):
            rk_dense_stages(method, effects, y, h, p, K, buf)
        th_stop = 2.0
        stop_status = OK
        if aps_cross or term_cross:  # a call only when needed: its array arguments cost refcounts
            ok, th_stop, stop_status, g_aps, n_aps, n_ev = _step_events(
                method, effects, y, ynew, K, h, t, p, buf, st, g_aps, n_aps, n_apsides,
                ev_t, ev_kind, ev_y, n_ev, term_cross)  # fmt: skip
            if not ok:
                n_ev = ev_t.shape[0]
                status = BUFFER_FULL
                break
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
            # Stop inside the step, on the dense output.
            rk_dense(method, y, K, h, th_stop, ynew)
            if effects & ATTITUDE:
                rk_dense_rate(method, K, th_stop, rate)
            t = t + th_stop * h
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

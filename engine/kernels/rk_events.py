"""Events of the adaptive Runge-Kutta run kernel (:mod:`.rk`) on a step's continuous extension.

- :func:`rk_dense` / :func:`rk_dense_rate` the dense output of a step and its derivative (the
  polynomial weights ``P`` of the tableau);
- :func:`rk_locate` event location on the dense output by Brent's method (xtol 4 eps);
- :func:`polish_apsis` an apsis to the accuracy of a step (:func:`apsis_newton`): the
  interpolant's error dominates on long steps (DOP853 at rtol 1e-10: up to 3.6e-10 in the
  apsidal angle, 5e-11 once polished);
- :func:`step_events` the events inside an accepted step, in order.

``method`` and ``effects`` reach these kernels as numba literals.
"""

from __future__ import annotations

import numpy as np

from .._jit import kernel
from .layouts import P_RIM, Y_U
from .protocol import (
    EPS,
    FIRST_TERMINAL,
    LAST_TERMINAL,
    OK,
    PERICENTRE,
    SPILL,
    brent_next,
    brent_start,
    brent_update,
    event_value,
    events_full,
    kind_enabled,
    push_event,
    record_apsis,
    status_of,
    terminal_crossed,
)
from .rk_codegen import rk_dense_poly, rk_stages, tableau


@kernel
def apsis_crossed(g_aps, g_new):
    """True where the apsis function u changed sign from g_aps (its sign before the step) to
    g_new (0 counts as crossed)."""
    return (g_aps > 0.0 and g_new <= 0.0) or (g_aps < 0.0 and g_new >= 0.0)


@kernel
def rk_dense(method, y, K, h, theta, out):
    """Dense output y(t + theta h), theta in [0, 1], into ``out``."""
    A, C, E, E3, P, ns, S, q, beta, bw, fmax = tableau(method)
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
    A, C, E, E3, P, ns, S, q, beta, bw, fmax = tableau(method)
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
def dense_poly_value(yj, h, c, theta):
    """yj + h sum_m c[m] theta^(m+1) (Horner's rule): one component of a step's dense output
    from its polynomial (:func:`.rk_codegen.rk_dense_poly`)."""
    acc = 0.0
    for m in range(len(c) - 1, -1, -1):
        acc = (acc + c[m]) * theta
    return yj + h * acc


@kernel
def rk_locate(method, effects, kind, y, K, h, p, g0, g1, buf, st):
    """theta in [0, 1] where the event function crosses 0 on the step's dense output (Brent,
    xtol 4 eps). The rim (r) and the apsides (u) need one component: its polynomial is summed
    over the stages once, then each evaluation is one Horner pass."""
    one = kind == SPILL or kind == PERICENTRE
    j = 0 if kind == SPILL else 2
    c = rk_dense_poly(method, K, j)
    brent_start(st, 0.0, 1.0, g0, g1)
    theta = 1.0
    for _ in range(100):
        done, theta = brent_next(st, 4.0 * EPS)
        if done:
            break
        if one:
            g = dense_poly_value(y[j], h, c, theta)
            if kind == SPILL:
                g -= p[P_RIM]
        else:
            rk_dense(method, y, K, h, theta, buf)
            g = event_value(kind, buf, p, effects)
        brent_update(st, g)
    return min(max(theta, 0.0), 1.0)


@kernel
def apsis_newton(out, f, h, t_hs):
    """One Newton correction of the time of an apsis whose state ``out`` at time t_hs [s] has
    the rates f: dt = -u/udot, out += dt f. Returns (applied, time [s]); not applied where
    |dt| > |h| (h [s] the step it lies in) or dt is not finite."""
    dt = -out[Y_U] / f[2]
    if not abs(dt) <= abs(h):
        return False, t_hs
    for j in range(out.shape[0]):
        out[j] += dt * f[j]
    return True, t_hs + dt


@kernel
def polish_apsis(method, effects, y, K, h, th, t, p, K2, out):
    """State (into ``out``) and time [s] of the apsis found at theta = th on the dense output of
    the step (t, t + h], to the accuracy of a step rather than of the interpolant (whose error
    dominates on long steps): one step of size th h from y (stages in K2), then
    :func:`apsis_newton`. Where the correction is not small the dense output stands."""
    A, C, E, E3, P, ns, S, q, beta, bw, fmax = tableau(method)
    n = y.shape[0]
    hs = th * h
    for j in range(n):
        K2[0, j] = K[0, j]
    rk_stages(method, effects, y, hs, p, K2, out)
    applied, t_aps = apsis_newton(out, K2[ns], h, t + hs)
    if not applied:
        rk_dense(method, y, K, h, th, out)
    return t_aps


@kernel
def step_events(method, effects, y, ynew, K, h, t, p, buf, st, K2, g_aps, n_aps, n_apsides,
                ev_t, ev_kind, ev_y, n_ev, term_cross, polish):  # fmt: skip
    """Events inside the accepted step (t, t + h]: the first terminal event, then the apsis
    before it (recorded; it may end the run after ``n_apsides`` apsides), then the terminal
    event itself. With ``polish`` the apsis is polished here (:func:`polish_apsis`, K2 as
    scratch); without, it is recorded from the dense output for the caller to polish (the
    lanes do it on a vector step). Returns (ok, theta of the stop (2 = none), stop status,
    g_aps, n_aps, n_ev, index of the apsis recorded (-1: none), its theta); ok is False when
    the event buffers are full. A run that stops at its last apsis (theta <= 1, status OK)
    ends on the recorded event."""
    th_stop = 2.0
    stop_status = OK
    stop_kind = 0
    i_aps = -1
    th_aps = 2.0
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
    g_new = ynew[Y_U]
    if n_apsides >= 0 and apsis_crossed(g_aps, g_new):
        th = rk_locate(method, effects, np.int64(PERICENTRE), y, K, h, p, y[Y_U], g_new, buf,
                       st)  # fmt: skip
        if th <= th_stop:
            if polish:
                t_aps = polish_apsis(method, effects, y, K, h, th, t, p, K2, buf)
            else:
                rk_dense(method, y, K, h, th, buf)
                t_aps = t + th * h
            i_aps = n_ev
            th_aps = th
            n_ev, g_aps, n_aps, reached = record_apsis(ev_t, ev_kind, ev_y, n_ev, t_aps, buf,
                                                       g_aps, n_aps, n_apsides)  # fmt: skip
            if events_full(n_ev, ev_t):
                return False, th_stop, stop_status, g_aps, n_aps, n_ev, i_aps, th_aps
            if reached:
                th_stop = th
                stop_status = OK
    if th_stop <= 1.0 and stop_status != OK:
        rk_dense(method, y, K, h, th_stop, buf)
        n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, t + th_stop * h, stop_kind, buf)
        if events_full(n_ev, ev_t):
            return False, th_stop, stop_status, g_aps, n_aps, n_ev, i_aps, th_aps
    return True, th_stop, stop_status, g_aps, n_aps, n_ev, i_aps, th_aps

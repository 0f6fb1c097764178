"""Runge-Kutta orbits in lock-step on the CPU's SIMD lanes: the batch path of the RK methods.

One orbit is a chain of dependent stages: a scalar step waits on the latency of every add,
multiply and division (DOP853: ~400 ns a step, most of it idle). :data:`LANES` orbits run
side by side instead, each with its own step size, state and tolerances, so each line of the
step is one vector instruction over the lanes (AVX2: 4 doubles): ~60 ns per orbit and step.

- :func:`lanes_attempt` one step of every lane, generated from the tableau by the same
  generator as the scalar step (:func:`.rk_codegen.unrolled_step_lines`): the very same
  arithmetic, so every lane reproduces the scalar run kernel bit for bit;
- the control (accept or reject, the next step, events, the end of an orbit) is scalar per
  lane and calls the run kernel's own helpers (:func:`.rk.step_decide`,
  :func:`.rk_events.step_events`, ...); a lane whose orbit ends takes the next point from a
  queue the threads share, so no lane idles until the points run out;
- :func:`integrate_points_lanes` the parallel batch: one worker per thread on that queue (a
  thread slowed by other work takes fewer points).

Results are those of :func:`.orbit.integrate_points` (tests/kernels/test_lanes.py checks
equality bit for bit), so this is an implementation of the batch, not a method of its own.
All state lives in one flat work array ``W`` (slot s of lane l at ``s * LANES + l``) so the
compiler sees constant offsets from one base and vectorises the loop over the lanes.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import literally, prange
from numba.core import cgutils, types
from numba.extending import intrinsic, overload

from .._jit import kernel, parallel_kernel
from .model import (
    ATTITUDE,
    N_ATTITUDE,
    N_BASE,
    N_PARAMS,
    RIM,
    SLIP_CHECK,
    rates5,
    rates9,
    rhs,
    set_alpha,
)
from .orbit import _reduce, initial_state, orbit_start, tolerance_scales
from .protocol import (
    APOCENTRE,
    BUFFER_FULL,
    NOT_BOUNDED,
    OK,
    RECORD_NONE,
    start_protocol,
    terminal_at,
)
from .rk import ERR_FLOOR, initial_step, step_allowed, step_decide, step_error
from .rk_codegen import (
    _GEN_OPTS,
    _literal,
    _rk_method,
    controller,
    rk_dense_stages,
    unrolled_step_lines,
)
from .rk_events import apsis_crossed, step_events
from .tableaux import RK_TABLEAUX

#: Orbits integrated side by side (4 doubles: one AVX2 register; wider gains nothing measured).
LANES = 4
#: Events a lane can hold (one period: two apsides and a terminal event).
EV_CAP = 4
# Per-lane scalars: float columns of F, int columns of I.
_T, _H_NEXT, _ERR_OLD, _G_APS = 0, 1, 2, 3
_ORBIT, _N_ACC, _N_REJ, _N_APS, _N_EV, _REJECTED = 0, 1, 2, 3, 4, 5


def layout(method: int, n: int) -> tuple[int, ...]:
    """Slots of the work array: (n, S, ns, Y, K, YN, ATOL, H, ERR, P, n_slots); K holds the
    main stages and f(y_new), row i of component j at slot K + i n + j; ERR the two values of
    :func:`.rk.step_error`."""
    tb = RK_TABLEAUX[method]
    ns = tb.n_stages
    oK = n
    oYN = oK + (ns + 1) * n
    oAT = oYN + n
    oH = oAT + n
    oERR = oH + 1
    oP = oERR + 2
    return (n, tb.A.shape[0], ns, 0, oK, oYN, oAT, oH, oERR, oP, oP + N_PARAMS)


def attempt_source(method: int, n: int) -> str:
    """Source of ``impl(method, effects, W, rtol)``: one step of every lane (the lane's
    h, y, f(y), tolerances and parameters from ``W``; its stages, y_new and
    :func:`.rk.step_error` into ``W``)."""
    _, _, ns, oY, oK, oYN, oAT, oH, oERR, oP, _ = layout(method, n)
    L = LANES
    slot = {"y": oY, "k0": oK, "atol": oAT}

    def load(kind, j):
        return f"W[{(slot[kind] + j) * L} + l]"

    def store(i, j, value):
        s = oYN + j if i == "y" else oK + i * n + j
        return f"W[{s * L} + l] = {value}"

    pt = ", ".join(f"W[{(oP + k) * L} + l]" for k in range(N_PARAMS))
    lines = ["def impl(method, effects, W, rtol):", f"    for l in range({L}):"]
    lines += [f"        pt = ({pt})", f"        h = W[{oH * L} + l]"]
    lines += unrolled_step_lines(method, n, load, store, "        ")
    lines.append(f"        W[{oERR * L} + l] = err")
    # The controller's roots in a loop of their own (a pow, where the tableau needs one, is a
    # library call: it would keep the step's loop from being vectorised).
    lines += [f"    for l in range({L}):"]
    ctl = repr(RK_TABLEAUX[method].controller())  # constants: the roots fold to sqrt or pow
    lines += [f"        e = step_error(W[{oERR * L} + l], W[{oYN * L} + l], {ctl})"]
    lines += [f"        W[{(oERR + c) * L} + l] = e[{c}]" for c in range(2)]
    return "\n".join(lines) + "\n"


@functools.cache
def _attempt_impl(method: int, n: int):
    namespace = {"math": math, "rates5": rates5, "rates9": rates9, "step_error": step_error}
    src = attempt_source(method, n)
    exec(compile(src, f"<conesurvey lanes method={method} n={n}>", "exec"), namespace)  # noqa: S102
    return namespace["impl"]


def _n_of(effects) -> int:
    return N_ATTITUDE if _literal(effects, "effects") & ATTITUDE else N_BASE


def lanes_attempt(method, effects, W, rtol):
    """One step of every lane and its controller's values (:func:`attempt_source`). Jit-only."""
    raise NotImplementedError("lanes_attempt runs inside numba kernels only")


def lanes_layout(method, effects):
    """:func:`layout` of the literal method and effect set, as constants. Jit-only."""
    raise NotImplementedError("lanes_layout runs inside numba kernels only")


@overload(lanes_attempt, jit_options=_GEN_OPTS)
def _ol_lanes_attempt(method, effects, W, rtol):
    return _attempt_impl(_rk_method(method), _n_of(effects))


@overload(lanes_layout, jit_options=_GEN_OPTS)
def _ol_lanes_layout(method, effects):
    consts = layout(_rk_method(method), _n_of(effects))

    def impl(method, effects):
        return consts

    return impl


# ---------------------------------------------------------------------------- borrowed arrays
@intrinsic
def _borrow(typingctx, arr):
    """A view of ``arr`` without a reference-count handle (meminfo NULL), so binding it to a
    parameter costs no atomic update (each one ~20 cycles; a lane's orbit binds about a hundred).
    The caller keeps an owner alive for as long as the view is used."""
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, sig, args):
        src = context.make_array(arr)(context, builder, value=args[0])
        dst = context.make_array(arr)(context, builder)
        dst.meminfo = cgutils.get_null_value(dst.meminfo.type)
        dst.parent = cgutils.get_null_value(dst.parent.type)
        for field in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(dst, field, getattr(src, field))
        return dst._getvalue()

    return arr(arr), codegen


@intrinsic
def _fetch_add(typingctx, counter, value):
    """counter[0] += value atomically; returns the old value (the workers' shared queue)."""
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(counter)(context, builder, value=args[0])
        val = context.cast(builder, args[1], sig.args[1], types.int64)
        return builder.atomic_rmw("add", ary.data, val, "monotonic")

    return types.int64(counter, value), codegen


@kernel
def _split(own, sizes):
    """Borrowed consecutive pieces of ``own`` of the given sizes."""
    out = []
    start = 0
    for size in sizes:
        out.append(_borrow(own[start : start + size]))
        start += size
    return out


# ---------------------------------------------------------------------------- the lane driver
# The lanes' own arrays live in the worker's frame and reach the helpers one by one: every array
# a call binds costs two atomic reference-count updates, so the per-orbit helpers are inlined
# and the events of a lane are handled on shared scratch copies (no views, no tuples).


@kernel(inline="always")
def _lane_start(method, effects, l, i, alpha, energy, hh, Lz, params, rtol, max_steps, W, F,
                I, LY0, LEV, LEVK, p, K, buf, ev_t, ev_kind, ev_y):  # fmt: skip
    """Start orbit i in lane l the way :func:`.orbit.one_period` and :func:`.rk.rk_run` start
    it. Returns OK when it runs, else the status it ends with at once (its start state and
    events are then in p, LY0[l] and ev_*)."""
    n, S, ns, oY, oK, oYN, oAT, oH, oERR, oP, n_slots = lanes_layout(method, effects)
    L = LANES
    for k in range(N_PARAMS):
        p[k] = params[k]
    set_alpha(p, alpha[i])
    I[l, _ORBIT] = i
    for c in range(1, 6):
        I[l, c] = 0
    ok, r1, r2, rc = orbit_start(p, energy[i], hh[i], Lz[i])
    if not ok:
        return NOT_BOUNDED
    y0 = initial_state(p, effects, r1, energy[i], hh[i], Lz[i])
    y0[2] = 0.0
    atol = tolerance_scales(p, effects, y0, energy[i], hh[i], Lz[i], r1, r2, rc)
    atol *= rtol
    for j in range(n):
        LY0[l, j] = y0[j]
    rhs(y0, p, effects, K, 0)
    status, n_ev, n_tr = start_protocol(effects, y0, p, RECORD_NONE, ev_t, ev_kind, ev_y, ev_t,
                                        ev_y)  # fmt: skip
    _save_events(l, n_ev, ev_t, ev_kind, ev_y, LEV, LEVK)
    I[l, _N_EV] = n_ev
    if status != OK:
        return status
    F[l, _T] = 0.0
    F[l, _ERR_OLD] = ERR_FLOOR
    F[l, _G_APS] = y0[2] if y0[2] != 0.0 else K[0, 2]
    h = initial_step(method, effects, y0, K, p, rtol, atol, buf)
    for j in range(n):
        W[(oY + j) * L + l] = y0[j]
        W[(oK + j) * L + l] = K[0, j]
        W[(oAT + j) * L + l] = atol[j]
    for k in range(N_PARAMS):
        W[(oP + k) * L + l] = p[k]
    W[oH * L + l] = h
    return step_allowed(0, max_steps, h, 0.0)


@kernel(inline="always")
def _save_events(l, n_ev, ev_t, ev_kind, ev_y, LEV, LEVK):
    """Copy the first n_ev events of the scratch buffers into lane l's row of LEV, LEVK."""
    n = ev_y.shape[1]
    for e in range(n_ev):
        LEV[l, e * (n + 1)] = ev_t[e]
        LEVK[l, e] = ev_kind[e]
        for j in range(n):
            LEV[l, e * (n + 1) + 1 + j] = ev_y[e, j]


@kernel(inline="always")
def _load_events(l, n_ev, LEV, LEVK, ev_t, ev_kind, ev_y):
    """Copy lane l's first n_ev events into the scratch buffers."""
    n = ev_y.shape[1]
    for e in range(n_ev):
        ev_t[e] = LEV[l, e * (n + 1)]
        ev_kind[e] = LEVK[l, e]
        for j in range(n):
            ev_y[e, j] = LEV[l, e * (n + 1) + 1 + j]


@kernel(inline="always")
def _lane_params(method, effects, l, W, p):
    """Lane l's parameter array, into p."""
    n, S, ns, oY, oK, oYN, oAT, oH, oERR, oP, n_slots = lanes_layout(method, effects)
    for k in range(N_PARAMS):
        p[k] = W[(oP + k) * LANES + l]


@kernel(inline="always")
def _lane_finish(effects, l, status, n_apsides, F, I, LY0, p, ev_t, ev_kind, ev_y, out_f,
                 out_n, out_status):  # fmt: skip
    """Write the result of lane l's orbit (ended with ``status``; its parameters in p, its
    events in ev_*): one period as :func:`.orbit.one_period` reduces it, or with
    ``n_apsides`` = 1 half a period (period = twice the time to r_max, by the time symmetry of
    a conservative orbit; no drift)."""
    i = I[l, _ORBIT]
    n_ev = I[l, _N_EV]
    y0 = LY0[l]
    res = (status, I[l, _N_ACC], I[l, _N_REJ], F[l, _T], y0, n_ev, 0)
    st, T, psi, prec, nst, drift, loss = _reduce(effects, p, y0, res, ev_t, ev_kind, ev_y)
    if n_apsides == 1:
        nan = math.nan
        st, T, psi, prec, drift, loss = status, nan, nan, nan, nan, nan
        if status == OK and (n_ev < 1 or ev_kind[0] != APOCENTRE):
            st = NOT_BOUNDED
        elif status == OK:
            T = 2.0 * ev_t[0]
            psi = abs(ev_y[0, 1])
            prec = (2.0 * psi - 2.0 * math.pi) / T
    out_status[i] = st
    out_f[0, i] = T
    out_f[1, i] = psi
    out_f[2, i] = prec
    out_f[3, i] = drift
    out_f[4, i] = loss
    out_n[i] = nst


@kernel(inline="always")
def _lane_events(method, effects, l, n_apsides, term_cross, W, F, I, LEV, LEVK, p, K, K2, ys,
                 yn, buf, brent, ev_t, ev_kind, ev_y):  # fmt: skip
    """The events of lane l's accepted step (:func:`.rk_events.step_events` on a scalar copy
    of the lane; p must hold its parameters). Returns (stops, status)."""
    n, S, ns, oY, oK, oYN, oAT, oH, oERR, oP, n_slots = lanes_layout(method, effects)
    L = LANES
    h = W[oH * L + l]
    for j in range(n):
        ys[j] = W[(oY + j) * L + l]
        yn[j] = W[(oYN + j) * L + l]
    for i in range(ns + 1):
        for j in range(n):
            K[i, j] = W[(oK + i * n + j) * L + l]
    if S > ns + 1:
        rk_dense_stages(method, effects, ys, h, p, K, buf)
    n_ev0 = I[l, _N_EV]
    _load_events(l, n_ev0, LEV, LEVK, ev_t, ev_kind, ev_y)
    ok, th_stop, stop_status, g_aps, n_aps, n_ev = step_events(
        method, effects, ys, yn, K, h, F[l, _T], p, buf, brent, K2, F[l, _G_APS],
        I[l, _N_APS], n_apsides, ev_t, ev_kind, ev_y, n_ev0, term_cross)  # fmt: skip
    F[l, _G_APS] = g_aps
    I[l, _N_APS] = n_aps
    if not ok:
        I[l, _N_EV] = EV_CAP
        return True, BUFFER_FULL
    I[l, _N_EV] = n_ev
    _save_events(l, n_ev, ev_t, ev_kind, ev_y, LEV, LEVK)
    if th_stop <= 1.0:
        return True, stop_status
    return False, OK


@kernel(inline="always")
def _lane_control(method, effects, l, ctl, max_steps, W, F, I):
    """Accept or reject lane l's attempt (:func:`.rk.step_decide`). Returns (accepted,
    stops, status, apsis crossed, h_next); a rejected attempt is set up for its retry."""
    n, S, ns, oY, oK, oYN, oAT, oH, oERR, oP, n_slots = lanes_layout(method, effects)
    L = LANES
    h = W[oH * L + l]
    e = (W[oERR * L + l], W[(oERR + 1) * L + l])
    accepted, h, h_next, err_old, rejected = step_decide(
        e, h, F[l, _ERR_OLD], I[l, _REJECTED] != 0, ctl
    )
    F[l, _ERR_OLD] = err_old
    I[l, _REJECTED] = rejected
    if not accepted:
        I[l, _N_REJ] += 1
        W[oH * L + l] = h
        status = step_allowed(I[l, _N_ACC] + I[l, _N_REJ], max_steps, h, F[l, _T])
        return False, status != OK, status, False, h_next
    I[l, _N_ACC] += 1
    aps = apsis_crossed(F[l, _G_APS], W[(oYN + 2) * L + l])
    return True, False, OK, aps, h_next


@kernel(inline="always")
def _lane_advance(method, effects, l, h_next, max_steps, W, F, I):
    """Move lane l to the end of its accepted step (y, f(y), t, the next step); returns the
    status of the next attempt (:func:`.rk.step_allowed`)."""
    n, S, ns, oY, oK, oYN, oAT, oH, oERR, oP, n_slots = lanes_layout(method, effects)
    L = LANES
    F[l, _T] += W[oH * L + l]
    for j in range(n):
        W[(oY + j) * L + l] = W[(oYN + j) * L + l]
        W[(oK + j) * L + l] = W[(oK + ns * n + j) * L + l]
    W[oH * L + l] = h_next
    return step_allowed(I[l, _N_ACC] + I[l, _N_REJ], max_steps, h_next, F[l, _T])


@kernel
def lanes_worker(method, effects, alpha, energy, hh, Lz, params, rtol, max_steps, n_apsides,
                 queue, out_f, out_n, out_status):  # fmt: skip
    """Integrate orbits LANES at a time, each until its ``n_apsides``-th apsis (2: one period;
    1: half), into out_f (rows of :data:`.orbit.PERIOD_ROWS`), out_n (accepted steps),
    out_status. A lane whose orbit ends takes the next one from ``queue`` (int64[1], the next
    point's index, shared by the workers) until every point is taken."""
    n, S, ns, oY, oK, oYN, oAT, oH, oERR, oP, n_slots = lanes_layout(method, effects)
    L = LANES
    ctl = controller(method)
    # One owner per dtype; the worker uses borrowed views of them (no reference counts).
    sizes = (n_slots * L, 4 * L, n * L, EV_CAP * (n + 1) * L, N_PARAMS, 2 * S * n, 3 * n, 8,
             EV_CAP, EV_CAP * n)  # fmt: skip
    own_f = np.zeros(sum(sizes))
    own_i = np.full(6 * L, -1, np.int64)
    own_k = np.zeros((L + 1) * EV_CAP, np.int8)
    parts = _split(own_f, sizes)
    W = parts[0]
    F = parts[1].reshape((L, 4))
    LY0 = parts[2].reshape((L, n))
    LEV = parts[3].reshape((L, EV_CAP * (n + 1)))
    p = parts[4]
    K = parts[5][: S * n].reshape((S, n))
    K2 = parts[5][S * n :].reshape((S, n))
    ys = parts[6][:n]
    yn = parts[6][n : 2 * n]
    buf = parts[6][2 * n :]
    brent = parts[7]
    ev_t = parts[8]
    ev_y = parts[9].reshape((EV_CAP, n))
    I = _borrow(own_i.reshape((L, 6)))  # noqa: E741
    LEVK = _borrow(own_k[: L * EV_CAP].reshape((L, EV_CAP)))
    ev_kind = _borrow(own_k[L * EV_CAP :])
    alpha, energy, hh, Lz = _borrow(alpha), _borrow(energy), _borrow(hh), _borrow(Lz)
    params, out_f, out_n = _borrow(params), _borrow(out_f), _borrow(out_n)
    out_status = _borrow(out_status)
    n_points = alpha.shape[0]
    while True:
        running = 0
        for l in range(L):  # refill the free lanes; orbits that end at their start are written
            while I[l, _ORBIT] < 0:
                i = _fetch_add(queue, 1)
                if i >= n_points:
                    break
                status = _lane_start(method, effects, l, i, alpha, energy, hh, Lz, params, rtol,
                                     max_steps, W, F, I, LY0, LEV, LEVK, p, K, buf, ev_t,
                                     ev_kind, ev_y)  # fmt: skip
                if status != OK:
                    _lane_finish(effects, l, status, n_apsides, F, I, LY0, p, ev_t, ev_kind,
                                 ev_y, out_f, out_n, out_status)  # fmt: skip
                    I[l, _ORBIT] = -1
                    W[oH * L + l] = 0.0
            running += I[l, _ORBIT] >= 0
        if running == 0:
            break
        lanes_attempt(method, effects, W, rtol)
        for l in range(L):
            if I[l, _ORBIT] < 0:
                continue
            accepted, stops, status, aps, h_next = _lane_control(
                method, effects, l, ctl, max_steps, W, F, I
            )
            if accepted:
                term = False
                if effects & (RIM | SLIP_CHECK):
                    _lane_params(method, effects, l, W, p)
                    for j in range(n):
                        yn[j] = W[(oYN + j) * L + l]
                    term = terminal_at(effects, yn, p) >= 0
                if aps or term:
                    _lane_params(method, effects, l, W, p)
                    stops, status = _lane_events(method, effects, l, n_apsides, term, W, F, I,
                                                 LEV, LEVK, p, K, K2, ys, yn, buf, brent, ev_t,
                                                 ev_kind, ev_y)  # fmt: skip
                if not stops:
                    status = _lane_advance(method, effects, l, h_next, max_steps, W, F, I)
                    stops = status != OK
            if stops:
                _lane_params(method, effects, l, W, p)
                _load_events(l, I[l, _N_EV], LEV, LEVK, ev_t, ev_kind, ev_y)
                _lane_finish(effects, l, status, n_apsides, F, I, LY0, p, ev_t, ev_kind, ev_y,
                             out_f, out_n, out_status)  # fmt: skip
                I[l, _ORBIT] = -1
                W[oH * L + l] = 0.0
    # The owners live to here: the borrowed views above hold no reference of their own.
    own_f[0] = own_i[0] + own_k[0]


@parallel_kernel
def integrate_points_lanes(alpha, energy, h, Lz, params, method, effects, rtol, max_steps,
                           n_apsides, n_workers, out_f, out_n, out_status):  # fmt: skip
    """:func:`.orbit.integrate_points` for a Runge-Kutta ``method`` (literal, like ``effects``):
    ``n_workers`` :func:`lanes_worker` (one per thread: ``numba.get_num_threads()``, which
    cannot be called in a cached kernel) taking points from one queue, so a thread slowed by
    other work takes fewer; ``n_apsides`` 2 gives its results bit for bit, 1 half a period.
    Each point's result is the same whichever lane or thread computes it."""
    literally(method)
    literally(effects)
    queue = np.zeros(1, np.int64)
    for _ in prange(max(1, min(n_workers, alpha.shape[0]))):
        lanes_worker(method, effects, alpha, energy, h, Lz, params, rtol, max_steps, n_apsides,
                     queue, out_f, out_n, out_status)  # fmt: skip

"""Hybrid fate maps on the SIMD lanes: :func:`.hybrid.hybrid_fate_points` for the Runge-Kutta
methods, its results bit for bit.

Each lane follows one launch's story the way :func:`.hybrid.hybrid_fate_of` does, with the
same pieces (:mod:`.story_parts`: its start, the switches and what follows each stretch, its
result) and the same loop (:func:`.hybrid.story_until_rolling`). What a lane does between them
depends on the stretch:

- a rolling stretch without spin friction is a fate run (:func:`.fate.fate_run`), so it runs
  on the vector step of the fate lanes (:mod:`.lanes_fate`): begun as
  :func:`.fate.run_restarting` begins a run (a start at rest, :func:`.lanes.lane_begin`), its
  steps taken LANES at a time with those of the other lanes, its end (the slip is one of the
  terminal events) and restarts from rest in scalar code, by the one restart rule
  (:func:`.lanes_fate.lane_run_ended`); its step count goes on from the story's, so the step
  budget is the scalar's;
- a stretch on the hybrid steps (sliding; rolling with spin friction) runs in scalar code in
  its lane, to its end (:func:`.story_parts.hybrid_stretch`), while the other lanes wait.

A lane whose story has ended takes the next launch from the queue the threads share
(tests/kernels/test_lanes_hybrid.py checks every output against the scalar kernel's).

Where the time goes (``scripts/bench_slide.py``'s 400 launches, rk45, rtol 1e-9, 5 s; counted
in the scalar kernel): without spin friction about half of it is in the rolling stretches (266k
steps of ~1,000 cycles) and half in sliding (79k hybrid steps of ~3,000 to 3,700 cycles: the
step's stages 57 %, its event search 25 %, the kink and step rules 12 %); the lanes take the
first half about 3.5 times faster, so the map runs ~1.5 times faster per core. With spin
friction every stretch is on the hybrid steps (96 % of the time: 281k steps rolling with the
spin couple), which stay scalar per lane: on the lanes such a map ran no faster than one
launch per thread (0.87 to 1.01 times its throughput), so :mod:`engine.hybrid` runs it there.
The hybrid step is the next to vectorise: its right-hand side branches on the mode, the slip
and the spin (:func:`.sliding.hybrid_rhs`), so a vector step needs it written with selects and
the lanes grouped by mode; its event search (:func:`.hybrid_step.first_event`) and step rules
would stay per lane.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, prange

from .._jit import kernel, parallel_kernel
from .cone import set_alpha
from .hybrid import story_until_rolling
from .lanes import ORBIT, lane_params, lane_workspace
from .lanes_fate import (
    OUT_F,
    OUT_FATE,
    OUT_N,
    R_F,
    R_I,
    R_W,
    lane_fate_run,
    lane_flagged_run,
    lane_run_ended,
)
from .lanes_step import LANES, borrow, fetch_add, lanes_attempt, lanes_control_fate, lanes_layout
from .model import N_PARAMS
from .rk_codegen import tableau
from .sliding import N_HYBRID, N_HYBRID_PARAMS
from .story_parts import (
    HI_STEPS,
    HS_T,
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
    rolled,
    story_begin,
    story_result,
)

#: Columns of a lane's floats: those of a fate-run lane (:mod:`.lanes_fate`: the time its
#: rolling stretch's run started at, ``F_T0``, and the stretch's horizon from its start,
#: ``F_HORIZON``), then the story's steps before the stretch. Its ints: a fate-run lane's (the
#: stretch's restarts from rest, ``RESTARTS``).
F_STEPS0 = 4
N_FLOATS = F_STEPS0 + 1


#: The lanes' stories travel as one tuple (numba's own type, as :mod:`.lanes_fate`'s runs), with
#: these places: a lane's story state (one row per lane: its parameters, rolling start and
#: tolerances, hybrid parameters, state and tolerances, the story's floats and ints) and what a
#: story writes on the way (its result row; event buffers of size 0: a map keeps no events).
(ST_LP, ST_LY0, ST_LAT, ST_LHP, ST_LYH, ST_LHAT, ST_LHS, ST_LHI, ST_ROW, ST_HEV_T, ST_HEV_KIND,
 ST_HEV_Y) = range(12)  # fmt: skip
#: The scratch arrays of the lanes' scalar code, one tuple: tolerances at, the hybrid steps'
#: stages HK and states hw, a rolling stretch's start yr and its tolerances ra.
SC_AT, SC_HK, SC_HW, SC_YR, SC_RA = range(5)


@kernel
def _store(out, i, fate, row, steps):
    out[OUT_FATE][i] = fate
    for j in range(row.shape[0]):
        out[OUT_F][j, i] = row[j]
    out[OUT_N][i] = steps


@kernel
def _stretch_over(effects, l, fate, t, steps, yv, st, runs):
    """Lane l's rolling stretch is over: it ended with ``fate`` at state yv, t [s] after its
    start, the story's steps counted to ``steps`` (:func:`.story_parts.rolled` takes it)."""
    rolled(effects, fate, t, yv, steps - np.int64(runs[R_F][l, F_STEPS0]), st[ST_LYH][l],
           st[ST_LHS][l], st[ST_LHI][l], st[ST_HEV_T], st[ST_HEV_KIND], st[ST_HEV_Y])  # fmt: skip


@kernel
def _stretch_ended(method, effects, l, status, t_run, yv, rtol, max_steps, st, runs, at):
    """Lane l's run of a rolling stretch ended with ``status`` at state yv, t_run [s] into the
    run: what follows, as in every fate-run lane (:func:`.lanes_fate.lane_run_ended`; ``st``:
    the lanes' stories, the ``ST_*`` tuple; ``runs``: their runs, :mod:`.lanes_fate`'s ``R_*``
    tuple; ``at``: scratch). Returns True when the lane runs again (a restart from rest), False
    when the stretch is over (:func:`_stretch_over`)."""
    again, fate, t, steps = lane_run_ended(method, effects, l, status, t_run, yv, rtol, max_steps,
                                           runs, st[ST_LP][l], at)  # fmt: skip
    if not again:
        _stretch_over(effects, l, fate, t, steps, yv, st, runs)
    return again


@kernel
def _lane_story(method, effects, model, spin, l, rtol, t_horizon, max_steps, st, runs, sc, out):
    """Go on with lane l's story in scalar code (:func:`.hybrid.hybrid_fate_of`'s loop) until a
    rolling stretch runs on the lanes (returns True) or the story ends (its point written into
    ``out``, :mod:`.lanes_fate`'s ``OUT_*`` tuple; the lane idle: False). ``sc``: the
    ``SC_*`` scratch tuple."""
    W, I, F = runs[R_W], runs[R_I], runs[R_F]
    ly = lanes_layout(method, effects)
    L = LANES
    p = st[ST_LP][l]
    y = st[ST_LYH][l]
    hs = st[ST_LHS][l]
    hi = st[ST_LHI][l]
    yr, ra = sc[SC_YR], sc[SC_RA]
    hw = (sc[SC_HK], sc[SC_HW][0], sc[SC_HW][1], sc[SC_HW][2])
    events = (st[ST_HEV_T], st[ST_HEV_KIND], st[ST_HEV_Y])
    while True:
        rolls, _ = story_until_rolling(method, effects, model, spin, p, y, st[ST_LY0][l],
                                       st[ST_LAT][l], st[ST_LHP][l], st[ST_LHAT][l], rtol,
                                       t_horizon, max_steps, hw, (yr, ra), hs, hi,
                                       events)  # as the scalar kernel  # fmt: skip
        if not rolls:
            break
        F[l, F_STEPS0] = hi[HI_STEPS]  # the budget is the story's
        again, f, t, steps = lane_fate_run(method, effects, l, yr, t_horizon - hs[HS_T],
                                           hi[HI_STEPS], ra, p, rtol, max_steps, runs,
                                           sc[SC_AT])  # fmt: skip
        if again:
            return True
        _stretch_over(effects, l, f, t, steps, yr, st, runs)
    fate = story_result(effects, model, spin, p, y, st[ST_LY0][l], st[ST_LHP][l], hs, hi,
                        st[ST_ROW])  # fmt: skip
    _store(out, I[l, ORBIT], fate, st[ST_ROW], hi[HI_STEPS])
    I[l, ORBIT] = -1
    W[ly.ACTIVE * L + l] = 0.0
    W[ly.H * L + l] = 0.0
    return False


@kernel
def _lane_start(effects, model, spin, l, i, launch, params, mu_k, c_spin, rtol, st, I, out):
    """Begin launch i's story (``launch``: the ``L_*`` tuple of :mod:`.story_parts`) in lane l
    (:func:`.story_parts.story_begin`). Returns True when it goes on; False when its point is
    written (it ended at its start)."""
    p = st[ST_LP][l]
    for k in range(N_PARAMS):
        p[k] = params[k]
    set_alpha(p, launch[L_ALPHA][i])
    row = st[ST_ROW]
    for j in range(row.shape[0]):
        row[j] = math.nan
    start = (launch[L_ENERGY][i], launch[L_H][i], launch[L_LZ][i], launch[L_R_START][i],
             launch[L_U0][i], launch[L_SLIP_U][i], launch[L_SLIP_V][i])  # fmt: skip
    fate = story_begin(effects, model, spin, p, mu_k, c_spin, start, rtol, row, st[ST_LY0][l],
                       st[ST_LAT][l], st[ST_LHP][l], st[ST_LYH][l], st[ST_LHAT][l],
                       st[ST_LHS][l], st[ST_LHI][l])  # fmt: skip
    if fate >= 0:
        _store(out, i, fate, row, 0)
        return False
    I[l, ORBIT] = i
    return True


@kernel
def lanes_hybrid_worker(method, effects, model, spin, launch, params, mu_k, c_spin, rtol, t_horizon,
                        max_steps, queue, out):  # fmt: skip
    """Follow launches (the ``L_*`` tuple of :mod:`.story_parts`) LANES at a time through their
    stories (:func:`.hybrid.hybrid_fate_of`), into ``out`` (the ``OUT_*`` tuple of
    :mod:`.lanes_fate`: fates, the rows of :data:`.story_parts.HYBRID_ROWS`, steps); a lane
    whose story has ended takes the next launch from ``queue`` (int64[1], shared by the
    workers)."""
    ly = lanes_layout(method, effects)
    L = LANES
    n = ly.n
    owners, W, LY0, LEV, pw, K, K2, V, brent, ev_t, ev_kind, ev_y, F, I, LEVK = lane_workspace(
        method, effects, 7, 4, N_FLOATS)  # fmt: skip
    ys, yn, yv, at, buf, yr, ra = V[0], V[1], V[2], V[3], V[4], V[5], V[6]
    st = (np.zeros((L, N_PARAMS)), LY0, np.zeros((L, n)), np.zeros((L, N_HYBRID_PARAMS)),
          np.zeros((L, N_HYBRID)), np.zeros((L, N_HYBRID)), np.zeros((L, N_HS)),
          np.zeros((L, N_HI), np.int64), np.empty(len(HYBRID_ROWS)), np.empty(0),
          np.empty(0, np.int8), np.empty((0, N_HYBRID)))  # ST_*  # fmt: skip
    runs = (W, I, F, LEV, LEVK, K, buf, ev_t, ev_kind, ev_y)  # lanes_fate's R_*
    sc = (at, np.empty((tableau(method)[6], N_HYBRID)), np.empty((3, N_HYBRID)), yr, ra)  # SC_*
    launch = (borrow(launch[L_ALPHA]), borrow(launch[L_ENERGY]), borrow(launch[L_H]),
              borrow(launch[L_LZ]), borrow(launch[L_R_START]), borrow(launch[L_U0]),
              borrow(launch[L_SLIP_U]), borrow(launch[L_SLIP_V]))  # L_*  # fmt: skip
    params = borrow(params)
    out = (borrow(out[OUT_FATE]), borrow(out[OUT_F]), borrow(out[OUT_N]))
    n_points = launch[L_ALPHA].shape[0]
    while True:
        running = 0
        for l in range(L):  # refill idle lanes; stories that end in scalar code are written
            while I[l, ORBIT] < 0:
                i = fetch_add(queue, 1)
                if i >= n_points:
                    break
                if _lane_start(effects, model, spin, l, i, launch, params, mu_k, c_spin, rtol, st,
                               I, out):  # fmt: skip
                    _lane_story(method, effects, model, spin, l, rtol, t_horizon, max_steps, st,
                                runs, sc, out)  # fmt: skip
            running += I[l, ORBIT] >= 0
        if running == 0:
            break
        lanes_attempt(method, effects, W, rtol)
        lanes_control_fate(method, effects, W, max_steps)
        for l in range(L):
            if W[ly.FLAG * L + l] == 0.0:
                continue
            ended, status, t = lane_flagged_run(method, effects, l, max_steps, W, pw, K, K2, ys,
                                                yn, yv, buf, brent, ev_t, ev_kind,
                                                ev_y)  # fmt: skip
            if not ended:
                continue
            lane_params(method, effects, l, W, pw)
            if _stretch_ended(method, effects, l, status, t, yv, rtol, max_steps, st, runs, at):
                continue
            _lane_story(method, effects, model, spin, l, rtol, t_horizon, max_steps, st, runs, sc,
                        out)  # fmt: skip
    # The owners live to here: the borrowed views above hold no reference of their own.
    owners[0][0] = owners[1][0] + owners[2][0]


@parallel_kernel
def hybrid_fate_points_lanes(launch, params, mu_k, c_spin, method, effects, model, spin, rtol,
                             t_horizon, max_steps, n_workers, out_fate, out_f, out_n):  # fmt: skip
    """:func:`.hybrid.hybrid_fate_points` for a Runge-Kutta ``method`` (literal, like
    ``effects`` and ``spin``), its results bit for bit: ``n_workers``
    :func:`lanes_hybrid_worker` (one per thread) taking launches from one queue."""
    literally(method)
    literally(effects)
    literally(model)
    literally(spin)
    queue = np.zeros(1, np.int64)
    out = (out_fate, out_f, out_n)  # OUT_*
    for _ in prange(max(1, min(n_workers, launch[L_ALPHA].shape[0]))):
        lanes_hybrid_worker(method, effects, model, spin, launch, params, mu_k, c_spin, rtol,
                            t_horizon, max_steps, queue, out)  # fmt: skip

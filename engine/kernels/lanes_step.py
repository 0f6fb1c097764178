"""The vectorised parts of the lanes batch (:mod:`.lanes`): one Runge-Kutta step and its
step-size control for :data:`LANES` orbits at once, generated for a literal method id.

All lane state lives in one flat work array ``W``: slot s of lane l at ``W[s * LANES + l]``
(:func:`layout`). The generated loops over the lanes address it with constant offsets from one
base, so the compiler proves the lanes independent and turns each line into one vector
instruction (AVX2: 4 doubles). A call into a library (a ``pow``) or a branch that cannot be
turned into a select would make a loop scalar again: the choices are selects and the
controller's powers arithmetic (:mod:`.branchless`; tests/kernels/test_lanes.py checks the
step's divisions are vector instructions and the control has no branch and no pow).

- :func:`lanes_attempt` one step of every lane: the same generator as the scalar step
  (:func:`.rk_codegen.unrolled_step_lines`), so the same arithmetic to the last bit; then the
  error and root the controller needs (:func:`.rk.step_error`);
- :func:`lanes_control` the decision of every lane (:func:`.rk.step_decide`): an accepted step
  without an event moves the lane on here; a lane with an apsis or a terminal event to look
  at, or out of steps, is flagged for the scalar code of :mod:`.lanes`.

Plus two intrinsics: :func:`borrow` (an array view without reference counting) and
:func:`fetch_add` (the threads' shared queue), and the guided pieces of points the workers take
from it (:func:`piece_starts`, :func:`take_point`).
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np
from numba.core import cgutils, types
from numba.extending import intrinsic, overload

from .._jit import kernel
from .branchless import keep, pick
from .layouts import Y_U, state_size_of
from .model import MODEL_ROWS, N_PARAMS, model_of_key
from .protocol import OK, terminal_between, terminal_events
from .rates import rates5, rates6, rates9, rates10
from .rk import clip_step, step_allowed, step_decide, step_error
from .rk_codegen import GEN_OPTS, literal_int, rk_method_id, unrolled_step_lines
from .rk_events import apsis_crossed
from .tableaux import RK_TABLEAUX

#: Orbits integrated side by side (4 doubles: one AVX2 register; wider gained nothing measured).
LANES = 4
#: Per-lane scalars, in this order after the parameters. FLAG: 0 nothing to do, 1 an accepted
#: step to finish in scalar code (events), 2 out of steps or step size, 3 a polishing step
#: taken (POLISH: the lane's attempt was the step to an apsis at theta h, :mod:`.lanes`; the
#: step it lies in was H_STEP, event I_APS, then STOP: the status to end with, or -1).
#: A fate run (:mod:`.lanes_fate`) also has T_END, the time its step is clipped to (a horizon),
#: and LAST, set where the step about to be taken was clipped to it (the run's last).
LANE_SCALARS = ("T", "ERR_OLD", "G_APS", "REJECTED", "N_ACC", "N_REJ", "ACTIVE", "FLAG", "H_NEXT",
                "POLISH", "H_STEP", "I_APS", "STOP", "T_END", "LAST")  # fmt: skip


class Layout(NamedTuple):
    """Slot numbers of the work array (times LANES: the offset of lane 0). The kernels read
    them by name (``ly.YN``): :func:`lanes_layout` gives them the layout as a constant."""

    n: int  # state components
    S: int  # all stages of the tableau
    ns: int  # main stages (K[ns] = f(y_new))
    Y: int
    K: int  # K[i, j] at K + i n + j, i = 0..ns
    YN: int
    ATOL: int
    H: int
    ERR: int  # the error the controller sees, and its root
    P: int  # the parameter array
    T: int
    ERR_OLD: int
    G_APS: int
    REJECTED: int
    N_ACC: int
    N_REJ: int
    ACTIVE: int
    FLAG: int
    H_NEXT: int
    POLISH: int
    H_STEP: int
    I_APS: int
    STOP: int
    T_END: int
    LAST: int
    SAVE_Y: int  # y_new and f(y_new) of a step whose apsis is being polished
    SAVE_K: int
    n_slots: int


def layout(method: int, n: int) -> Layout:
    """The work array's slots for the pair ``method`` on n components."""
    tb = RK_TABLEAUX[method]
    ns = tb.n_stages
    K = n
    YN = K + (ns + 1) * n
    ATOL = YN + n
    H = ATOL + n
    ERR = H + 1
    P = ERR + 2
    lane = {name: P + N_PARAMS + k for k, name in enumerate(LANE_SCALARS)}
    SAVE_Y = P + N_PARAMS + len(LANE_SCALARS)
    return Layout(n, tb.A.shape[0], ns, 0, K, YN, ATOL, H, ERR, P, **lane, SAVE_Y=SAVE_Y,
                  SAVE_K=SAVE_Y + n, n_slots=SAVE_Y + 2 * n)  # fmt: skip


def _w(slot: int, j: int = 0) -> str:
    return f"W[{(slot + j) * LANES} + l]"


def attempt_source(method: int, n: int, floor: int | None = None) -> str:
    """Source of ``impl(method, effects, W, rtol)``: one step of every lane (h, y, f(y),
    tolerances and parameters from ``W``; its stages, y_new, error and root into ``W``).
    ``floor``: the parameter slot of the model's domain floor (:func:`.model.domain_floor`;
    None: 0, written as no subtraction at all, as the cone's r > 0 always was)."""
    ly = layout(method, n)
    slot = {"y": ly.Y, "k0": ly.K, "atol": ly.ATOL}

    def load(kind, j):
        return _w(slot[kind], j)

    def store(i, j, value):
        return f"{_w(ly.YN if i == 'y' else ly.K + i * n, j)} = {value}"

    pt = ", ".join(_w(ly.P, k) for k in range(N_PARAMS))
    lines = ["def impl(method, effects, W, rtol):", f"    for l in range({LANES}):"]
    lines += [f"        pt = ({pt})", f"        h = {_w(ly.H)}"]
    lines += unrolled_step_lines(method, n, load, store, "        ")
    lines.append(f"        {_w(ly.ERR)} = err")
    # The controller's root in a loop of its own (arithmetic: .branchless.power).
    ctl = repr(RK_TABLEAUX[method].controller())
    lines += [f"    for l in range({LANES}):"]
    inside = _w(ly.YN) if floor is None else f"{_w(ly.YN)} - {_w(ly.P + floor)}"
    lines += [f"        e = step_error({_w(ly.ERR)}, {inside}, {ctl})"]
    lines += [f"        {_w(ly.ERR, c)} = e[{c}]" for c in range(2)]
    return "\n".join(lines) + "\n"


def control_source(method: int, n: int, terminal: bool, fate: bool = False) -> str:
    """Source of ``impl(method, effects, W, max_steps)``: the step-size decision of every
    active lane, as :func:`.rk.rk_run` takes it, written with selects. A lane whose accepted
    step crossed an apsis or (with ``terminal`` events compiled in) has a terminal event
    (:func:`.protocol.terminal_between` y and y_new) keeps its state and gets FLAG 1; an
    accepted step without one moves the lane to y_new; a lane that may not take another
    attempt (:func:`.rk.step_allowed`) gets FLAG 2; a lane that took a polishing step keeps
    everything and gets FLAG 3. Every choice is a select (:func:`.branchless.pick`,
    :func:`.branchless.keep`): one vector loop. A ``fate`` run (:mod:`.lanes_fate`) looks for
    no apsides and clips the next attempt to T_END as rk_run clips to t_end (setting LAST; an
    accepted LAST step gets FLAG 1)."""
    ly = layout(method, n)
    ctl = repr(RK_TABLEAUX[method].controller())
    w = _w
    y = ", ".join(_w(ly.Y, j) for j in range(n))
    yn = ", ".join(_w(ly.YN, j) for j in range(n))
    pt = ", ".join(_w(ly.P, k) for k in range(N_PARAMS))
    term = f"terminal_between(effects, ({y}), ({yn}), ({pt}))" if terminal else "False"
    lines = ["def impl(method, effects, W, max_steps):", f"    for l in range({LANES}):"]
    lines += [
        f"        pol = {w(ly.POLISH)} != 0.0",
        f"        act = ({w(ly.ACTIVE)} != 0.0) & (not pol)",
        f"        h = {w(ly.H)}",
        f"        t = {w(ly.T)}",
        f"        eold = {w(ly.ERR_OLD)}",
        f"        acc, h_new, h_next, eold2, rej2 = step_decide(({w(ly.ERR)}, {w(ly.ERR, 1)}), "
        f"h, eold, {w(ly.REJECTED)} != 0.0, {ctl})",
        f"        aps = {'False' if fate else f'apsis_crossed({w(ly.G_APS)}, {w(ly.YN, Y_U)})'}",
        f"        term = {term}",
        f"        last = {f'{w(ly.LAST)} != 0.0' if fate else 'False'}",
        "        simple = act & acc & (not aps) & (not term) & (not last)",
        f"        n_acc = {w(ly.N_ACC)} + pick(act & acc, 1.0, 0.0)",
        f"        n_rej = {w(ly.N_REJ)} + pick(act & (not acc), 1.0, 0.0)",
        "        t2 = pick(simple, t + h, t)",
        "        h2 = pick(simple, h_next, pick(act, h_new, h))",
        "        ok = step_allowed(n_acc + n_rej, max_steps, h2, t2) == OK",
    ]
    for j in range(n):
        lines.append(f"        {w(ly.Y, j)} = keep(simple, {w(ly.YN, j)}, {w(ly.Y, j)})")
        lines.append(f"        {w(ly.K, j)} = keep(simple, {w(ly.K + ly.ns * n, j)}, {w(ly.K, j)})")
    if fate:  # the next attempt clipped to T_END, as rk_run clips it to t_end
        lines += [
            "        nxt = act & ok & (simple | (not acc))",
            f"        h_clip, clip = clip_step(t2, h2, {w(ly.T_END)})",
            "        h2 = pick(nxt, h_clip, h2)",
            f"        {w(ly.LAST)} = keep(nxt, pick(clip, 1.0, 0.0), {w(ly.LAST)})",
        ]
    lines += [
        f"        {w(ly.T)} = t2",
        f"        {w(ly.H)} = h2",
        f"        {w(ly.H_NEXT)} = keep(act, h_next, {w(ly.H_NEXT)})",
        f"        {w(ly.ERR_OLD)} = keep(act, eold2, eold)",
        f"        {w(ly.REJECTED)} = keep(act, pick(rej2, 1.0, 0.0), {w(ly.REJECTED)})",
        f"        {w(ly.N_ACC)} = n_acc",
        f"        {w(ly.N_REJ)} = n_rej",
        f"        {w(ly.FLAG)} = pick(pol, 3.0, pick(act & acc & (not simple), 1.0, "
        "pick(act & (not ok), 2.0, 0.0)))",
    ]
    return "\n".join(lines) + "\n"


_NAMESPACE = {
    "math": math,
    "rates5": rates5,
    "rates6": rates6,
    "rates9": rates9,
    "rates10": rates10,
    "step_error": step_error,
    "step_decide": step_decide,
    "step_allowed": step_allowed,
    "clip_step": clip_step,
    "apsis_crossed": apsis_crossed,
    "terminal_between": terminal_between,
    "OK": OK,
    "pick": pick,
    "keep": keep,
}


@functools.cache
def _compiled(kind: str, method: int, n: int, terminal: bool, floor: int | None = None):
    if kind == "attempt":
        src = attempt_source(method, n, floor)
    else:
        src = control_source(method, n, terminal, kind == "fate control")
    namespace = dict(_NAMESPACE)
    exec(compile(src, f"<conesurvey lanes {kind} method={method} n={n}>", "exec"), namespace)  # noqa: S102
    return namespace["impl"]


def _effects(effects) -> tuple[int, bool]:
    e = literal_int(effects, "effects")
    return state_size_of(e), terminal_events(e)


def _floor(effects) -> int | None:
    """The slot of the model's domain floor (None: 0, the cone's r > 0)."""
    return MODEL_ROWS[model_of_key(literal_int(effects, "effects"))].physics.DOMAIN_FLOOR_SLOT


def lanes_attempt(method, effects, W, rtol):
    """One step of every lane, its error and root (:func:`attempt_source`). Jit-only."""
    raise NotImplementedError("lanes_attempt runs inside numba kernels only")


def lanes_control(method, effects, W, max_steps):
    """The step-size decision of every lane (:func:`control_source`). Jit-only."""
    raise NotImplementedError("lanes_control runs inside numba kernels only")


def lanes_control_fate(method, effects, W, max_steps):
    """The step-size decision of every lane of a fate run (:func:`control_source` with
    ``fate``). Jit-only."""
    raise NotImplementedError("lanes_control_fate runs inside numba kernels only")


def lanes_layout(method, effects):
    """:func:`layout` of the literal method and effect set, a constant :class:`Layout` (read
    by name). Jit-only."""
    raise NotImplementedError("lanes_layout runs inside numba kernels only")


@overload(lanes_attempt, jit_options=GEN_OPTS)
def _ol_lanes_attempt(method, effects, W, rtol):
    return _compiled("attempt", rk_method_id(method), _effects(effects)[0], False, _floor(effects))


@overload(lanes_control, jit_options=GEN_OPTS)
def _ol_lanes_control(method, effects, W, max_steps):
    return _compiled("control", rk_method_id(method), *_effects(effects))


@overload(lanes_control_fate, jit_options=GEN_OPTS)
def _ol_lanes_control_fate(method, effects, W, max_steps):
    return _compiled("fate control", rk_method_id(method), *_effects(effects))


@overload(lanes_layout, jit_options=GEN_OPTS)
def _ol_lanes_layout(method, effects):
    consts = layout(rk_method_id(method), _effects(effects)[0])

    def impl(method, effects):
        return consts

    return impl


# ------------------------------------------------------------------------------ intrinsics
@intrinsic
def borrow(typingctx, arr):
    """A view of ``arr`` without a reference-count handle (meminfo NULL): binding it to a
    parameter costs no atomic update (~20 cycles each; an orbit's start, events and result bind
    about a hundred). The caller keeps an owner alive for as long as the view is used."""
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


@kernel
def split_owned(own, sizes):
    """Borrowed consecutive pieces of ``own`` of the given sizes."""
    out = []
    start = 0
    for size in sizes:
        out.append(borrow(own[start : start + size]))
        start += size
    return out


@intrinsic
def fetch_add(typingctx, counter, value):
    """counter[0] += value atomically; returns the old value (the workers' shared queue)."""
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(counter)(context, builder, value=args[0])
        val = context.cast(builder, args[1], sig.args[1], types.int64)
        return builder.atomic_rmw("add", ary.data, val, "monotonic")

    return types.int64(counter, value), codegen


#: Guided pieces of the workers' queue: a piece is 1 / (PIECE_SPLIT x workers) of the points
#: left, down to single points at the end (:func:`piece_starts`).
PIECE_SPLIT = 4


@kernel
def piece_starts(n, n_workers):
    """The pieces the workers take from their shared queue (:func:`take_point`): the first
    point of each piece of 0..n-1, then n (int64[pieces + 1]). Each piece is 1 / (PIECE_SPLIT
    ``n_workers``) of the points left (at least one point): a few large pieces first, a few
    dozen atomic increments a call instead of one per point, each worker's results written
    into runs of adjacent points (no cache line bounced between the cores per point), then
    single points at the end, so the workers finish within an orbit of each other as a queue
    of single points does."""
    div = PIECE_SPLIT * max(1, n_workers)
    k, s = 0, 0
    while s < n:
        s += max(1, (n - s) // div)
        k += 1
    starts = np.empty(k + 1, np.int64)
    s = 0
    for j in range(k):
        starts[j] = s
        s += max(1, (n - s) // div)
    starts[k] = n
    return starts


@kernel(inline="always")
def take_point(queue, starts, nxt, end):
    """A worker's next point: the next of its piece [nxt, end), or the first of the next piece
    of ``starts`` (:func:`piece_starts`) taken from ``queue`` (int64[1]: the next piece,
    shared by the workers). Returns (point, nxt, end); point -1 when every piece is taken."""
    if nxt >= end:
        c = fetch_add(queue, 1)
        if c >= starts.shape[0] - 1:
            return -1, nxt, end
        nxt, end = starts[c], starts[c + 1]
    return nxt, nxt + 1, end

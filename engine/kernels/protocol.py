"""The run protocol every integrator kernel follows: status codes, event kinds, buffers, events.

A run kernel (:func:`.rk.rk_run`, :func:`.symplectic.sym_run`, ...) has one signature (see
:mod:`.orbit`), writes events and recorded states into buffers the caller preallocated, and
returns ``(status, n_accepted, n_rejected, t, y, n_events, n_recorded)`` (the fields of
:data:`RUN_RESULT`): it never raises and never reallocates, so its hot loop has no reference
counting. The helpers here are the parts every run kernel shares: the terminal events already
on at the start, appending an event or a recorded state, the event functions, and Brent's
root finder in reverse communication (the caller evaluates the function on its own dense
output or partial step).

``effects`` reaches these helpers as a numba literal from the run kernel, so the tests
``effects & SPILL_EFFECTS`` fold to constants here as in the caller.
"""

from __future__ import annotations

import math

import numpy as np
from numba.core import errors, types
from numba.extending import overload

from .._jit import kernel
from .effects import EFFECTS, REVOLUTIONS, bringing
from .layouts import P_R_VERTEX, P_THETA_MAX, P_V_REST, Y_R, Y_THETA, Y_U, Y_V
from .model import leaves, lift_margin, rim_margin, slip_margin

#: The parameters every run kernel makes literal (``numba.literally``; named so to
#: :func:`engine._jit.call_specialized`): a run compiles only its method's and effects' code.
LITERAL = ("method", "effects")

EPS = 2.220446049250313e-16
SQRT_EPS = 1.4901161193847656e-08

# ---------------------------------------------------------------------------- statuses (int8)
#: (code, CF flag meaning, message) of every exit status of one integration. The code is the
#: position in the table; the flags name the ``status`` variable's CF ``flag_meanings``.
STATUSES = (
    (0, "ok", "ok"),
    (1, "spilled", "spilled: the orbit reached the rim before the end"),
    (2, "slipped", "slipped: friction needed exceeded mu N before the end"),
    (3, "max_steps", "maximum number of steps reached"),
    (4, "step_too_small", "step size fell below 16 eps |t|"),
    (
        5,
        "not_bounded",
        "not a bounded orbit: no turning points (forbidden, escaping, radial or invalid input)",
    ),
    (6, "non_finite", "non-finite state"),
    (7, "unsupported_scene", "method does not support this scene"),
    (8, "buffer_full", "output buffer full (internal: the caller retries with more room)"),
    (9, "rest", "came to rest: rolling resistance stopped the sphere"),
    (10, "vertex", "reached the vertex region, where the single-contact model ends"),
    (11, "lifted_off", "lifted off: the normal force fell to zero and the sphere left the surface"),
)
OK = 0
SPILLED = 1
SLIPPED = 2
MAX_STEPS = 3
STEP_TOO_SMALL = 4
NOT_BOUNDED = 5
NONFINITE = 6
UNSUPPORTED = 7
BUFFER_FULL = 8
RESTED = 9
AT_VERTEX = 10
LIFTED_OFF = 11
STATUS_FLAGS = tuple(row[1] for row in STATUSES)
#: Statuses of a run that ended as the physics says (the others are failures).
NORMAL_ENDS = (OK, SPILLED, SLIPPED, RESTED, AT_VERTEX, LIFTED_OFF)
STATUS_MESSAGES = tuple(row[2] for row in STATUSES)

# ------------------------------------------------------------------------ event kinds (int8)
PERICENTRE = 0
APOCENTRE = 1
SPILL = 2
SLIP = 3
REST = 4
VERTEX = 5
HORIZON = 6
FAILURE = 7  # where a run failed (recorded by engine.simulate, never by a kernel)
LIFTOFF = 8  # the normal force fell to zero: brought by the model (``.model.leaves``)
EVENT_NAMES = ("pericentre", "apocentre", "spill", "slip", "rest", "vertex", "horizon", "failed",
               "liftoff")  # fmt: skip
#: The terminal event kinds, in the order they are checked (an apsis is not terminal; FAILURE,
#: between them, is never enabled).
FIRST_TERMINAL = SPILL
LAST_TERMINAL = LIFTOFF
#: The effects that bring each terminal event (the effects table's ``events``); the horizon is
#: brought by the run option REVOLUTIONS.
SPILL_EFFECTS = bringing("spill")
SLIP_EFFECTS = bringing("slip")
REST_EFFECTS = bringing("rest")
VERTEX_EFFECTS = bringing("vertex")
#: Effects (and run options) that bring terminal events into a run.
TERMINAL_EFFECTS = SPILL_EFFECTS | SLIP_EFFECTS | REST_EFFECTS | VERTEX_EFFECTS | REVOLUTIONS

# ------------------------------------------------------------------ what a run records
RECORD_NONE = 0
RECORD_STEPS = 1
RECORD_EVERY_DT = 2

#: Fields of the tuple a run kernel returns.
RUN_RESULT = ("status", "n_accepted", "n_rejected", "t", "y", "n_events", "n_recorded")


def _check_tables() -> None:
    for code, (c, _, _) in enumerate(STATUSES):
        assert c == code, "STATUSES must be listed in code order"
    terminal = EVENT_NAMES[FIRST_TERMINAL:HORIZON]
    for e in EFFECTS:
        assert set(e.events) <= set(terminal), f"{e.name}: events {e.events} not in {terminal}"


_check_tables()


# ------------------------------------------------------------------------------- buffers
@kernel
def copy_into(src, dst):
    """dst[:] = src for 1-D arrays (a loop: no slicing machinery to compile)."""
    for j in range(src.shape[0]):
        dst[j] = src[j]


@kernel
def copy_row(src, dst, row):
    """dst[row, :] = src."""
    for j in range(src.shape[0]):
        dst[row, j] = src[j]


@kernel
def event_buffers(capacity, n):
    """Empty event buffers (time, kind, state) for ``capacity`` events of states of length n
    (times and states are views of one allocation)."""
    block = np.empty(capacity * (n + 1))
    return block[:capacity], np.empty(capacity, np.int8), block[capacity:].reshape((capacity, n))


@kernel
def push_event(ev_t, ev_kind, ev_y, n_ev, t, kind, y):
    """Record event ``kind`` at time t [s] with state y while the buffers have room; returns
    the count of events so far, recorded or not (every event buffer's one rule: a trajectory,
    which needs them all, stops with :data:`BUFFER_FULL` once :func:`events_full`, and is run
    again with more room; a story runs on)."""
    if n_ev < ev_t.shape[0]:
        ev_t[n_ev] = t
        ev_kind[n_ev] = kind
        copy_row(y, ev_y, n_ev)
    return n_ev + 1


@kernel
def events_full(n_ev, ev_t):
    """Whether some of ``n_ev`` events found no room in the buffers (:func:`push_event`)."""
    return n_ev > ev_t.shape[0]


@kernel
def push_state(tr_t, tr_y, n_tr, t, y):
    """Append a recorded state; returns the new count, or -1 if the buffers are full."""
    if n_tr == tr_t.shape[0]:
        return -1
    tr_t[n_tr] = t
    copy_row(y, tr_y, n_tr)
    return n_tr + 1


@kernel
def record_apsis(ev_t, ev_kind, ev_y, n_ev, t, y, g_aps, n_aps, n_apsides):
    """Append the apsis the apsis function (sign ``g_aps`` before it) just crossed at time t with
    state y. Returns (the event count (:func:`push_event`), the new sign, apsides so far,
    whether the run's ``n_apsides`` (if > 0) are reached)."""
    kind = APOCENTRE if g_aps > 0.0 else PERICENTRE
    n_ev = push_event(ev_t, ev_kind, ev_y, n_ev, t, kind, y)
    n_aps += 1
    return n_ev, -g_aps, n_aps, n_apsides > 0 and n_aps >= n_apsides


# -------------------------------------------------------------------------------- events
@kernel
def kind_enabled(effects, kind):
    """Whether the terminal event ``kind`` is compiled into runs of ``effects`` (folds to a
    constant: ``effects`` is a literal)."""
    if kind == SPILL:
        return effects & SPILL_EFFECTS != 0
    if kind == SLIP:
        return effects & SLIP_EFFECTS != 0
    if kind == REST:
        return effects & REST_EFFECTS != 0
    if kind == VERTEX:
        return effects & VERTEX_EFFECTS != 0
    if kind == HORIZON:
        return effects & REVOLUTIONS != 0
    if kind == LIFTOFF:
        return leaves(effects)
    return False


def terminal_events(effects) -> bool:
    """Whether runs of ``effects`` (an int, or a literal in a kernel, where it folds to a
    constant) watch for terminal events: an effect's, the horizon's, or the model's lift-off."""
    return bool(int(effects) & TERMINAL_EFFECTS) or leaves(int(effects))


@overload(terminal_events, jit_options={"nogil": True})
def _terminal_events(effects):
    if not isinstance(effects, types.IntegerLiteral):
        raise errors.TypingError("effects must be a numba literal here")
    value = terminal_events(effects.literal_value)
    return lambda effects: value


@kernel
def event_value(kind, y, p, effects):
    """Event function g(y) of an event kind; a terminal event fires where g reaches 0 from below
    (apsides: u, either way; the direction tells pericentre from apocentre)."""
    if kind == SPILL:
        return rim_margin(y, p)
    if kind == SLIP:
        return slip_margin(y, p, effects)
    if kind == REST:
        return p[P_V_REST] - math.sqrt(y[Y_U] * y[Y_U] + y[Y_V] * y[Y_V])
    if kind == VERTEX:
        return p[P_R_VERTEX] - y[Y_R]
    if kind == HORIZON:
        return abs(y[Y_THETA]) - p[P_THETA_MAX]
    if kind == LIFTOFF:
        return lift_margin(y, p, effects)
    return y[Y_U]


@kernel
def terminal_fired(kind, g):
    """True where the terminal event function value g means the event has happened (the rim
    is reached at g = 0; slipping needs g > 0, lifting off N < 0: a cylinder's ball with no
    speed along the wall has N = 0 and rolls down it). Without a branch (``|``, ``&``), so that
    the lanes' step-size control stays vector code (:mod:`.lanes_step`)."""
    return (g > 0.0) | ((kind != SLIP) & (kind != LIFTOFF) & (g == 0.0))


@kernel
def terminal_crossed(kind, g0, g1):
    """True where a terminal event happens between two states with event values g0, g1. Rest
    is an event only when the speed falls through its threshold (a sphere that starts at rest
    may move off), the vertex only when the centre enters its region (an orbit that starts
    at its r_min inside the region leaves it: the closed form's convention); the others fire
    wherever they hold at the end of the step."""
    if kind == REST or kind == VERTEX:
        return (g0 < 0.0) & terminal_fired(kind, g1)
    return terminal_fired(kind, g1)


@kernel
def terminal_at(effects, y, p):
    """Terminal event kind already on at state y or -1; checked in kind order (rest and the
    vertex are not events at a start: see :func:`terminal_crossed`; the fate kernel decides a
    start at rest or inside the vertex region)."""
    for kind in range(FIRST_TERMINAL, LAST_TERMINAL + 1):
        if kind != REST and kind != VERTEX and kind_enabled(effects, kind):
            if terminal_fired(kind, event_value(kind, y, p, effects)):
                return kind
    return -1


@kernel
def terminal_between(effects, y, ynew, p):
    """Whether any terminal event happens in the step from y to ynew. Every event function is
    evaluated and the answers combined without an early exit: no branch, so the lanes' control
    runs it as vector code (a run evaluates them all anyway on every step without an event)."""
    hit = False
    for kind in range(FIRST_TERMINAL, LAST_TERMINAL + 1):
        if kind_enabled(effects, kind):
            g1 = event_value(kind, ynew, p, effects)
            g0 = event_value(kind, y, p, effects) if kind == REST or kind == VERTEX else -1.0
            hit = hit | terminal_crossed(kind, g0, g1)
    return hit


@kernel
def status_of(kind):
    """Exit status of a run that stopped at terminal event ``kind``."""
    if kind == SPILL:
        return SPILLED
    if kind == SLIP:
        return SLIPPED
    if kind == REST:
        return RESTED
    if kind == VERTEX:
        return AT_VERTEX
    if kind == LIFTOFF:
        return LIFTED_OFF
    return OK


@kernel
def start_protocol(effects, y, p, record, ev_t, ev_kind, ev_y, tr_t, tr_y):
    """Shared start of every run at t = 0: record the first state, and stop at once if a
    terminal event is already on. Returns (status, n_ev, n_tr); status OK means run on."""
    n_tr = 0
    if record != RECORD_NONE:
        n_tr = push_state(tr_t, tr_y, 0, 0.0, y)
        if n_tr < 0:
            return BUFFER_FULL, 0, 0
    kind = terminal_at(effects, y, p)
    if kind < 0:
        return OK, 0, n_tr
    n_ev = push_event(ev_t, ev_kind, ev_y, 0, 0.0, kind, y)
    if events_full(n_ev, ev_t):
        return BUFFER_FULL, 0, n_tr
    return status_of(kind), n_ev, n_tr


# ---------------------------------------------------------------------- Brent's zeroin
@kernel
def brent_start(st, a, b, fa, fb):
    """Start a reverse-communication Brent search on [a, b] with fa fb <= 0 (state ``st``[8])."""
    st[0] = a
    st[1] = b
    st[2] = a
    st[3] = fa
    st[4] = fb
    st[5] = fa
    st[6] = b - a
    st[7] = b - a


@kernel
def _brent_save(st, a, b, c, fa, fb, fc):
    st[0] = a
    st[1] = b
    st[2] = c
    st[3] = fa
    st[4] = fb
    st[5] = fc


@kernel
def brent_next(st, xtol):
    """Brent's zeroin step: (done, x). When not done the caller evaluates f(x) and calls
    :func:`brent_update`; when done x is the root within 2 eps |x| + xtol/2."""
    a, b, c, fa, fb, fc, d, e = st[0], st[1], st[2], st[3], st[4], st[5], st[6], st[7]
    if (fb > 0.0 and fc > 0.0) or (fb < 0.0 and fc < 0.0):
        c = a
        fc = fa
        d = b - a
        e = d
    if abs(fc) < abs(fb):
        a = b
        b = c
        c = a
        fa = fb
        fb = fc
        fc = fa
    tol = 2.0 * EPS * abs(b) + 0.5 * xtol
    m = 0.5 * (c - b)
    if abs(m) <= tol or fb == 0.0:
        _brent_save(st, a, b, c, fa, fb, fc)
        return True, b
    if abs(e) >= tol and abs(fa) > abs(fb):
        s = fb / fa
        if a == c:
            pp = 2.0 * m * s
            qq = 1.0 - s
        else:
            qq = fa / fc
            rr = fb / fc
            pp = s * (2.0 * m * qq * (qq - rr) - (b - a) * (rr - 1.0))
            qq = (qq - 1.0) * (rr - 1.0) * (s - 1.0)
        if pp > 0.0:
            qq = -qq
        else:
            pp = -pp
        if 2.0 * pp < min(3.0 * m * qq - abs(tol * qq), abs(e * qq)):
            e = d
            d = pp / qq
        else:
            d = m
            e = m
    else:
        d = m
        e = m
    a = b
    fa = fb
    if abs(d) > tol:
        b = b + d
    else:
        b = b + (tol if m > 0.0 else -tol)
    _brent_save(st, a, b, c, fa, fb, fc)
    st[6] = d
    st[7] = e
    return False, b


@kernel
def brent_update(st, fx):
    """Report f at the x that :func:`brent_next` asked for."""
    st[4] = fx

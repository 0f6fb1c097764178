"""Adaptive explicit Runge-Kutta integration (Dormand-Prince 5(4) and 8(5,3)) of a scene, in numba.

Layers, each a pure kernel (no Python in the loops):

- :func:`rk_attempt` one step plus its error estimate for any tableau of :mod:`.tableaux`: the
  code is generated from the tableau data (an ``@overload`` on the literal ``method`` unrolls the
  stages with the coefficients as constants; :func:`generated_source` prints it); the error norm
  is the RMS norm (DOP853: Hairer's stretched 5th/3rd-order norm);
- :func:`initial_step` the starting step of Hairer, Norsett & Wanner I, section II.4;
- :func:`rk_dense` / :func:`rk_dense_component` / :func:`rk_dense_rate` the continuous extension
  (Shampine's quartic for DP5, Hairer's degree-7 one for DOP853: 3 extra stages, computed only on
  steps that need them) and its derivative;
- :func:`rk_locate` event location on the dense output by Brent's method (xtol 4 eps);
- :func:`rk_run` the one adaptive loop: PI step-size control (:data:`SAFETY`,
  :data:`MIN_FACTOR`, :data:`MAX_FACTOR`, per-method exponents), events (apsides u = 0, the rim,
  slip onset), optional recording of the trajectory, status codes instead of exceptions.

Error control: a step is accepted when the RMS over components of err_i / (atol_i + rtol
max(|y_i|, |y_new_i|)) is <= 1, with atol_i = rtol * scale_i and the scales of
:func:`tolerance_scales` (the orbit's own size of each component: the radial velocity is measured
against its largest value on the orbit, so nearly circular orbits keep their apsides accurate).
Measured accuracy (tests/test_integrators.py): period and apsidal angle within 100 rtol kappa
relative, kappa = max(1, (A/r1^2)/|calE|) the amplification of a velocity error at the pericentre
into the radial energy ((1+e)/(1-e) for a free-fall ellipse, ~1 otherwise).

``method`` and ``effects`` must reach these kernels as numba literals (the entry points call
``numba.literally``); everything else (tolerances, parameters, initial state) is a runtime value.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import literally
from numba.core import errors, types
from numba.extending import overload

from .._jit import kernel
from .physics import coefficients
from .roots import circular_radius, turning_points
from .scenes import (
    ATTITUDE,
    N_ATTITUDE,
    N_BASE,
    P_COS,
    P_G,
    P_K,
    P_M,
    P_RIM,
    P_SIN,
    RIM,
    SLIP_CHECK,
    param_tuple,
    rates5,
    rates9,
    rhs,
    rim_margin,
    slip_margin,
    state_size,
)
from .tableaux import (
    DOP853_A,
    DOP853_C,
    DOP853_E,
    DOP853_E3,
    DOP853_ERR_ORDER,
    DOP853_N_STAGES,
    DOP853_P,
    DP5_A,
    DP5_C,
    DP5_E,
    DP5_ERR_ORDER,
    DP5_N_STAGES,
    DP5_P,
)

# Methods (literal integers in the kernels).
RK45 = 0
DOP853 = 1
SYMPLECTIC = 2
METHOD_IDS = {"rk45": RK45, "dop853": DOP853, "symplectic": SYMPLECTIC}

# Step-size control.
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
#: PI-controller beta of each method (Hairer's defaults: dopri5 0.04, dop853 0).
BETA = (0.04, 0.0)
#: Coefficient of beta in the proportional exponent (dopri5: 0.75, dop853: 0.2).
BETA_WEIGHT = (0.75, 0.2)
#: Floor of the previous error in the PI controller.
ERR_FLOOR = 1e-4
EPS = 2.220446049250313e-16
SQRT_EPS = 1.4901161193847656e-08

# Exit status of one integration (int8).
OK = 0
SPILLED = 1
SLIPPED = 2
MAX_STEPS = 3
STEP_TOO_SMALL = 4
NOT_BOUNDED = 5
NONFINITE = 6
UNSUPPORTED = 7
BUFFER_FULL = 8
STATUS_MESSAGES = (
    "ok",
    "spilled: the orbit reached the rim before the end",
    "slipped: friction needed exceeded mu N before the end",
    "maximum number of steps reached",
    "step size fell below 16 eps |t|",
    "not a bounded orbit: no turning points (forbidden, escaping, radial or invalid input)",
    "non-finite state",
    "method does not support this scene (symplectic needs a conservative scene)",
    "output buffer full (internal: the caller retries with more room)",
)

#: CF flag_meanings of the status codes (same order as STATUS_MESSAGES).
STATUS_FLAGS = (
    "ok",
    "spilled",
    "slipped",
    "max_steps",
    "step_too_small",
    "not_bounded",
    "non_finite",
    "unsupported_scene",
    "buffer_full",
)

# Event kinds (int8, CF flag_values 0..3).
PERICENTRE = 0
APOCENTRE = 1
SPILL = 2
SLIP = 3
EVENT_NAMES = ("pericentre", "apocentre", "spill", "slip")

# What the run records along the way.
RECORD_NONE = 0
RECORD_STEPS = 1
RECORD_EVERY_DT = 2

_DP5_E3 = np.zeros(DP5_N_STAGES + 1)


@kernel
def tableau(method):
    """(A, C, E, E3, P, n_stages, n_all, error_order) of a method (literal ``method``)."""
    if method == DOP853:
        return (
            DOP853_A,
            DOP853_C,
            DOP853_E,
            DOP853_E3,
            DOP853_P,
            DOP853_N_STAGES,
            DOP853_A.shape[0],
            DOP853_ERR_ORDER,
        )
    return DP5_A, DP5_C, DP5_E, _DP5_E3, DP5_P, DP5_N_STAGES, DP5_A.shape[0], DP5_ERR_ORDER


# ------------------------------------------------------------------------------------- one step
# The step and the extra dense-output stages are unrolled from the tableau data: an @overload
# builds, for the literal ``method`` and state size, straight-line code with the coefficients as
# constants (zero terms left out) and the stages in local scalars, so the generic stepper runs
# as fast as one written by hand (scripts/bench_effects.py). It is plain Python source compiled
# by numba inside the (disk-cached) callers; ``generated_source`` shows it.
_GEN_OPTS = {"error_model": "numpy", "fastmath": False, "nogil": True}
_TABLEAUX = {
    RK45: (DP5_A, DP5_E, _DP5_E3, DP5_N_STAGES),
    DOP853: (DOP853_A, DOP853_E, DOP853_E3, DOP853_N_STAGES),
}


def _lincomb(coefs, term: str) -> str:
    """Source of sum_m coefs[m] * term.format(m=m) over the nonzero coefficients."""
    out = [f"{float(c)!r} * {term.format(m=m)}" for m, c in enumerate(coefs) if c != 0.0]
    return " + ".join(out) if out else "0.0"


def _attempt_source_loops(method: int) -> str:
    """Like :func:`_attempt_source` with a loop over the components (less code to compile: used
    for the 13-stage DOP853, whose steps are few)."""
    A, E, E3, ns = _TABLEAUX[method]
    lines = ["def impl(method, effects, y, h, pt, K, ynew, rtol, atol):", "    n = y.shape[0]"]
    for i in range(1, ns + 1):
        lines += [
            "    for j in range(n):",
            f"        ynew[j] = y[j] + h * ({_lincomb(A[i, :i], 'K[{m}, j]')})",
            f"    rhs(ynew, pt, effects, K, {i})",
        ]
    lines += [
        "    e5 = 0.0",
        "    e3 = 0.0",
        "    for j in range(n):",
        "        sc = atol[j] + rtol * max(abs(y[j]), abs(ynew[j]))",
        f"        d = ({_lincomb(E, 'K[{m}, j]')}) / sc",
        "        e5 += d * d",
        f"        d = ({_lincomb(E3, 'K[{m}, j]')}) / sc",
        "        e3 += d * d",
        "    if e5 == 0.0 and e3 == 0.0:",
        "        return 0.0",
        "    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)",
    ]
    return "\n".join(lines) + "\n"


def _attempt_source(method: int, n: int) -> str:
    """Source of ``impl(method, effects, y, h, pt, K, ynew, rtol, atol) -> err``: one step of
    size h from y with K[0] = f(y); writes the stages K[1..ns], y_new and K[ns] = f(y_new).
    Dormand-Prince 5: straight-line code on scalars; DOP853: loops over the components."""
    if method == DOP853:
        return _attempt_source_loops(method)
    A, E, E3, ns = _TABLEAUX[method]
    comps = range(n)
    rates = "rates9" if n == 9 else "rates5"
    lines = ["def impl(method, effects, y, h, pt, K, ynew, rtol, atol):"]
    lines += [f"    y_{j} = y[{j}]" for j in comps]
    lines += [f"    k0_{j} = K[0, {j}]" for j in comps]
    for i in range(1, ns + 1):
        args = [f"y_{j} + h * ({_lincomb(A[i, :i], 'k{m}_' + str(j))})" for j in comps]
        if i == ns:
            lines += [f"    n_{j} = {args[j]}" for j in comps]
            lines += [f"    ynew[{j}] = n_{j}" for j in comps]
            args = [f"n_{j}" for j in comps]
        targets = ", ".join(f"k{i}_{j}" for j in comps)
        lines.append(f"    {targets} = {rates}({', '.join(args)}, pt, effects)")
    lines += [f"    K[{i}, {j}] = k{i}_{j}" for i in range(1, ns + 1) for j in comps]
    lines += ["    e5 = 0.0", "    e3 = 0.0"]
    for j in comps:
        lines.append(f"    sc = atol[{j}] + rtol * max(abs(y_{j}), abs(n_{j}))")
        lines.append(f"    d = ({_lincomb(E, 'k{m}_' + str(j))}) / sc")
        lines.append("    e5 += d * d")
        if method == DOP853:
            lines.append(f"    d = ({_lincomb(E3, 'k{m}_' + str(j))}) / sc")
            lines.append("    e3 += d * d")
    if method == DOP853:
        lines += [
            "    if e5 == 0.0 and e3 == 0.0:",
            "        return 0.0",
            f"    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * {n})",
        ]
    else:
        lines.append(f"    return abs(h) * math.sqrt(e5 / {n})")
    return "\n".join(lines) + "\n"


def _dense_stages_source(method: int) -> str:
    """Source of ``impl(method, effects, y, h, p, K, ytmp)``: the extra stages (array form)."""
    A, E, E3, ns = _TABLEAUX[method]
    lines = ["def impl(method, effects, y, h, p, K, ytmp):", "    n = state_size(effects)"]
    for i in range(ns + 1, A.shape[0]):
        lines += [
            "    for j in range(n):",
            f"        ytmp[j] = y[j] + h * ({_lincomb(A[i, :i], 'K[{m}, j]')})",
            f"    rhs(ytmp, p, effects, K, {i})",
        ]
    if A.shape[0] == ns + 1:
        lines.append("    return")
    return "\n".join(lines) + "\n"


def _dense_component_source(method: int) -> str:
    """Source of ``impl(method, y, K, h, theta, j)``: one component of the dense output."""
    P = DOP853_P if method == DOP853 else DP5_P
    lines = ["def impl(method, y, K, h, theta, j):", "    acc = 0.0"]
    for i in range(P.shape[0]):
        if not P[i].any():
            continue
        horner = "0.0"
        for c in P[i][::-1]:
            horner = (
                f"({horner} + {float(c)!r}) * theta" if horner != "0.0" else f"{float(c)!r} * theta"
            )
        lines.append(f"    acc += ({horner}) * K[{i}, j]")
    lines.append("    return y[j] + h * acc")
    return "\n".join(lines) + "\n"


def generated_source(kind: str, method: int, n: int = 5) -> str:
    """The generated source of an unrolled kernel: "attempt" (step + error), "dense_stages" or
    "dense_component"."""
    if kind == "attempt":
        return _attempt_source(method, n)
    if kind == "dense_stages":
        return _dense_stages_source(method)
    return _dense_component_source(method)


@functools.cache
def _generated(kind: str, method: int, n: int):
    src = generated_source(kind, method, n)
    namespace = {
        "math": math,
        "rhs": rhs,
        "rates5": rates5,
        "rates9": rates9,
        "state_size": state_size,
    }
    exec(compile(src, f"<conesurvey {kind} method={method} n={n}>", "exec"), namespace)  # noqa: S102
    return namespace["impl"]


def _literal(arg, name: str) -> int:
    if not isinstance(arg, types.IntegerLiteral):
        raise errors.TypingError(f"{name} must be a numba literal here (use numba.literally)")
    return int(arg.literal_value)


def rk_attempt(method, effects, y, h, pt, K, ynew, rtol, atol):
    """Attempt one step of size h [s] from y with K[0] = f(y) given; returns the scaled RMS
    error estimate (accept when <= 1; DOP853: Hairer's stretched 5th/3rd-order norm). ``pt`` is
    the parameter tuple (:func:`.scenes.param_tuple`: read once, kept in registers).

    Writes the stages K[1..ns], ``ynew`` and K[ns] = f(ynew) (first same as last). Jit-only.
    """
    raise NotImplementedError("rk_attempt runs inside numba kernels only")


def rk_dense_stages(method, effects, y, h, p, K, ytmp):
    """The extra stages the dense output needs (DOP853: 3; Dormand-Prince 5: none). Jit-only."""
    raise NotImplementedError("rk_dense_stages runs inside numba kernels only")


def _inline_dp5(expr, caller_info, callee_info) -> bool:
    """Inline the straight-line Dormand-Prince 5 step into the loop at numba-IR level (a few
    percent faster: no reference counting of its array arguments); DOP853 stays a call (its
    larger step costs compile time, and its steps are few)."""
    method = callee_info.signature.args[0]
    return isinstance(method, types.IntegerLiteral) and method.literal_value == RK45


@overload(rk_attempt, jit_options=_GEN_OPTS, inline=_inline_dp5)
def _ol_rk_attempt(method, effects, y, h, pt, K, ynew, rtol, atol):
    m = _literal(method, "method")
    n = N_ATTITUDE if _literal(effects, "effects") & ATTITUDE else N_BASE
    return _generated("attempt", m, n)


@overload(rk_dense_stages, jit_options=_GEN_OPTS)
def _ol_rk_dense_stages(method, effects, y, h, p, K, ytmp):
    return _generated("dense_stages", _literal(method, "method"), 0)


@kernel
def rk_dense(method, y, K, h, theta, out):
    """Dense output y(t + theta h), theta in [0, 1], into ``out``."""
    A, C, E, E3, P, ns, S, q = tableau(method)
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


def rk_dense_component(method, y, K, h, theta, j):
    """Component j of the dense output at theta (events that need one component only; the
    polynomial weights are unrolled from the tableau). Jit-only."""
    raise NotImplementedError("rk_dense_component runs inside numba kernels only")


@overload(rk_dense_component, jit_options=_GEN_OPTS)
def _ol_rk_dense_component(method, y, K, h, theta, j):
    return _generated("dense_component", _literal(method, "method"), 0)


@kernel
def rk_dense_rate(method, K, theta, out):
    """Time derivative [per s] of the dense output at theta, into ``out``."""
    A, C, E, E3, P, ns, S, q = tableau(method)
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
    A, C, E, E3, P, ns, S, q = tableau(method)
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
    A, C, E, E3, P, ns, S, q = tableau(method)
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


# --------------------------------------------------------------------------------------- events
@kernel
def event_value(kind, y, p):
    """Event function g(y) of an event kind; an event fires where g crosses 0 upwards
    (apsides: either way, the direction tells pericentre from apocentre)."""
    if kind == SPILL:
        return rim_margin(y, p)
    if kind == SLIP:
        return slip_margin(y, p)
    return y[2]


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
def brent_next(st, xtol):
    """Brent's zeroin step: (done, x). When not done the caller evaluates f(x) and calls
    :func:`brent_update`; when done x is the root within 2 eps |x| + xtol/2."""
    a = st[0]
    b = st[1]
    c = st[2]
    fa = st[3]
    fb = st[4]
    fc = st[5]
    d = st[6]
    e = st[7]
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
        st[0] = a
        st[1] = b
        st[2] = c
        st[3] = fa
        st[4] = fb
        st[5] = fc
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
    st[0] = a
    st[1] = b
    st[2] = c
    st[3] = fa
    st[4] = fb
    st[5] = fc
    st[6] = d
    st[7] = e
    return False, b


@kernel
def brent_update(st, fx):
    """Report f at the x that :func:`brent_next` asked for."""
    st[4] = fx


@kernel
def rk_locate(method, kind, y, K, h, p, g0, g1, buf, st):
    """theta in [0, 1] where the event function crosses 0 on the step's dense output (Brent,
    xtol 4 eps)."""
    brent_start(st, 0.0, 1.0, g0, g1)
    theta = 1.0
    for _ in range(100):
        done, theta = brent_next(st, 4.0 * EPS)
        if done:
            break
        if kind == SLIP:
            rk_dense(method, y, K, h, theta, buf)
            g = slip_margin(buf, p)
        elif kind == SPILL:
            g = rk_dense_component(method, y, K, h, theta, 0) - p[P_RIM]
        else:
            g = rk_dense_component(method, y, K, h, theta, 2)
        brent_update(st, g)
    return min(max(theta, 0.0), 1.0)


# ------------------------------------------------------------------------ start and tolerances
@kernel
def orbit_start(p, energy, h, Lz):
    """(ok, r1, r2, rc) of the bounded orbit (calE = energy [J], h [m/s], L_z): the turning
    points [m] and the circular radius [m]; ok is False when the orbit is not bounded."""
    A, B, C = coefficients(p[0], h, Lz, p[P_M], p[P_G], p[P_K])
    if not (Lz != 0.0 and math.isfinite(energy) and math.isfinite(h) and math.isfinite(Lz)):
        return False, math.nan, math.nan, math.nan
    rc = circular_radius(A, B, C)
    if math.isnan(rc):
        return False, math.nan, math.nan, rc
    r1, r2 = turning_points(energy, A, B, C, rc)
    ok = r1 > 0.0 and r2 >= r1 and math.isfinite(r2)
    return ok, r1, r2, rc


@kernel
def initial_state(p, effects, r0, energy, h, Lz):
    """State at radius r0 [m] on the orbit (calE, h, L_z): u >= 0 from the energy (0 at a
    turning point), theta = 0, attitude = identity."""
    n = state_size(effects)
    y = np.zeros(n)
    s = p[P_SIN]
    c = p[P_COS]
    M = p[P_M]
    A, B, C = coefficients(p[0], h, Lz, M, p[P_G], p[P_K])
    ke = energy - (A / (r0 * r0) + B / r0 + C * r0)
    y[0] = r0
    y[1] = 0.0
    y[2] = math.sqrt(2.0 * ke / M) if ke > 0.0 else 0.0
    y[3] = Lz / (M * r0 * s)
    y[4] = h + Lz * c / (M * r0 * s * s)
    if effects & ATTITUDE:
        y[5] = 1.0
    return y


@kernel
def tolerance_scales(p, effects, y0, energy, h, Lz, r1, r2, rc):
    """Characteristic size of each state component on the orbit (atol_i = rtol * scale_i).

    r: r1 [m]; theta: 1 rad; u: the largest radial speed sqrt(2 (calE - V_min)/M) [m/s];
    v: its smallest size |v(r2)| (v r is L_z/(M sin a), so v must stay relatively accurate for L_z
    to be conserved near the axis, where r2/r1 is huge); w: max |w| over [r1, r2]; quaternion: 1.
    Velocities are floored at sqrt(eps) times the speed, so an exactly circular orbit still has a
    usable absolute tolerance.
    """
    n = y0.shape[0]
    sc = np.ones(n)
    M = p[P_M]
    s = p[P_SIN]
    c = p[P_COS]
    A, B, C = coefficients(p[0], h, Lz, M, p[P_G], p[P_K])
    speed = math.sqrt(y0[2] ** 2 + y0[3] ** 2 + y0[4] ** 2)
    if math.isfinite(rc) and rc > 0.0:
        du = energy - (A / (rc * rc) + B / rc + C * rc)
        umax = math.sqrt(2.0 * du / M) if du > 0.0 else 0.0
    else:
        umax = max(speed, math.sqrt(2.0 * abs(energy) / M))
    vel = max(speed, umax)
    floor = SQRT_EPS * vel
    sc[0] = y0[0]
    sc[1] = 1.0
    sc[2] = max(umax, floor)
    # v = L_z/(M r sin a) carries L_z: keep it relatively accurate where it is smallest (r2).
    r_far = r2 if math.isfinite(r2) else r1
    sc[3] = max(abs(Lz / (M * r_far * s)), floor)
    w1 = abs(h + Lz * c / (M * r1 * s * s))
    w2 = abs(h + Lz * c / (M * r2 * s * s)) if math.isfinite(r2) else abs(h)
    sc[4] = max(max(w1, w2), floor)
    return sc


# ----------------------------------------------------------------------------------- the driver
@kernel
def _copy(src, dst):
    """dst[:] = src for 1-D arrays (a loop: no slicing machinery to compile)."""
    for j in range(src.shape[0]):
        dst[j] = src[j]


@kernel
def _copy_row(src, dst, row):
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
def rk_run(method, effects, y0, p, rtol, atol, t_end, n_apsides, max_steps, record, dt_out,
           ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
    """Integrate from t = 0 until t_end [s], the ``n_apsides``-th apsis (if > 0), a terminal
    event (spill, slip) or a failure.

    Events go to the preallocated ``ev_t`` [s], ``ev_kind`` (int8), ``ev_y`` (state). ``record``:
    :data:`RECORD_NONE`, :data:`RECORD_STEPS` (every accepted step) or :data:`RECORD_EVERY_DT`
    (every ``dt_out`` seconds on the dense output), into ``tr_t``, ``tr_y`` and, with the
    attitude, ``tr_rate`` (dy/dt); the first and last states are recorded in both modes. A full
    buffer stops the run with status :data:`BUFFER_FULL` (the caller retries with more room).
    Buffers are never reallocated here, so the hot loop has no reference counting.

    Returns (status, n_accepted, n_rejected, t, y, n_ev, n_tr).
    """
    A, C, E, E3, P, ns, S, q = tableau(method)
    n = state_size(effects)
    # One allocation for all work arrays (views into it).
    n_rate = n if effects & ATTITUDE else 0
    work = np.empty(S * n + 3 * n + n_rate + 8)
    K = work[: S * n].reshape((S, n))
    y = work[S * n : S * n + n]
    ynew = work[S * n + n : S * n + 2 * n]
    buf = work[S * n + 2 * n : S * n + 3 * n]  # scratch: extra stages, dense output, first step
    rate = work[S * n + 3 * n : S * n + 3 * n + n_rate]
    st = work[S * n + 3 * n + n_rate :]
    _copy(y0, y)
    cap_ev = ev_t.shape[0]
    cap_tr = tr_t.shape[0]
    n_ev = 0
    n_tr = 0
    beta = BETA[method]
    k1 = 1.0 / (q + 1) - BETA_WEIGHT[method] * beta
    k_rej = 1.0 / (q + 1)

    t = 0.0
    rhs(y, p, effects, K, 0)
    status = OK
    n_acc = 0
    n_rej = 0
    n_aps = 0
    if record != RECORD_NONE:
        if cap_tr < 1:
            return BUFFER_FULL, 0, 0, t, y, 0, 0
        tr_t[0] = t
        _copy_row(y, tr_y, 0)
        if effects & ATTITUDE:
            for j in range(n):
                tr_rate[0, j] = K[0, j]
        n_tr = 1
    next_out = dt_out
    # Terminal events already on at the start.
    if effects & RIM:
        if rim_margin(y, p) >= 0.0:
            status = SPILLED
    if effects & SLIP_CHECK:
        if status == OK and slip_margin(y, p) > 0.0:
            status = SLIPPED
    if status != OK:
        if cap_ev < 1:
            return BUFFER_FULL, 0, 0, t, y, 0, n_tr
        ev_t[0] = t
        ev_kind[0] = SPILL if status == SPILLED else SLIP
        _copy_row(y, ev_y, 0)
        return status, 0, 0, t, y, 1, n_tr
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
            if math.isnan(err) or math.isinf(err):
                h *= MIN_FACTOR
            else:
                h *= max(MIN_FACTOR, SAFETY * err ** (-k_rej))
            rejected = True
            continue
        n_acc += 1
        # PI controller for the next step.
        if err == 0.0:
            fac = MAX_FACTOR
        else:
            fac = min(MAX_FACTOR, max(MIN_FACTOR, SAFETY * err ** (-k1) * err_old**beta))
        if rejected:
            fac = min(fac, 1.0)
        rejected = False
        err_old = max(err, ERR_FLOOR)
        h_next = h * fac

        # ---- events inside (t, t + h]
        g_new = ynew[2]
        aps_cross = (g_aps > 0.0 and g_new <= 0.0) or (g_aps < 0.0 and g_new >= 0.0)
        term_cross = False
        if effects & RIM:
            if rim_margin(ynew, p) >= 0.0:
                term_cross = True
        if effects & SLIP_CHECK:
            if slip_margin(ynew, p) > 0.0:
                term_cross = True
        sample = record == RECORD_EVERY_DT and next_out <= t + h and next_out < t_end
        if method == DOP853:
            if aps_cross or term_cross or sample:
                rk_dense_stages(method, effects, y, h, p, K, buf)
        th_stop = 2.0
        stop_status = OK
        stop_kind = 0
        if term_cross:
            for kind in range(SPILL, SLIP + 1):
                if kind == SPILL and not effects & RIM:
                    continue
                if kind == SLIP and not effects & SLIP_CHECK:
                    continue
                g1 = event_value(kind, ynew, p)
                if g1 > 0.0 or (kind == SPILL and g1 == 0.0):
                    g0 = event_value(kind, y, p)
                    th = rk_locate(method, kind, y, K, h, p, g0, g1, buf, st)
                    if th < th_stop:
                        th_stop = th
                        stop_kind = kind
                        stop_status = SPILLED if kind == SPILL else SLIPPED
        if aps_cross:
            th = rk_locate(method, np.int64(PERICENTRE), y, K, h, p, y[2], g_new, buf, st)
            if th <= th_stop:
                if n_ev == cap_ev:
                    status = BUFFER_FULL
                    break
                rk_dense(method, y, K, h, th, buf)
                ev_t[n_ev] = t + th * h
                ev_kind[n_ev] = APOCENTRE if g_aps > 0.0 else PERICENTRE
                _copy_row(buf, ev_y, n_ev)
                n_ev += 1
                n_aps += 1
                g_aps = -g_aps
                if n_apsides > 0 and n_aps >= n_apsides:
                    th_stop = th
                    stop_status = OK
        if th_stop <= 1.0 and stop_status != OK:
            if n_ev == cap_ev:
                status = BUFFER_FULL
                break
            rk_dense(method, y, K, h, th_stop, buf)
            ev_t[n_ev] = t + th_stop * h
            ev_kind[n_ev] = stop_kind
            _copy_row(buf, ev_y, n_ev)
            n_ev += 1
        stopping = th_stop <= 1.0 or last

        # ---- recording
        if sample:
            t_lim = t + min(th_stop, 1.0) * h
            while next_out <= t_lim and next_out < t_end and n_tr < cap_tr:
                th = (next_out - t) / h
                tr_t[n_tr] = next_out
                rk_dense(method, y, K, h, th, buf)
                _copy_row(buf, tr_y, n_tr)
                if effects & ATTITUDE:
                    rk_dense_rate(method, K, th, buf)
                    _copy_row(buf, tr_rate, n_tr)
                n_tr += 1
                next_out = n_tr * dt_out
            if n_tr == cap_tr:
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
            if n_tr == cap_tr:
                status = BUFFER_FULL
                break
            tr_t[n_tr] = t
            _copy_row(y, tr_y, n_tr)
            if effects & ATTITUDE:
                _copy_row(rate, tr_rate, n_tr)
            n_tr += 1
        if stopping:
            status = stop_status
            break
        h = h_next
    return status, n_acc, n_rej, t, y, n_ev, n_tr

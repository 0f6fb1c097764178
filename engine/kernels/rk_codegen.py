"""Runge-Kutta code generated from tableau data, for a literal method id.

Each function here is a jit-only stub with an ``@overload`` that builds, for the literal
``method`` (a position in :data:`.tableaux.RK_TABLEAUX`) and the state size, plain Python source
with the coefficients as constants (zero terms left out), compiled by numba inside the
(disk-cached) callers. A straight-line step keeps the stages in local scalars, so the generic
stepper runs as fast as one written by hand (``scripts/bench_effects.py``). :func:`generated_source`
shows the code.

- :func:`tableau` the tableau's arrays and constants;
- :func:`rk_attempt` one step plus its error estimate (RMS norm; with a 3rd-order companion,
  Hairer's stretched norm);
- :func:`rk_stages` the stages of one step without the error estimate (compact loops);
- :func:`rk_dense_stages` the extra stages only the dense output needs;
- :func:`rk_dense_poly` the polynomial of one component's dense output (events on one
  component evaluate it by Horner's rule).
"""

from __future__ import annotations

import functools
import math

from numba.core import errors, types
from numba.extending import overload

from .layouts import N_BASE, state_size, state_size_of
from .rates import rates5, rates6, rates9, rates10, rhs
from .tableaux import RK_TABLEAUX

GEN_OPTS = {"error_model": "numpy", "fastmath": False, "nogil": True}


def _lincomb(coefs, term: str) -> str:
    """Source of sum_m coefs[m] * term.format(m=m) over the nonzero coefficients."""
    out = [f"{float(c)!r} * {term.format(m=m)}" for m, c in enumerate(coefs) if c != 0.0]
    return " + ".join(out) if out else "0.0"


def _norm_lines(stretched: bool, n: str, ind: str = "    ") -> list[str]:
    """Lines that set ``err`` from the sums e5 (and e3): the RMS norm, or Hairer's stretched
    norm (0 where both sums are 0)."""
    if stretched:
        return [
            f"{ind}err = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * {n})"
            " if (e5 != 0.0 or e3 != 0.0) else 0.0"
        ]
    return [f"{ind}err = abs(h) * math.sqrt(e5 / {n})"]


def _attempt_source_loops(method: int) -> str:
    """Like :func:`_attempt_source` with a loop over the components (less code to compile)."""
    tb = RK_TABLEAUX[method]
    A, E, E3, ns = tb.A, tb.E, tb.E3, tb.n_stages
    stretched = bool(E3.any())
    lines = ["def impl(method, effects, y, h, pt, K, ynew, rtol, atol):", "    n = y.shape[0]"]
    for i in range(1, ns + 1):
        lines += [
            "    for j in range(n):",
            f"        ynew[j] = y[j] + h * ({_lincomb(A[i, :i], 'K[{m}, j]')})",
            f"    rhs(ynew, pt, effects, K, {i})",
        ]
    lines += ["    e5 = 0.0", "    e3 = 0.0", "    for j in range(n):"]
    lines += ["        sc = atol[j] + rtol * max(abs(y[j]), abs(ynew[j]))"]
    lines += [f"        d = ({_lincomb(E, 'K[{m}, j]')}) / sc", "        e5 += d * d"]
    if stretched:
        lines += [f"        d = ({_lincomb(E3, 'K[{m}, j]')}) / sc", "        e3 += d * d"]
    return "\n".join(lines + _norm_lines(stretched, "n") + ["    return err"]) + "\n"


def unrolled_step_lines(method: int, n: int, load, store, ind: str) -> list[str]:
    """Straight-line source of one step of the pair ``method`` on n components: the stages in
    local scalars, then ``err`` (the scaled error estimate). ``load(kind, j)`` is the source of
    the input ``kind`` ("y", "k0", "atol") of component j; ``store(i, j, value)`` the statement
    that saves stage i (ns: f(y_new); "y": y_new) of component j. Used by the scalar step here
    and by the lanes step (:mod:`.lanes`), so both do the very same arithmetic."""
    tb = RK_TABLEAUX[method]
    A, E, E3, ns = tb.A, tb.E, tb.E3, tb.n_stages
    stretched = bool(E3.any())
    comps = range(n)
    rates = f"rates{n}"
    lines = [f"{ind}y_{j} = {load('y', j)}" for j in comps]
    lines += [f"{ind}k0_{j} = {load('k0', j)}" for j in comps]
    for i in range(1, ns + 1):
        args = [f"y_{j} + h * ({_lincomb(A[i, :i], 'k{m}_' + str(j))})" for j in comps]
        if i == ns:
            lines += [f"{ind}n_{j} = {args[j]}" for j in comps]
            lines += [f"{ind}{store('y', j, f'n_{j}')}" for j in comps]
            args = [f"n_{j}" for j in comps]
        targets = ", ".join(f"k{i}_{j}" for j in comps)
        lines.append(f"{ind}{targets} = {rates}({', '.join(args)}, pt, effects)")
    lines += [f"{ind}{store(i, j, f'k{i}_{j}')}" for i in range(1, ns + 1) for j in comps]
    lines += [f"{ind}e5 = 0.0", f"{ind}e3 = 0.0"]
    for j in comps:
        lines.append(f"{ind}sc = {load('atol', j)} + rtol * max(abs(y_{j}), abs(n_{j}))")
        lines.append(f"{ind}d = ({_lincomb(E, 'k{m}_' + str(j))}) / sc")
        lines.append(f"{ind}e5 += d * d")
        if stretched:
            lines.append(f"{ind}d = ({_lincomb(E3, 'k{m}_' + str(j))}) / sc")
            lines.append(f"{ind}e3 += d * d")
    return lines + _norm_lines(stretched, str(n), ind)


_SCALAR_LOAD = {"y": "y[{j}]", "k0": "K[0, {j}]", "atol": "atol[{j}]"}


def _scalar_store(i, j: int, value: str) -> str:
    return f"ynew[{j}] = {value}" if i == "y" else f"K[{i}, {j}] = {value}"


def _attempt_source(method: int, n: int) -> str:
    """Source of ``impl(method, effects, y, h, pt, K, ynew, rtol, atol) -> err``: one step of
    size h from y with K[0] = f(y); writes the stages K[1..ns], y_new and K[ns] = f(y_new).
    Straight-line code on scalars where the tableau says ``unroll``, else loops."""
    if not RK_TABLEAUX[method].unroll:
        return _attempt_source_loops(method)
    lines = ["def impl(method, effects, y, h, pt, K, ynew, rtol, atol):"]
    load = lambda kind, j: _SCALAR_LOAD[kind].format(j=j)  # noqa: E731
    lines += unrolled_step_lines(method, n, load, _scalar_store, "    ")
    return "\n".join(lines + ["    return err"]) + "\n"


def _stages_source(method: int) -> str:
    """Source of ``impl(method, effects, y, h, pt, K, ynew)``: the stages of one step (loops
    over the components, no error estimate): y_new and K[ns] = f(y_new)."""
    tb = RK_TABLEAUX[method]
    lines = ["def impl(method, effects, y, h, pt, K, ynew):", "    n = y.shape[0]"]
    for i in range(1, tb.n_stages + 1):
        lines += [
            "    for j in range(n):",
            f"        ynew[j] = y[j] + h * ({_lincomb(tb.A[i, :i], 'K[{m}, j]')})",
            f"    rhs(ynew, pt, effects, K, {i})",
        ]
    return "\n".join(lines) + "\n"


def _dense_stages_source(method: int) -> str:
    """Source of ``impl(method, effects, y, h, p, K, ytmp)``: the extra stages (array form)."""
    tb = RK_TABLEAUX[method]
    A, ns = tb.A, tb.n_stages
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


def _dense_poly_source(method: int) -> str:
    """Source of ``impl(method, K, j)``: the coefficients c_m = sum_i P[i, m] K[i, j] of
    component j's dense output y_j + h sum_m c_m theta^(m+1), as a tuple."""
    P = RK_TABLEAUX[method].P
    terms = [_lincomb(P[:, m], "K[{m}, j]") for m in range(P.shape[1])]
    return "def impl(method, K, j):\n    return (" + ", ".join(terms) + ",)\n"


def _tableau_source(method: int) -> str:
    """Source of ``impl(method)``: the tableau's arrays (frozen globals) and its constants."""
    tb = RK_TABLEAUX[method]
    consts = (tb.n_stages, tb.A.shape[0], tb.error_order, float(tb.beta), float(tb.beta_weight),
              float(tb.max_factor))  # fmt: skip
    return "def impl(method):\n    return T_A, T_C, T_E, T_E3, T_P, " + ", ".join(map(repr, consts))


def _controller_source(method: int) -> str:
    """Source of ``impl(method)``: the controller's constants (:meth:`.Tableau.controller`)."""
    consts = ", ".join(map(repr, RK_TABLEAUX[method].controller()))
    return f"def impl(method):\n    return ({consts})\n"


_SOURCES = {
    "attempt": lambda method, n: _attempt_source(method, n),
    "stages": lambda method, n: _stages_source(method),
    "dense_stages": lambda method, n: _dense_stages_source(method),
    "dense_poly": lambda method, n: _dense_poly_source(method),
    "tableau": lambda method, n: _tableau_source(method),
    "controller": lambda method, n: _controller_source(method),
}


def generated_source(kind: str, method: int, n: int = N_BASE) -> str:
    """The generated source of a kernel: "attempt" (step + error), "stages" (step only),
    "dense_stages", "dense_poly", "tableau" or "controller"."""
    return _SOURCES[kind](method, n)


@functools.cache
def _generated(kind: str, method: int, n: int):
    src = generated_source(kind, method, n)
    tb = RK_TABLEAUX[method]
    namespace = {
        "math": math,
        "rhs": rhs,
        "rates5": rates5,
        "rates6": rates6,
        "rates9": rates9,
        "rates10": rates10,
        "state_size": state_size,
        "T_A": tb.A,
        "T_C": tb.C,
        "T_E": tb.E,
        "T_E3": tb.E3,
        "T_P": tb.P,
    }
    exec(compile(src, f"<conesurvey {kind} method={method} n={n}>", "exec"), namespace)  # noqa: S102
    return namespace["impl"]


def literal_int(arg, name: str) -> int:
    if not isinstance(arg, types.IntegerLiteral):
        raise errors.TypingError(f"{name} must be a numba literal here (use numba.literally)")
    return int(arg.literal_value)


def rk_method_id(arg) -> int:
    m = literal_int(arg, "method")
    if not 0 <= m < len(RK_TABLEAUX):
        raise errors.TypingError(f"no Runge-Kutta tableau with id {m}")
    return m


def tableau(method):
    """(A, C, E, E3, P, n_stages, n_all_stages, error_order, beta, beta_weight, max_factor) of
    the Runge-Kutta pair ``method`` (literal). Jit-only."""
    raise NotImplementedError("tableau runs inside numba kernels only")


def controller(method):
    """(k1, k_rej, beta, max_factor) of the pair ``method`` (literal), as constants
    (:meth:`.tableaux.Tableau.controller`). Jit-only."""
    raise NotImplementedError("controller runs inside numba kernels only")


def rk_attempt(method, effects, y, h, pt, K, ynew, rtol, atol):
    """Attempt one step of size h [s] from y with K[0] = f(y) given; returns the scaled error
    estimate (accept when <= 1). ``pt`` is the parameter tuple (:func:`.model.param_tuple`:
    read once, kept in registers). Writes the stages K[1..ns], ``ynew`` and K[ns] = f(ynew)
    (first same as last). Jit-only."""
    raise NotImplementedError("rk_attempt runs inside numba kernels only")


def rk_stages(method, effects, y, h, pt, K, ynew):
    """The stages of one step of size h [s] from y with K[0] = f(y) given, without an error
    estimate: writes ``ynew`` and K[1..ns] (K[ns] = f(ynew)). Compact loops (for the rare
    extra step that polishes an event). Jit-only."""
    raise NotImplementedError("rk_stages runs inside numba kernels only")


def rk_dense_stages(method, effects, y, h, p, K, ytmp):
    """The extra stages the dense output needs (DOP853: 3; Dormand-Prince 5: none). Jit-only."""
    raise NotImplementedError("rk_dense_stages runs inside numba kernels only")


def rk_dense_poly(method, K, j):
    """(c_1, ..., c_deg): component j of the dense output is y_j + h sum_m c_m theta^m
    (events that need one component only). Jit-only."""
    raise NotImplementedError("rk_dense_poly runs inside numba kernels only")


def _inline_unrolled(expr, caller_info, callee_info) -> bool:
    """Inline a straight-line step into the loop at numba-IR level (a few percent faster: no
    reference counting of its array arguments); a looped step stays a call (it costs compile
    time, and its steps are few)."""
    method = callee_info.signature.args[0]
    return isinstance(method, types.IntegerLiteral) and RK_TABLEAUX[method.literal_value].unroll


@overload(tableau, jit_options=GEN_OPTS)
def _ol_tableau(method):
    return _generated("tableau", rk_method_id(method), 0)


@overload(controller, jit_options=GEN_OPTS)
def _ol_controller(method):
    return _generated("controller", rk_method_id(method), 0)


@overload(rk_attempt, jit_options=GEN_OPTS, inline=_inline_unrolled)
def _ol_rk_attempt(method, effects, y, h, pt, K, ynew, rtol, atol):
    m = rk_method_id(method)
    n = state_size_of(literal_int(effects, "effects"))
    return _generated("attempt", m, n)


@overload(rk_stages, jit_options=GEN_OPTS)
def _ol_rk_stages(method, effects, y, h, pt, K, ynew):
    return _generated("stages", rk_method_id(method), 0)


@overload(rk_dense_stages, jit_options=GEN_OPTS)
def _ol_rk_dense_stages(method, effects, y, h, p, K, ytmp):
    return _generated("dense_stages", rk_method_id(method), 0)


@overload(rk_dense_poly, jit_options=GEN_OPTS)
def _ol_rk_dense_poly(method, K, j):
    return _generated("dense_poly", rk_method_id(method), 0)

"""Code without branches or library calls, for the loops over the SIMD lanes: a select
(:func:`pick`), bit casts, and x ** a (:func:`power`) for the step-size control of the
Runge-Kutta runs.

A loop over the lanes (:mod:`.lanes_step`) becomes one vector loop only if its body is one
straight line: ``a if c else b`` is a branch in numba's code, and where one side is a load, a
store or more than a few instructions the compiler keeps it (a store of ``W[i] if c else
W[j]`` into ``W[i]`` becomes a store under a branch): :func:`pick` is a select instruction,
:func:`keep` one whose result goes back where its second value came from.
The PI controller takes two powers a step (the error's root and the previous error's weight,
:mod:`.rk`). The C library's ``pow`` is a call: it keeps every loop it stands in scalar, and on
the SIMD lanes (:mod:`.lanes_step`) four calls a step cost as much as a third of the
vectorised step. :func:`power` is exp(a log x) written as arithmetic and bit operations only
(the log and exp of fdlibm, as in FreeBSD's and musl's libm: polynomials after an exact
reduction by powers of two), so a loop over the lanes that takes it is one vector loop, and
the scalar run and the lanes compute the same bits (no fast-math: every operation is IEEE's).

Accuracy: log and exp within 1 ulp each; x ** a within (2 + |a log x|) ulp relative, for
x >= 0 (subnormals too) and |a log x| <= 700 (tests/kernels/test_powers.py); x = 0 and inf
give what ``x ** a`` gives, NaN and x < 0 NaN.
"""

from __future__ import annotations

import math

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from .._jit import kernel


@intrinsic
def pick(typingctx, c, a, b):
    """``a if c else b`` as one select instruction: both a and b are evaluated, no branch."""
    if not isinstance(c, types.Boolean):
        return None
    ty = typingctx.unify_types(a, b)
    if not isinstance(ty, (types.Float, types.Integer, types.Boolean)):
        return None

    def codegen(context, builder, sig, args):
        ty = sig.return_type
        a_v = context.cast(builder, args[1], sig.args[1], ty)
        b_v = context.cast(builder, args[2], sig.args[2], ty)
        return builder.select(args[0], a_v, b_v)

    return ty(c, a, b), codegen


@intrinsic
def keep(typingctx, c, new, old):
    """``new if c else old`` for a value stored back where ``old`` was loaded: a select the
    compiler cannot turn into a masked store (``old`` passes a freeze), which AMD's Zen
    microcodes (vmaskmovpd: a dozen times a plain store's cost)."""
    if not isinstance(c, types.Boolean) or new != old:
        return None

    def codegen(context, builder, sig, args):
        frozen = ir.Instruction(builder.block, args[2].type, "freeze", [args[2]])
        builder._insert(frozen)
        return builder.select(args[0], args[1], frozen)

    return old(c, new, old), codegen


@intrinsic
def float_bits(typingctx, x):
    """The bits of a float64 as an int64 (a bitcast: one register move, also on vectors)."""
    if x != types.float64:
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(x), codegen


@intrinsic
def bits_float(typingctx, i):
    """The float64 whose bits are the int64 i."""
    if not isinstance(i, types.Integer) or i.bitwidth != 64:
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(i), codegen


# fdlibm's e_log.c: ln 2 in two parts and the minimax polynomial of (log(1+f) - f + f^2/2)/s.
LN2_HI = 6.93147180369123816490e-01
LN2_LO = 1.90821492927058770002e-10
LG1 = 6.666666666666735130e-01
LG2 = 3.999999999940941908e-01
LG3 = 2.857142874366239149e-01
LG4 = 2.222219843214978396e-01
LG5 = 1.818357216161805012e-01
LG6 = 1.531383769920937332e-01
LG7 = 1.479819860511658591e-01
# fdlibm's e_exp.c: the minimax polynomial of x (e^x + 1)/(e^x - 1) - 2 around 0.
P1 = 1.66666666666666019037e-01
P2 = -2.77777777770155933842e-03
P3 = 6.61375632143793436117e-05
P4 = -1.65339022054652515390e-06
P5 = 4.13813679705723846039e-08
INV_LN2 = 1.44269504088896338700e00
#: 1.5 2^52: adding and subtracting it rounds a float below 2^51 to the nearest integer, and
#: the sum's low bits hold that integer.
ROUNDER = 6755399441055744.0
ROUNDER_BITS = 0x4338000000000000
TINY = 2.2250738585072014e-308  # the smallest normal float64
TWO54 = 1.8014398509481984e16


@kernel(inline="always")
def log_positive(x):
    """log(x) for a positive finite x (fdlibm's log, without branches)."""
    sub = x < TINY
    x = pick(sub, x * TWO54, x)
    ix = float_bits(x) + 0x00095F6200000000  # mantissas above sqrt(2) move to the next octave
    e = ix >> 52  # biased exponent (1 ... 2046): its float through the integer's bits
    k = bits_float(ROUNDER_BITS | e) - (ROUNDER + 1023.0) - pick(sub, 54.0, 0.0)
    f = bits_float((ix & 0x000FFFFFFFFFFFFF) + 0x3FE6A09E00000000) - 1.0  # in [-0.29, 0.41]
    hfsq = 0.5 * f * f
    s = f / (2.0 + f)
    z = s * s
    w = z * z
    t1 = w * (LG2 + w * (LG4 + w * LG6))
    t2 = z * (LG1 + w * (LG3 + w * (LG5 + w * LG7)))
    return s * (hfsq + (t2 + t1)) + k * LN2_LO - hfsq + f + k * LN2_HI


@kernel(inline="always")
def exp_bounded(x):
    """exp(x) for |x| <= 700 (fdlibm's exp, without branches)."""
    t = x * INV_LN2 + ROUNDER
    k = t - ROUNDER  # x / ln 2 rounded to an integer
    ki = float_bits(t) - ROUNDER_BITS
    hi = x - k * LN2_HI
    lo = k * LN2_LO
    r = hi - lo  # |r| <= ln(2) / 2
    rr = r * r
    c = r - rr * (P1 + rr * (P2 + rr * (P3 + rr * (P4 + rr * P5))))
    y = 1.0 + ((r * c) / (2.0 - c) - lo + hi)
    return y * bits_float((ki + 1023) << 52)


@kernel(inline="always")
def power(x, a):
    """x ** a for x >= 0 (a: best a compile-time constant), without a library call: the
    step-size control's powers (module docstring)."""
    r = exp_bounded(min(700.0, max(-700.0, a * log_positive(x))))
    at_0 = pick(a == 0.0, 1.0, pick(a < 0.0, math.inf, 0.0))
    at_inf = pick(a < 0.0, 0.0, pick(a == 0.0, 1.0, math.inf))
    r = pick(x == 0.0, at_0, pick(x == math.inf, at_inf, r))
    return pick(x >= 0.0, r, math.nan)

"""Circular radius and turning points of V(r) = A/r^2 + B/r + C r, in numba.

The circular radius r_c is the positive root of C r^3 - B r - 2A. In units of
q = (2A/C)^(1/3) it is the root t(b) of t^3 - b t - 1 with b = B/(C q^2); a start from
t ~ 1/sqrt(1 + b^2) (b < 0) or sqrt(b + 1/(1 + b/2)) (b >= 0), within 7 %, and an estimate of
q from the bits of 2A/C (within 6 %) leave Halley's method about three steps.

The turning points are the positive roots of C r^3 - energy r^2 + B r + A. A naive cubic
formula loses half the digits near the circular limit, where the two roots merge. Instead
both roots are found from the factorised excess over the minimum,

    r^2 (V(r) - energy) = (r - r_c)^2 (C r + A/r_c^2) - delta r^2,    delta = energy - V_min,

(exact when r_c is the root of C r^3 - B r - 2A), by Halley's method on the right-hand side,
a cubic that is small only where the excess is: the gap r2 - r1 is as accurate as
energy - V_min itself, i.e. as the problem's conditioning allows. With x = r - r_c,
sigma = sqrt(delta / (C r_c + A/r_c^2)) and c3 = C r_c / (C r_c + A/r_c^2) the roots are
x/r_c = +-sigma + (1 - c3/2) sigma^2 + O(sigma^3) near the circular limit; far from it
r1 ~ sqrt(A/delta) and r2 solves the quadratic the cubic becomes for large x. Both roots are
iterated together (two independent dependency chains overlap in the CPU). Each root is then
checked against energy = V(r) to rounding; one that fails (a very deep well, where the
factorised excess is all rounding, or a radius beyond the range of r^2) is solved on the
monotone side of the well by bracketed Newton, or is NaN. Free fall (C = 0) has closed
forms, written without cancellation.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel

_EPS = 2.220446049250313e-16
_MAX_NEWTON = 80
_MAX_HALLEY = 8
#: Unconditional Halley steps: RC_STEPS for r_c (from within ~15 %), TP_STEPS for each
#: turning point (module docstring); a root not converged after them takes the safe path.
RC_STEPS = 3
TP_STEPS = 3
#: A Halley step shorter than HALLEY_STOP times the root's scale ends the iteration: the
#: method's error after it is ~HALLEY_STOP^3 of that scale (below rounding).
HALLEY_STOP = 1e-6
#: Polish a turning point on energy - V(r) only where V there is evaluated with POLISH_GAIN
#: times less rounding than the excess over V_min (where both are alike, polishing only adds
#: the noise of Newton's method on a flat function).
POLISH_GAIN = 4.0
#: Where 2A/C lies outside this range the bit-level cube-root estimate is not used.
_Q3_RANGE = (1e-300, 1e300)


@kernel
def _cbrt_estimate(x):
    """x^(1/3) within 6 % for a normal x > 0, from its bits (exponent / 3)."""
    i = np.float64(x).view(np.int64)
    return np.int64(i // 3 + np.int64(0x2A9F7893782DA1CE)).view(np.float64)


@kernel
def cbrt(x):
    """x^(1/3) to ~1e-14 relative, x > 0: the bit-level estimate and two Halley steps
    (y <- y (y^3 + 2x) / (2 y^3 + x)); ``x ** (1/3)`` outside the range of the estimate."""
    if not (_Q3_RANGE[0] < x < _Q3_RANGE[1]):
        return x ** (1.0 / 3.0)
    y = _cbrt_estimate(x)
    for _ in range(2):
        y3 = y * y * y
        y *= (y3 + 2.0 * x) / (2.0 * y3 + x)
    return y


@kernel
def _circular_radius_newton(A, B, C):
    """Root of C r^3 - B r - 2A by Newton's method from an upper bound (monotone: the cubic is
    convex for r > 0); the safe path for extreme scales and the fallback."""
    q = (2.0 * A / C) ** (1.0 / 3.0)
    if B < 0.0:
        r = min(q, -2.0 * A / B)
    else:
        r = math.sqrt(B / C) + q
    for _ in range(_MAX_NEWTON):
        f = (C * r * r - B) * r - 2.0 * A
        if f <= 0.0:
            break
        fp = 3.0 * C * r * r - B
        rn = r - f / fp
        if not rn < r:
            break
        r = rn
    return r


@kernel
def rc_eligible(A, C):
    """Whether :func:`circular_radius` takes its fast path (Halley from an estimate): A > 0,
    C > 0 and 2A/C within the range of the bit-level cube root."""
    q3 = 2.0 * A / C
    return A > 0.0 and C > 0.0 and _Q3_RANGE[0] < q3 < _Q3_RANGE[1]


@kernel
def rc_start(A, B, C):
    """Start of the Halley iteration for r_c (module docstring), within ~15 %."""
    q = _cbrt_estimate(2.0 * A / C)
    b = B / (C * q * q)
    if b < 0.0:
        return q / math.sqrt(1.0 + b * b)
    return q * math.sqrt(b + 1.0 / (1.0 + 0.5 * b))


@kernel
def rc_step(r, A, B, C):
    """One Halley step on C r^3 - B r - 2A: (new r, step taken)."""
    cr2 = C * r * r
    f = (cr2 - B) * r - 2.0 * A
    fp = 3.0 * cr2 - B
    dr = f * fp / (fp * fp - 3.0 * f * C * r)  # f f' / (f'^2 - f f''/2)
    return r - dr, dr


@kernel
def rc_finish(r, dr, A, B, C):
    """r_c after the RC_STEPS unconditional steps: more steps until one is below HALLEY_STOP
    (converged: the error is then ~HALLEY_STOP^3 r), else the monotone Newton iteration."""
    for _ in range(_MAX_HALLEY):
        if abs(dr) <= HALLEY_STOP * r:
            return r
        r, dr = rc_step(r, A, B, C)
    return _circular_radius_newton(A, B, C)


@kernel
def circular_radius(A, B, C):
    """Radius [m] where V has its minimum: positive root of C r^3 - B r - 2A; NaN if none.

    Requires A > 0. Under gravity (C > 0) the root is unique; in free fall (C = 0) it is
    -2A/B for B < 0 and there is none for B >= 0.
    """
    if not A > 0.0:
        return math.nan
    if C == 0.0:
        return -2.0 * A / B if B < 0.0 else math.nan
    if not rc_eligible(A, C):
        return _circular_radius_newton(A, B, C)
    r = rc_start(A, B, C)
    dr = math.inf
    # RC_STEPS steps without an exit test: a loop exit taken at a data-dependent step costs
    # more than a step, and the batch kernels take these steps over lanes of points.
    for _ in range(RC_STEPS):
        r, dr = rc_step(r, A, B, C)
    return rc_finish(r, dr, A, B, C)


@kernel
def well(A, B, C, rc):
    """What the turning points need of the potential alone (the same for every energy):
    (a = A/r_c^2, V_min, c3 = C r_c / (C r_c + a), 1 / (C r_c + a), noise), where noise =
    a + |B|/r_c + C r_c is the size of the terms of V_min."""
    a = A / (rc * rc)
    b = B / rc
    c = C * rc
    vmin = a + b + c
    gam = c + a
    return a, vmin, c / gam, 1.0 / gam, a + abs(b) + c


@kernel
def tp_step(r, rc, C, a, delta):
    """One Halley step on phi(r) = (r - rc)^2 (C r + a) - delta r^2 = r^2 (V(r) - energy):
    (new r, converged), converged when the step is below HALLEY_STOP of the root's scale
    min(r, |r - rc|)."""
    x = r - rc
    w = C * r + a
    phi = x * x * w - delta * r * r
    d1 = 2.0 * x * w + C * x * x - 2.0 * delta * r
    d2 = 2.0 * w + 4.0 * C * x - 2.0 * delta
    dr = phi * d1 / (d1 * d1 - 0.5 * phi * d2)
    return r - dr, abs(dr) <= HALLEY_STOP * min(r, abs(x))


@kernel
def tp_accept(r, done, rc, inner):
    """Whether a converged Halley iterate is the wanted root: the inner one lies in (0, rc),
    the outer one in (rc, inf) (phi has one root in each)."""
    if inner:
        return done and 0.0 < r < rc
    return done and rc < r < math.inf


@kernel
def _safe_step(r, rc, C, a, delta, lo, hi, inner):
    """A Halley step kept in the bracket (lo, hi) of the root: phi > 0 outside [r1, r2], so
    the bracket shrinks with the sign of phi; a step leaving it is replaced by bisection
    (geometric when the bracket spans decades, doubling while it is open). Returns (new r,
    lo, hi, converged)."""
    x = r - rc
    phi = x * x * (C * r + a) - delta * r * r
    if phi == 0.0:
        return r, lo, hi, True
    if (phi > 0.0) == inner:  # r lies below the root
        lo = r
    else:
        hi = r
    rn, done = tp_step(r, rc, C, a, delta)
    if done or lo < rn < hi:
        return rn, lo, hi, done
    if math.isinf(hi):
        rn = 2.0 * r
    elif hi > 4.0 * lo:
        rn = math.sqrt(lo * hi) if lo > 0.0 else 0.25 * hi
    else:
        rn = 0.5 * (lo + hi)
    return rn, lo, hi, not (lo < rn < hi)


@kernel
def tp_safe(r, rc, C, a, delta, inner):
    """The root (inner: r1 in (0, rc), else r2 in (rc, inf)) by safeguarded Halley steps
    from r: the path of a root that TP_STEPS plain steps did not settle."""
    lo, hi = (0.0, rc) if inner else (rc, math.inf)
    for _ in range(_MAX_NEWTON):
        r, lo, hi, done = _safe_step(r, rc, C, a, delta, lo, hi, inner)
        if done:
            return r
    return math.nan  # not converged: never a silently wrong root (tp_final solves it anew)


@kernel
def polish(r, energy, A, B, C, noise_c, lo, hi):
    """Newton on energy - V(r) from r, kept inside (lo, hi), if V at r is evaluated with
    POLISH_GAIN times less rounding (|A|/r^2 + |B|/r + C r + |energy|) than the excess over
    V_min (``noise_c``)."""
    if POLISH_GAIN * (A + (abs(B) + (C * r + abs(energy)) * r) * r) >= noise_c * r * r:
        return r
    for _ in range(_MAX_NEWTON):
        ir = 1.0 / r
        f = energy - (A * ir * ir + B * ir + C * r)
        fp = 2.0 * A * ir * ir * ir + B * ir * ir - C
        if fp == 0.0:
            return r
        rn = r - f / fp
        if not (lo < rn < hi):
            return r
        if abs(rn - r) <= 2.0 * _EPS * rn:
            return rn
        r = rn
    return r


@kernel
def tp_starts(rc, a, delta, c3, igam):
    """Starting points (r1, r2) of the Halley iterations (module docstring)."""
    eps = delta * igam
    sig = math.sqrt(eps)
    if sig < 1.0:
        k2 = 1.0 - 0.5 * c3
        q2 = k2 * sig * sig
        q3 = (k2 * (1.0 - c3) + 0.125 * c3 * c3) * sig * sig * sig
        r1 = rc * (1.0 - sig + q2 - q3)
        r2 = rc * (1.0 + sig + q2 + q3)
        if 0.0 < r1 < rc:
            return r1, r2
    s1 = math.sqrt(a / delta)  # sqrt((1 - c3) / eps)
    r1 = rc * s1 / (1.0 + s1)
    d = 1.0 - eps
    disc = math.sqrt(d * d + 8.0 * c3 * eps)
    xf = (disc - d) / (2.0 * c3) if d < 0.0 else 4.0 * eps / (d + disc)
    r2 = rc * (1.0 + max(sig, xf))
    return r1, r2 if r2 < math.inf else rc * (1.0 + sig)


@kernel
def turning_points_in(energy, A, B, C, rc, a, vmin, c3, igam, noise):
    """:func:`turning_points` given the potential's :func:`well` ``(a, vmin, c3, igam,
    noise)`` (C > 0): TP_STEPS Halley steps on both roots side by side (two independent
    dependency chains overlap in the CPU), the safe path for a root they did not settle, the
    polish."""
    delta = energy - vmin
    if not delta >= 0.0:
        return math.nan, math.nan
    g1, g2 = tp_starts(rc, a, delta, c3, igam)
    r1, r2, d1, d2 = g1, g2, False, False
    for _ in range(TP_STEPS):
        r1, d1 = tp_step(r1, rc, C, a, delta)
        r2, d2 = tp_step(r2, rc, C, a, delta)
    if not tp_accept(r1, d1, rc, True):
        r1 = tp_safe(g1, rc, C, a, delta, True)
    if not tp_accept(r2, d2, rc, False):
        r2 = tp_safe(g2, rc, C, a, delta, False)
    return tp_final(r1, r2, energy, A, B, C, rc, abs(energy) + noise)


@kernel
def turning_points(energy, A, B, C, rc):
    """Inner and outer turning points (r1, r2) [m] of a bounded orbit, energy > V(rc).

    ``rc`` is :func:`circular_radius`. For C = 0 (free fall, B < 0, energy < 0) the closed
    form is used. Returns NaN where the inputs do not describe a bounded orbit.
    """
    if C == 0.0:
        # |energy| r^2 + B r + A = 0 with B < 0: stable quadratic formula; disc = 4 A delta.
        delta = energy + B * B / (4.0 * A)
        if not (B < 0.0 and energy < 0.0 and delta >= 0.0):
            return math.nan, math.nan
        sq = math.sqrt(4.0 * A * delta)
        big = sq - B
        return 2.0 * A / big, big / (-2.0 * energy)
    a, vmin, c3, igam, noise = well(A, B, C, rc)
    return turning_points_in(energy, A, B, C, rc, a, vmin, c3, igam, noise)


@kernel
def _is_root(r, energy, A, B, C):
    """Whether energy - V(r) vanishes to rounding (64 eps of the terms' sizes)."""
    ir = 1.0 / r
    scale = A * ir * ir + abs(B) * ir + C * r + abs(energy)
    return abs(energy - (A * ir * ir + B * ir + C * r)) <= 64.0 * _EPS * scale


@kernel
def _above_outer(energy, A, B, C, rc):
    """A radius beyond the outer turning point (V > energy there)."""
    r = max(2.0 * rc, energy / C if energy > 0.0 else 0.0)
    for _ in range(2100):
        if A / (r * r) + B / r + C * r > energy:
            break
        r *= 2.0
    return r


@kernel
def _bracketed(energy, A, B, C, lo, hi):
    """The root of V(r) = energy in (lo, hi), where V is monotone: safeguarded Newton with
    (geometric) bisection; NaN unless it converges to a root."""
    glo = energy - (A / (lo * lo) + B / lo + C * lo)
    r = math.sqrt(lo * hi) if lo > 0.0 and hi > 4.0 * lo else 0.5 * (lo + hi)
    for _ in range(4 * _MAX_NEWTON):
        ir = 1.0 / r
        g = energy - (A * ir * ir + B * ir + C * r)
        if (g > 0.0) == (glo > 0.0):
            lo = r
        else:
            hi = r
        gp = 2.0 * A * ir * ir * ir + B * ir * ir - C
        rn = r - g / gp if gp != 0.0 else math.nan
        if not (lo < rn < hi):
            rn = math.sqrt(lo * hi) if lo > 0.0 and hi > 4.0 * lo else 0.5 * (lo + hi)
        if abs(rn - r) <= 2.0 * _EPS * r:
            return rn if _is_root(rn, energy, A, B, C) else math.nan
        r = rn
    return math.nan


@kernel
def tp_final(r1, r2, energy, A, B, C, rc, noise_c):
    """The turning points (r1, r2) from the Halley iterates: polished, then checked as roots.

    The excess energy - V_min carries a rounding error of eps |V_min| (plus the terms of V at
    r_c, ``noise_c``); where V is evaluated more accurately at the root itself (a deep narrow
    well: |V_min| >> |V(r)|), polish on energy - V(r) directly. Where the factorised excess is
    dominated by rounding (a very deep well) or the iteration did not converge (NaN), solve
    V(r) = energy on the monotone side of the well instead; NaN if even that fails.
    """
    r1 = polish(r1, energy, A, B, C, noise_c, 0.0, rc)
    r2 = polish(r2, energy, A, B, C, noise_c, rc, math.inf)
    if not _is_root(r1, energy, A, B, C):
        # A/r1^2 = energy - B/r1 - C r1 <= |energy| + |B|/r1 bounds r1 from below.
        lo1 = 2.0 * A / (abs(B) + math.hypot(B, 2.0 * math.sqrt(A) * math.sqrt(abs(energy))))
        r1 = _bracketed(energy, A, B, C, lo1, rc)
    if not _is_root(r2, energy, A, B, C):
        r2 = _bracketed(energy, A, B, C, rc, _above_outer(energy, A, B, C, rc))
    return r1, r2


@kernel
def free_fall_r_min(energy, A, B):
    """Pericentre [m] of an escaping free-fall orbit (energy >= 0): root of energy r^2 - B r - A."""
    root = math.hypot(B, 2.0 * math.sqrt(A) * math.sqrt(energy))  # sqrt(B^2 + 4 A E), no underflow
    if B > 0.0:
        return (B + root) / (2.0 * energy)
    return 2.0 * A / (root - B)

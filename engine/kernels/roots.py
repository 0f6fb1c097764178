"""Circular radius and turning points of V(r) = A/r^2 + B/r + C r, in numba.

The turning points are the positive roots of C r^3 - energy r^2 + B r + A. A naive cubic
formula loses half the digits near the circular limit, where the two roots merge. Instead
both roots are found from the factorised excess over the minimum,

    V(r) - V(r_c) = (r - r_c)^2 G(r),    G(r) = C/r + A/(r^2 r_c^2) > 0,

(exact when r_c is the root of C r^3 - B r - 2A), by Newton's method on the monotone function
F(r) = (r - r_c) sqrt(G(r)) = +-sqrt(energy - V_min). The gap r2 - r1 is then as accurate as
energy - V_min itself, i.e. as the problem's conditioning allows. Free fall (C = 0) has closed
forms, written without cancellation.
"""

from __future__ import annotations

import math

from .._jit import kernel

_EPS = 2.220446049250313e-16
_MAX_NEWTON = 80


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
    # Start from an upper bound: the cubic is convex for r > 0, so Newton decreases monotonically.
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
def _newton_step(target, rc, irc2, A, C, lo, hi, r):
    """One safeguarded Newton step on F(r) = (r - rc) sqrt(C/r + A/(r^2 rc^2)) = target.

    F is increasing; the bracket (lo, hi) shrinks with the sign of F, and a step leaving it
    is replaced by bisection (geometric when the bracket spans decades). Returns
    (new r, lo, hi, converged).
    """
    ir = 1.0 / r
    GA = A * ir * ir * irc2
    G = C * ir + GA
    sG = math.sqrt(G)
    x = r - rc
    F = x * sG - target
    if F == 0.0:
        return r, lo, hi, True
    if F > 0.0:
        hi = r
    else:
        lo = r
    # F' = sG + x G'/(2 sG) with G' = -(G + GA)/r, grouped so that nothing overflows when r is
    # many decades below rc (L_z -> 0); a non-finite F' falls back to bisection.
    Fp = sG - (x * ir) * ((G + GA) / (2.0 * sG))
    rn = r - F / Fp if 0.0 < Fp < math.inf else math.nan
    if abs(rn - r) <= 2.0 * _EPS * r:
        return rn, lo, hi, True
    if hi - lo <= 4.0 * _EPS * hi:  # the bracket holds the root to rounding: Newton on a
        return r, lo, hi, True  # noisy F can step back and forth across it forever
    if not (lo < rn < hi):
        if math.isinf(hi):
            rn = 2.0 * r
        elif lo > 0.0 and hi > 4.0 * lo:
            rn = math.sqrt(lo * hi)
        else:
            rn = 0.5 * (lo + hi)
    return rn, lo, hi, False


@kernel
def _polish(r, energy, A, B, C, noise_c, lo, hi):
    """Newton on energy - V(r) from r, kept inside (lo, hi), if V at r is evaluated with less
    rounding (|A|/r^2 + |B|/r + C r + |energy|) than the excess over V_min (``noise_c``)."""
    ir = 1.0 / r
    if A * ir * ir + abs(B) * ir + C * r + abs(energy) >= noise_c:
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
    Vc = A / (rc * rc) + B / rc + C * rc
    delta = energy - Vc
    if not delta >= 0.0:
        return math.nan, math.nan
    s = math.sqrt(delta)
    G0 = C / rc + A / (rc * rc * rc * rc)
    x0 = s / math.sqrt(G0)
    r1g = rc - x0
    if not r1g > 0.0:
        # Far from the minimum the inner root sits where A/r^2 ~ energy - B/r.
        r1g = min(0.5 * rc, math.sqrt(A / max(energy, 2.0 * A / (rc * rc))))
    r2g = max(rc + x0, energy / C)
    if B < 0.0:  # a deep well: beyond r_c, V ~ B/r + C r, whose level set bounds r2 from above
        r2g = max(r2g, (energy + math.sqrt(energy * energy - 4.0 * C * B)) / (2.0 * C))
    # Both roots in one loop: two independent dependency chains overlap in the CPU.
    irc2 = 1.0 / (rc * rc)
    # A positive lower bound of r1 (A/r1^2 = energy - B/r1 - C r1 <= |energy| + |B|/r1) lets the
    # safeguard bisect geometrically: r1 may lie many decades below r_c (L_z -> 0).
    lo1 = 2.0 * A / (abs(B) + math.hypot(B, 2.0 * math.sqrt(A * abs(energy))))
    r1g = max(r1g, lo1)
    r1, hi1, done1 = r1g, rc, False
    r2, lo2, hi2, done2 = r2g, rc, math.inf, False
    for _ in range(_MAX_NEWTON):
        if not done1:
            r1, lo1, hi1, done1 = _newton_step(-s, rc, irc2, A, C, lo1, hi1, r1)
        if not done2:
            r2, lo2, hi2, done2 = _newton_step(s, rc, irc2, A, C, lo2, hi2, r2)
        if done1 and done2:
            break
    # The excess energy - V_min carries a rounding error of eps |V_min| (plus the terms of V at
    # r_c); where V is evaluated more accurately at the root itself (a deep narrow well:
    # |V_min| >> |V(r)|), polish on energy - V(r) directly.
    if not (done1 and done2):  # not converged: never a silently wrong root
        return math.nan, math.nan
    noise_c = abs(energy) + A / (rc * rc) + abs(B) / rc + C * rc
    r1 = _polish(r1, energy, A, B, C, noise_c, 0.0, rc)
    r2 = _polish(r2, energy, A, B, C, noise_c, rc, math.inf)
    # Where the factorised excess is dominated by rounding (a very deep well: |V_min| >> |V(r)|)
    # its Newton iteration can stop away from the root: check, and solve V(r) = energy on the
    # monotone side of the well instead; NaN if even that fails.
    if not _is_root(r1, energy, A, B, C):
        r1 = _bracketed(energy, A, B, C, lo1, rc)
    if not _is_root(r2, energy, A, B, C):
        r2 = _bracketed(energy, A, B, C, rc, _above_outer(energy, A, B, C, rc))
    return r1, r2


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
def free_fall_r_min(energy, A, B):
    """Pericentre [m] of an escaping free-fall orbit (energy >= 0): root of energy r^2 - B r - A."""
    root = math.hypot(B, 2.0 * math.sqrt(A) * math.sqrt(energy))  # sqrt(B^2 + 4 A E), no underflow
    if B > 0.0:
        return (B + root) / (2.0 * energy)
    return 2.0 * A / (root - B)

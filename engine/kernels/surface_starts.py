"""Where a surface's runs start: a point of a map is a launch.

A surface map's point ``i`` is the column ``X[:, i]`` of the points array: the surface's two
shape parameters (a survey may sweep them, as alpha on the cone), the launch position (the
centre's distance rho0 [m] from the axis; on the cylinder, where that is fixed, the centre's
height z0 [m]), its speed v0 [m/s] along the parallel, its spin w0 = a omega . nu [m/s] and its
speed u0 [m/s] along the meridian (0: a turning point, where a one-period run starts).

- :func:`set_point` puts the point's shape into p, and where the sphere fits and touches: the
  meridian parameter's range [Q_LO, Q_HI], the inner end (the hole, the axis region, or where
  the surface's curvature stops the sphere fitting) and the rim (``Scene.rim``: the edge's
  distance from the axis; the cylinder's height; the cone's slant length);
- :func:`launch_q` the meridian parameter of the launch position;
- :func:`period_start`, :func:`fate_start` where the runs start; :func:`story_start` and
  :func:`resume_rolling` a story's rolling start and a rolling stretch's after a slip (the
  hybrid model's, :mod:`.contact`).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .effects import DISSIPATIVE
from .fate_codes import NO_ORBIT, REST_SPEED, RUNS
from .layouts import (
    ATTITUDE,
    P_CRR,
    P_G,
    P_K,
    P_M,
    P_R_VERTEX,
    P_RADIUS,
    P_RIM,
    P_RIM_SLANT,
    P_V_REST,
    Y_QUAT,
    Y_R,
    Y_U,
    Y_V,
    Y_W,
    state_size,
)
from .meridian import (
    BOWL,
    CONE,
    CYLINDER,
    FUNNEL,
    P_KIND,
    P_Q_FLOOR,
    P_Q_HI,
    P_Q_LO,
    P_SHAPE1,
    P_SHAPE2,
    PARABOLOID,
    POWER_LAW,
    PROFILE,
    centre,
)
from .surface import motion_rates, rolling_energy

#: Columns of the points array.
X_SHAPE1, X_SHAPE2, X_POS, X_V, X_W, X_U = 0, 1, 2, 3, 4, 5
SQRT_EPS = 1.4901161193847656e-08
#: Axis region of a surface that reaches its axis, in units of the sphere's radius (the cone's
#: vertex region: :data:`.model.VERTEX_FRACTION`).
AXIS_FRACTION = 1e-2
#: Where the sphere stops fitting, a run ends where 1 - a kc falls to this (the centre's
#: surface has a cusp where it reaches 0).
FIT_MARGIN = 1e-3


@kernel
def _fits_from(p, q_lo, q_hi, margin):
    """The smallest q in [q_lo, q_hi] from which on 1 - a kc > margin (margin 0: the sphere
    fits), by bisection where it does not hold at q_lo (the curvature grows towards the
    axis)."""
    if centre(p, q_lo)[6] > margin:
        return q_lo
    lo, hi = q_lo, q_hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if centre(p, mid)[6] > margin:
            hi = mid
        else:
            lo = mid
        if hi - lo <= 4e-16 * abs(hi):
            break
    return hi


@kernel
def _axis(p, lo, hi):
    """The q in [lo, hi] where the centre reaches the axis (rho = 0; a cone's contact slant
    a cot(alpha)), by bisection."""
    if not math.isfinite(hi):
        hi = max(2.0 * abs(lo), 1.0)
        while centre(p, hi)[0] < 0.0:
            hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if centre(p, mid)[0] < 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 4e-16 * abs(hi):
            break
    return hi


@kernel
def set_point(p, X, i):
    """Point i's shape into p, and its meridian parameter's range (module docstring)."""
    p[P_SHAPE1] = X[X_SHAPE1, i]
    p[P_SHAPE2] = X[X_SHAPE2, i]
    kind = p[P_KIND]
    rim = p[P_RIM_SLANT]
    if kind == BOWL:
        r = p[P_SHAPE1]
        q_lo, q_hi = 0.0, math.pi / 2 if rim >= r else math.asin(rim / r)
    elif kind == CYLINDER:
        q_lo, q_hi = -math.inf, rim
    elif kind == FUNNEL:
        q_lo, q_hi = p[P_SHAPE2], rim
    elif kind == PROFILE:
        q_lo, q_hi = p[P_SHAPE1], min(p[P_SHAPE2], rim)
    elif kind == CONE:
        q_lo, q_hi = 0.0, rim
    else:
        q_lo, q_hi = 0.0, rim
    if kind != CYLINDER and centre(p, q_lo)[0] < 0.0:  # the centre reaches the axis above q_lo
        q_lo = _axis(p, q_lo, q_hi)
    floor = q_lo if kind != FUNNEL else 0.0  # a funnel's meridian goes on below its hole
    inner = q_lo
    if kind != CYLINDER:  # where the sphere stops fitting, and the axis region
        top = q_hi if math.isfinite(q_hi) else max(2.0 * q_lo, 1.0)
        fits = _fits_from(p, max(q_lo, 1e-300), top, 0.0)
        if fits > q_lo:  # it stops fitting before the axis: the run ends a margin before
            floor = fits
            inner = _fits_from(p, fits, top, FIT_MARGIN)
        q_lo = fits
    p[P_Q_LO] = q_lo
    p[P_Q_HI] = q_hi
    p[P_Q_FLOOR] = floor
    p[P_RIM] = q_hi
    p[P_R_VERTEX] = inner
    if kind != CYLINDER and kind != FUNNEL:  # the axis region: the centre within a few a / 100
        p[P_R_VERTEX] = max(inner, launch_q(p, AXIS_FRACTION * p[P_RADIUS]))


@kernel
def launch_q(p, pos):
    """The meridian parameter q where the centre is at distance ``pos`` [m] from the axis (the
    cylinder: at height ``pos``) on [Q_LO, Q_HI] (rho grows with q): Newton's steps on
    rho(q) - pos (d rho/dq = sigma cos b) kept inside a bracket that bisection shrinks where a
    step leaves it; NaN where no q of the range has it."""
    if p[P_KIND] == CYLINDER:
        return pos
    lo = p[P_Q_LO]
    hi = p[P_Q_HI]
    if not math.isfinite(hi):
        hi = max(2.0 * lo, 1.0)
        for _ in range(2000):
            if centre(p, hi)[0] >= pos:
                break
            hi *= 2.0
    if not (centre(p, lo)[0] <= pos <= centre(p, hi)[0]):
        return math.nan
    q = 0.5 * (lo + hi)
    kind = p[P_KIND]
    if kind == PARABOLOID or kind == FUNNEL or kind == POWER_LAW or kind == PROFILE:
        # q is the contact's distance from the axis, rho + a sin b: one slope away from pos
        guess = pos + p[P_RADIUS] * centre(p, max(pos, lo))[3]
        if lo < guess < hi:
            q = guess
    for _ in range(200):
        rho, z, cb, sb, kappa, sigma, fit = centre(p, q)
        f = rho - pos
        if f < 0.0:
            lo = q
        else:
            hi = q
        slope = sigma * cb
        step = f / slope if slope > 0.0 else math.inf
        nxt = q - step
        if not (lo < nxt < hi):  # outside the bracket: bisect
            nxt = 0.5 * (lo + hi)
        if abs(nxt - q) <= 4e-16 * abs(q) or hi - lo <= 4e-16 * abs(hi):
            return nxt
        q = nxt
    return q


@kernel
def launch_state(effects, p, X, i):
    """The state of point i's launch (theta = 0, attitude identity, no work done); empty where
    the launch position is not on the surface where the sphere fits."""
    q0 = launch_q(p, X[X_POS, i])
    if not math.isfinite(q0):
        return np.empty(0)
    y = np.zeros(state_size(effects))
    y[Y_R] = q0
    y[Y_U] = X[X_U, i] if X.shape[0] > X_U else 0.0
    y[Y_V] = X[X_V, i]
    y[Y_W] = X[X_W, i]
    if effects & ATTITUDE:
        y[Y_QUAT] = 1.0
    return y


@kernel
def tolerance_scales(effects, p, y0):
    """Characteristic size of each state component (atol_i = rtol * scale_i): q: its own size
    (1 for the cylinder's height and the bowl's angle below 1); theta: 1 rad; the velocities:
    the launch's speed with the speed the drop from the launch height to the inner end can add
    (for a launch at rest with no inner end below it, the speed of a fall through the ball's
    radius, sqrt(g a)), each floored at sqrt(eps) of it; the work of the effects: the energy
    scale."""
    n = y0.shape[0]
    sc = np.ones(n)
    rho, z, cb, sb, kappa, sigma, fit = centre(p, y0[Y_R])
    z_in = centre(p, max(p[P_Q_LO], 0.0))[1] if math.isfinite(p[P_Q_LO]) else z
    drop = max(z - z_in, 0.0)
    speed = math.sqrt(y0[Y_U] ** 2 + y0[Y_V] ** 2 + y0[Y_W] ** 2)
    vel = max(speed, math.sqrt(2.0 * p[P_G] * drop / (1.0 + p[P_K])))
    if vel == 0.0:  # at rest with nothing below it to fall to (a cylinder's wall): the speed
        vel = math.sqrt(p[P_G] * p[P_RADIUS])  # it gains falling its own radius
    floor = SQRT_EPS * vel
    sc[Y_R] = max(abs(y0[Y_R]), 1.0) if p[P_KIND] == CYLINDER else max(abs(y0[Y_R]), floor)
    sc[Y_U] = max(vel, floor)
    sc[Y_V] = max(abs(y0[Y_V]), floor)
    sc[Y_W] = max(max(abs(y0[Y_W]), abs(y0[Y_V])), floor)
    if effects & DISSIPATIVE:
        sc[n - 1] = max(0.5 * p[P_M] * vel * vel, p[P_M] * p[P_G] * max(abs(z), drop))
    return sc


@kernel
def period_start(effects, p, X, i, rtol):
    """Where point i's one-period run starts: its launch, a turning point (u0 = 0). (ok, y0,
    atol, orbit constants (unused: NaN)); ok False where the launch is not on the surface, is
    not at a turning point, or has no speed along the parallel (it passes through the axis)."""
    nan = (math.nan, math.nan, math.nan)
    y0 = launch_state(effects, p, X, i)
    if y0.shape[0] == 0 or y0[Y_U] != 0.0 or y0[Y_V] == 0.0 or not math.isfinite(y0[Y_W]):
        return False, np.empty(0), np.empty(0), nan
    atol = tolerance_scales(effects, p, y0) * rtol
    return True, y0, atol, nan


@kernel
def fate_start(effects, p, X, i, rtol):
    """Where point i's fate run starts: its launch (:func:`.model.fate_start`'s tuple; the rest
    threshold set in p). No orbit where the launch is not on the surface or beyond the rim."""
    nan = (math.nan, math.nan, math.nan)
    none = np.empty(0)
    y0 = launch_state(effects, p, X, i)
    if y0.shape[0] == 0 or not (math.isfinite(y0[Y_U]) and math.isfinite(y0[Y_V])):
        return NO_ORBIT, math.nan, none, 0.0, 0.0, none, nan
    if y0[Y_R] > p[P_RIM]:
        return NO_ORBIT, math.nan, none, 0.0, 0.0, none, nan
    sc = tolerance_scales(effects, p, y0)
    p[P_V_REST] = REST_SPEED * rtol * max(sc[Y_U], abs(y0[Y_V]))
    return RUNS, math.nan, y0, 0.0, 0.0, sc * rtol, nan


@kernel
def story_start(effects, p, start, rtol, out, y0, atol):
    """A story's rolling start (:func:`.contact.story_start`): ``start`` = (rho0 [m] (the
    cylinder: z0), v0, w0, unused, u0, slip_u, slip_v [m/s]); y0 at the launch (theta = 0), its
    tolerances, the rest threshold in p. Returns (fate or -1, the energy scale [J], the speed
    scale [m/s], (NaN, NaN, NaN): no orbit constants); no orbit where the launch is not on the
    surface or beyond the rim."""
    pos, v0, w0, _, u0, slip_u, slip_v = start
    orbit = (math.nan, math.nan, math.nan)
    q0 = launch_q(p, pos)
    if not (math.isfinite(q0) and math.isfinite(v0) and math.isfinite(w0) and math.isfinite(u0)):
        return NO_ORBIT, 0.0, 0.0, orbit
    if q0 > p[P_RIM]:
        return NO_ORBIT, 0.0, 0.0, orbit
    for j in range(y0.shape[0]):
        y0[j] = 0.0
    y0[Y_R] = q0
    y0[Y_U] = u0
    y0[Y_V] = v0
    y0[Y_W] = w0
    sc = tolerance_scales(effects, p, y0)
    slip = max(abs(slip_u), abs(slip_v))
    p[P_V_REST] = REST_SPEED * rtol * max(max(sc[Y_U], abs(v0)), slip)
    for j in range(y0.shape[0]):
        atol[j] = sc[j] * rtol
    vel = max(max(sc[Y_U], sc[Y_V]), max(sc[Y_W], slip))
    return -1, abs(rolling_energy(q0, u0, v0, w0, p)), vel, orbit


@kernel
def resume_rolling(effects, p, yr, rtol, ra):
    """A rolling stretch from yr (after a slip; :func:`.contact.resume_rolling`): its
    tolerances into ra (:func:`tolerance_scales`); no orbit constants (NaN)."""
    sc = tolerance_scales(effects, p, yr)
    for j in range(yr.shape[0]):
        ra[j] = sc[j] * rtol
    return math.nan, math.nan, math.nan


@kernel
def holds_at_rest(p, y):
    """Whether rolling resistance can hold a sphere at rest at y: the slope's pull
    g sin(b) against the most the resistance gives, c_rr N = c_rr M g cos(b) (at rest the
    normal force is the weight's part): tan(b) <= c_rr."""
    rho, z, cb, sb, kappa, sigma, fit = centre(p, y[Y_R])
    return sb <= p[P_CRR] * cb


@kernel
def starts_inner(effects, p, y0):
    """Whether the run from the turning point y0 starts at the inner one: the meridian
    acceleration there points outward."""
    return motion_rates(y0[Y_R], 0.0, y0[Y_V], y0[Y_W], p, effects)[2] > 0.0

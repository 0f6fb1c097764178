"""Where the cone's runs start: a point of a map is an orbit given by its invariants.

A cone map's point ``i`` is the column ``X[:, i]`` of the points array: (alpha [rad],
calE [J], h [m/s], L_z [kg m^2/s]) for a one-period map, and r_start [m] after them for a fate
map (the radius it starts from at rest radially: its r_min, or a launch's radius). From it:

- :func:`orbit_start` the turning points and the circular radius (the closed form's roots);
- :func:`initial_state` the state at a radius of the orbit; :func:`tolerance_scales` the size
  of each component on the orbit (its absolute tolerances);
- :func:`period_start` where a one-period run starts (its r_min), :func:`fate_start` where a
  fate run does (the rim, the vertex region, a radial orbit's way out of it);
- :func:`holds_at_rest` whether rolling resistance holds a sphere at rest on this slope;
- :func:`story_start` and :func:`resume_rolling`: a story's rolling start from its launch, and
  a rolling stretch's after a slip (the hybrid model's, :mod:`.contact`).

The drivers call these through the model interface (:mod:`.model`, :mod:`.contact`).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .cone import (
    P_ALPHA,
    P_COS,
    P_COT,
    P_GC,
    P_SIN,
    coefficients,
    invariants,
    motion_rates,
    radial_energy,
    set_alpha,
)
from .effects import DISSIPATIVE, EFFECT_BITS
from .fate_codes import FATE_VERTEX, NO_ORBIT, REST_SPEED, RUNS
from .layouts import (
    ATTITUDE,
    P_CRR,
    P_G,
    P_INV_M1K,
    P_K,
    P_M,
    P_R_VERTEX,
    P_RIM,
    P_V_REST,
    Y_QUAT,
    Y_R,
    Y_THETA,
    Y_U,
    Y_V,
    Y_W,
    state_size,
)
from .roots import circular_radius, turning_points

ROLLING_RESISTANCE = EFFECT_BITS["rolling_resistance"]
SQRT_EPS = 1.4901161193847656e-08
#: Columns of the points array: (alpha, calE, h, L_z), then a fate map's r_start.
X_ALPHA, X_ENERGY, X_H, X_LZ, X_START = 0, 1, 2, 3, 4


@kernel
def set_point(p, X, i):
    """Point i's geometry into p: its alpha (:func:`.cone.set_alpha`)."""
    set_alpha(p, X[X_ALPHA, i])


@kernel
def orbit_start(p, energy, h, Lz):
    """(ok, r1, r2, rc) of the bounded orbit (calE = energy [J], h [m/s], L_z): the turning
    points [m] and the circular radius [m]; ok is False when the orbit is not bounded."""
    A, B, C = coefficients(p[P_ALPHA], h, Lz, p[P_M], p[P_G], p[P_K])
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
    A, B, C = coefficients(p[P_ALPHA], h, Lz, M, p[P_G], p[P_K])
    ke = energy - (A / (r0 * r0) + B / r0 + C * r0)
    y[Y_R] = r0
    y[Y_THETA] = 0.0
    y[Y_U] = math.sqrt(2.0 * ke / M) if ke > 0.0 else 0.0
    y[Y_V] = Lz / (M * r0 * s)
    y[Y_W] = h + Lz * c / (M * r0 * s * s)
    if effects & ATTITUDE:
        y[Y_QUAT] = 1.0
    return y


@kernel
def tolerance_scales(p, effects, y0, energy, h, Lz, r1, r2, rc):
    """Characteristic size of each state component on the orbit (atol_i = rtol * scale_i).

    r: r1 [m]; theta: 1 rad; u: the largest radial speed sqrt(2 (calE - V_min)/M) [m/s];
    v: its smallest size |v(r2)| (v r is L_z/(M sin a), so v must stay relatively accurate for L_z
    to be conserved near the axis, where r2/r1 is huge); w: max |w| over [r1, r2]; quaternion: 1.
    Velocities are floored at sqrt(eps) times the speed, so an exactly circular orbit still has a
    usable absolute tolerance. The work of the dissipative forces: the orbit's energy scale.
    """
    n = y0.shape[0]
    sc = np.ones(n)
    M = p[P_M]
    s = p[P_SIN]
    c = p[P_COS]
    A, B, C = coefficients(p[P_ALPHA], h, Lz, M, p[P_G], p[P_K])
    speed = math.sqrt(y0[Y_U] ** 2 + y0[Y_V] ** 2 + y0[Y_W] ** 2)
    if math.isfinite(rc) and rc > 0.0:
        du = energy - (A / (rc * rc) + B / rc + C * rc)
        umax = math.sqrt(2.0 * du / M) if du > 0.0 else 0.0
    else:
        umax = max(speed, math.sqrt(2.0 * abs(energy) / M))
    vel = max(speed, umax)
    floor = SQRT_EPS * vel
    sc[Y_R] = y0[Y_R]
    sc[Y_THETA] = 1.0
    sc[Y_U] = max(umax, floor)
    # v = L_z/(M r sin a) carries L_z: keep it relatively accurate where it is smallest (r2).
    r_far = r2 if math.isfinite(r2) else r1
    sc[Y_V] = max(abs(Lz / (M * r_far * s)), floor)
    w1 = abs(h + Lz * c / (M * r1 * s * s))
    w2 = abs(h + Lz * c / (M * r2 * s * s)) if math.isfinite(r2) else abs(h)
    sc[Y_W] = max(max(w1, w2), floor)
    if effects & DISSIPATIVE:  # the work of the dissipative forces: the orbit's energy scale
        sc[n - 1] = max(abs(energy), 0.5 * M * vel * vel)
    return sc


@kernel
def period_start(effects, p, X, i, rtol):
    """Where point i's one-period run starts (p holds its geometry: :func:`set_point`): (ok,
    y0 at r_min with u = 0, atol, the run's orbit constants (calE, h, L_z)); ok is False where
    the orbit is not bounded (y0 and atol empty)."""
    energy, h, Lz = X[X_ENERGY, i], X[X_H, i], X[X_LZ, i]
    ok, r1, r2, rc = orbit_start(p, energy, h, Lz)
    if not ok:
        return False, np.empty(0), np.empty(0), (energy, h, Lz)
    y0 = initial_state(p, effects, r1, energy, h, Lz)
    y0[Y_U] = 0.0  # exactly at the turning point
    atol = tolerance_scales(p, effects, y0, energy, h, Lz, r1, r2, rc)
    atol *= rtol
    return True, y0, atol, (energy, h, Lz)


@kernel
def fate_start(effects, p, X, i, rtol):
    """Where point i's fate run starts, at rest radially (u = 0) at r_start, theta = 0 (p holds
    its geometry; the rest threshold is set in it): (start, r, y0, t0 [s], work0 [J], atol, the
    run's orbit constants). ``start`` is :data:`.fate_codes.RUNS` where it runs from y0 at t0
    (a radial orbit: from the edge of the vertex region, reached with the work work0 of the
    resistance), else the fate it has at its start (no orbit: the inputs, or a start beyond the
    rim, the closed form's off_cone; the vertex: it starts there moving in, or a radial orbit
    cannot leave it), at radius r (y0 and atol empty)."""
    energy, h, Lz, r_start = X[X_ENERGY, i], X[X_H, i], X[X_LZ, i], X[X_START, i]
    orbit = (energy, h, Lz)
    none = np.empty(0)
    if not (r_start >= 0.0 and math.isfinite(energy) and math.isfinite(Lz)):
        return NO_ORBIT, math.nan, none, 0.0, 0.0, none, orbit
    if r_start > p[P_RIM]:  # beyond the rim: the closed form's off_cone
        return NO_ORBIT, math.nan, none, 0.0, 0.0, none, orbit
    ok, r1, r2, rc = orbit_start(p, energy, h, Lz)
    if not ok:
        r1 = r_start
        r2 = math.inf
    t0 = 0.0
    work0 = 0.0
    if r_start == 0.0:  # a radial orbit from the vertex: to the edge of its region
        y0, t0, work0 = leave_vertex(p, effects, energy, h)
        if t0 < 0.0:
            return FATE_VERTEX, 0.0, none, 0.0, 0.0, none, orbit
        r1 = y0[Y_R]
    else:
        y0 = initial_state(p, effects, r_start, energy, h, Lz)
        y0[Y_U] = 0.0  # a turning point: the start of a map's orbit, or a launch with u0 = 0
        if r_start <= p[P_R_VERTEX]:  # inside the vertex region: at its r_min it leaves
            if motion_rates(y0[Y_R], 0.0, y0[Y_V], y0[Y_W], p, effects)[2] <= 0.0:
                return FATE_VERTEX, r_start, none, 0.0, 0.0, none, orbit
    sc = tolerance_scales(p, effects, y0, energy, h, Lz, min(r1, y0[Y_R]), r2, rc)
    p[P_V_REST] = REST_SPEED * rtol * max(sc[Y_U], abs(y0[Y_V]))
    atol = sc * rtol
    return RUNS, math.nan, y0, t0, work0, atol, orbit


@kernel
def story_start(effects, p, start, rtol, out, y0, atol):
    """A story's rolling start (:func:`.contact.story_start`): ``start`` = (calE [J], h [m/s],
    L_z, r_start [m], u0, slip_u, slip_v [m/s]); y0 on the orbit at r_start with radial speed
    u0, its tolerances, the rest threshold in p (from the orbit's speeds and the slip's).
    Returns (fate or -1, the energy scale [J] (the orbit's calE with u0's part), the speed
    scale [m/s], the orbit (calE, h, L_z)); a start in the vertex region that does not leave
    it ends there (its floats in ``out``)."""
    energy, h, Lz, r_start, u0, slip_u, slip_v = start
    orbit = (energy, h, Lz)
    if not (r_start >= 0.0 and math.isfinite(energy) and math.isfinite(Lz)):
        return NO_ORBIT, 0.0, 0.0, orbit
    if r_start > p[P_RIM]:  # beyond the rim, as a fate map says
        return NO_ORBIT, 0.0, 0.0, orbit
    e_true = energy + 0.5 * p[P_M] * u0 * u0
    ok, r1, r2, rc = orbit_start(p, e_true, h, Lz)
    if not ok:
        r1 = r_start
        r2 = math.inf
    yi = initial_state(p, effects, r_start, e_true, h, Lz)
    yi[Y_U] = u0
    if r_start <= p[P_R_VERTEX]:  # in the vertex region: it ends there unless it leaves it
        leaves = u0 > 0.0 or (u0 == 0.0 and motion_rates(yi[Y_R], 0.0, yi[Y_V], yi[Y_W], p,
                                                         effects)[2] > 0.0)  # fmt: skip
        if r_start == 0.0 or not leaves:
            out[0] = 0.0
            out[1] = r_start
            for j in range(2, 6):
                out[j] = 0.0
            return FATE_VERTEX, 0.0, 0.0, orbit
    for j in range(yi.shape[0]):
        y0[j] = yi[j]
    sc = tolerance_scales(p, effects, y0, e_true, h, Lz, min(r1, r_start), r2, rc)
    p[P_V_REST] = REST_SPEED * rtol * max(max(sc[Y_U], abs(y0[Y_V])), max(abs(slip_u), abs(slip_v)))
    for j in range(y0.shape[0]):
        atol[j] = sc[j] * rtol
    vel = max(max(sc[Y_U], sc[Y_V]), max(sc[Y_W], max(abs(slip_u), abs(slip_v))))
    return -1, e_true, vel, orbit


@kernel
def resume_rolling(effects, p, yr, rtol, ra):
    """A rolling stretch from yr (after a slip; :func:`.contact.resume_rolling`): its orbit
    (calE, h, L_z) from yr's invariants, its tolerances into ra from that orbit's scales."""
    E1, Lz1, h1 = invariants(yr, p)
    e1 = radial_energy(E1, h1, p[P_M], p[P_K])
    ok1, q1, q2, qc = orbit_start(p, e1, h1, Lz1)
    if not ok1:
        q1 = yr[Y_R]
        q2 = math.inf
    sc = tolerance_scales(p, effects, yr, e1, h1, Lz1, min(q1, yr[Y_R]), q2, qc)
    for j in range(yr.shape[0]):
        ra[j] = sc[j] * rtol
    return e1, h1, Lz1


@kernel
def leave_vertex(p, effects, energy, h):
    """The state where a radial orbit (L_z = 0, radial energy ``energy``) leaving the vertex
    reaches the edge of the vertex region, the time it took and the work of the resistance on
    the way: along the generatrix (v = 0, N = M g sin(alpha)) the deceleration is constant,
    g cos(alpha)/(1+k) + c_rr g sin(alpha)/(1+k). Time -1: it never gets there."""
    r_v = p[P_R_VERTEX]
    y = initial_state(p, effects, r_v, energy, h, 0.0)
    decel = p[P_GC]
    work = 0.0
    if effects & ROLLING_RESISTANCE:
        resistance = p[P_CRR] * p[P_M] * p[P_G] * p[P_SIN]  # c_rr N [N]
        decel += resistance * p[P_INV_M1K]
        work = resistance * r_v
        y[state_size(effects) - 1] = work
    u0 = math.sqrt(2.0 * energy / p[P_M]) if energy > 0.0 else 0.0
    u2 = u0 * u0 - 2.0 * decel * r_v
    if not u2 > 0.0:
        return y, -1.0, 0.0
    y[Y_U] = math.sqrt(u2)
    return y, (u0 - y[Y_U]) / decel, work


@kernel
def holds_at_rest(p, y=None):
    """Whether rolling resistance can hold a sphere at rest on this cone's slope (anywhere: y
    is not needed): the slope's pull g cos(alpha) against the most the resistance gives,
    c_rr N = c_rr M g sin(alpha)."""
    return p[P_COT] <= p[P_CRR]


@kernel
def starts_inner(effects, p, y0):
    """A cone's one-period run starts at r_min, the inner turning point."""
    return True

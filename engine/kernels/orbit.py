"""Integrating orbits: the start state, tolerances, one run kernel per method id, the one-period
reduction and the parallel batch over points.

Every integrator kernel follows the run protocol (:mod:`.protocol`) with one signature::

    run(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps, record,
        dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate)
        -> (status, n_accepted, n_rejected, t, y, n_events, n_recorded)

with ``orbit`` = (calE [J], h [m/s], L_z [kg m^2/s]). :func:`run` picks the kernel from the
literal ``method`` id: the Runge-Kutta pairs of :data:`.tableaux.RK_TABLEAUX` (ids 0, 1, ...)
share :func:`.rk.rk_run`; other methods are listed in :data:`RUN_KERNELS`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, prange
from numba.core import errors, types
from numba.extending import overload

from .._jit import kernel, parallel_kernel
from .effects import DISSIPATIVE
from .model import (
    ATTITUDE,
    P_COS,
    P_G,
    P_K,
    P_M,
    P_SIN,
    coefficients,
    invariants,
    kinetic_energy,
    set_alpha,
    state_size,
)
from .protocol import (
    APOCENTRE,
    NOT_BOUNDED,
    OK,
    PERICENTRE,
    RECORD_NONE,
    SQRT_EPS,
    event_buffers,
)
from .rk import rk_run
from .roots import circular_radius, turning_points
from .symplectic import SYMPLECTIC, sym_run
from .tableaux import RK_TABLEAUX

#: Run kernels of the methods that are not Runge-Kutta pairs, by kernel id.
RUN_KERNELS = {SYMPLECTIC: sym_run}
#: Rows of the float output of :func:`integrate_points`.
PERIOD_ROWS = ("period", "apsidal_angle", "precession_rate", "energy_drift", "energy_loss")


def run(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps, record, dt_out,
        ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
    """The run kernel of the literal method id (module docstring). Jit-only."""
    raise NotImplementedError("run runs inside numba kernels only")


@overload(run, jit_options={"error_model": "numpy", "nogil": True})
def _ol_run(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps, record,
            dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
    if not isinstance(method, types.IntegerLiteral):
        raise errors.TypingError("method must be a numba literal here (use numba.literally)")
    m = int(method.literal_value)
    target = rk_run if 0 <= m < len(RK_TABLEAUX) else RUN_KERNELS.get(m)
    if target is None:
        raise errors.TypingError(f"no integrator kernel with id {m}")

    def impl(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps, record,
             dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
        return target(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps,
                      record, dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate)  # fmt: skip

    return impl


@kernel
def solve(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps, record, dt_out,
          ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate):  # fmt: skip
    """:func:`run` compiled for a literal method and effect set (the entry point of a single
    trajectory)."""
    literally(method)
    literally(effects)
    return run(method, effects, y0, p, orbit, rtol, atol, t_end, n_apsides, max_steps, record,
               dt_out, ev_t, ev_kind, ev_y, tr_t, tr_y, tr_rate)  # fmt: skip


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
    usable absolute tolerance. The work of the dissipative forces: the orbit's energy scale.
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
    if effects & DISSIPATIVE:  # the work of the dissipative forces: the orbit's energy scale
        sc[n - 1] = max(abs(energy), 0.5 * M * vel * vel)
    return sc


# ------------------------------------------------------------------------- one radial period
@kernel
def reduce_period(effects, p, y0, res, ev_t, ev_kind, ev_y):
    """(status, T, psi, precession, steps, drift, loss) from a run that stopped at the second
    apsis."""
    nan = math.nan
    status = res[0]
    n_acc = res[1]
    n_ev = res[5]
    if status != OK:
        return status, nan, nan, nan, n_acc, nan, nan
    if n_ev < 2 or ev_kind[0] != APOCENTRE or ev_kind[1] != PERICENTRE:
        return NOT_BOUNDED, nan, nan, nan, n_acc, nan, nan
    T = ev_t[1]
    psi = abs(ev_y[0, 1])
    E0 = invariants(y0, p)[0]
    E1 = invariants(ev_y[1], p)[0]
    scale = max(abs(E0), kinetic_energy(y0, p))
    drift = abs(E1 - E0) / scale
    loss = E0 - E1 if effects & DISSIPATIVE else nan
    return OK, T, psi, (2.0 * psi - 2.0 * math.pi) / T, n_acc, drift, loss


@kernel
def one_period(method, effects, p, energy, h, Lz, rtol, max_steps):
    """One radial period from r_min (u = 0, theta = 0) to the next r_min.

    Returns (status, period [s], apsidal angle [rad], precession rate [rad/s], accepted steps,
    energy drift [1], energy lost [J]). The drift is |E(T) - E(0)| / max(|E(0)|, KE(0)), KE the
    kinetic energy: relative to E, or to the kinetic energy where E ~ 0.
    """
    ok, r1, r2, rc = orbit_start(p, energy, h, Lz)
    if not ok:
        return NOT_BOUNDED, math.nan, math.nan, math.nan, 0, math.nan, math.nan
    y0 = initial_state(p, effects, r1, energy, h, Lz)
    y0[2] = 0.0  # exactly at the turning point
    atol = tolerance_scales(p, effects, y0, energy, h, Lz, r1, r2, rc)
    atol *= rtol
    ev_t, ev_kind, ev_y = event_buffers(4, y0.shape[0])
    # Nothing is recorded: the event buffers stand in for the (unused) trajectory buffers.
    res = run(method, effects, y0, p, (energy, h, Lz), rtol, atol, math.inf, np.int64(2),
              max_steps, np.int64(RECORD_NONE), 0.0, ev_t, ev_kind, ev_y, ev_t, ev_y,
              ev_y)  # fmt: skip
    return reduce_period(effects, p, y0, res, ev_t, ev_kind, ev_y)


@parallel_kernel
def integrate_points(alpha, energy, h, Lz, params, method, effects, rtol, max_steps, out_f,
                     out_n, out_status):  # fmt: skip
    """:func:`one_period` for every point, in parallel (``method``, ``effects``: literal ints).

    Writes ``out_f`` float64[5, n] (rows :data:`PERIOD_ROWS`), ``out_n`` int64[n] accepted
    steps and ``out_status`` int8[n].
    """
    literally(method)
    literally(effects)
    n = alpha.shape[0]
    for i in prange(n):
        p = params.copy()
        set_alpha(p, alpha[i])
        res = one_period(method, effects, p, energy[i], h[i], Lz[i], rtol, max_steps)
        store_period(out_f, out_n, out_status, i, res)


@kernel
def store_period(out_f, out_n, out_status, i, res):
    """Write :func:`one_period`'s result tuple for point i: ``out_f`` rows :data:`PERIOD_ROWS`,
    ``out_n`` the accepted steps, ``out_status`` the status."""
    st, T, psi, prec, nst, drift, loss = res
    out_status[i] = st
    out_f[0, i] = T
    out_f[1, i] = psi
    out_f[2, i] = prec
    out_f[3, i] = drift
    out_f[4, i] = loss
    out_n[i] = nst

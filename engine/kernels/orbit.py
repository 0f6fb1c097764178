"""Integrating orbits: the start state, tolerances, one run kernel per method id, the one-period
reduction and the parallel batch over points.

One radial period by symmetry: without a dissipative effect (:data:`.effects.DISSIPATIVE`) the
equations of motion are invariant under t -> -t, theta -> -theta, u -> -u (r, v, w unchanged),
so the motion from r_max back to r_min is the mirror image of the motion from r_min to r_max.
A conservative scene's one-period map therefore integrates r_min -> r_max once
(:func:`period_apsides` = 1) and doubles: period = 2 t(r_max), and the apsidal angle is the
azimuth swept to r_max. A dissipative scene integrates the whole (decaying) period.

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
from .model import energy, kinetic_energy, period_start, set_point, starts_inner
from .protocol import (
    APOCENTRE,
    NOT_BOUNDED,
    OK,
    PERICENTRE,
    RECORD_NONE,
    event_buffers,
)
from .rk import rk_run
from .symplectic import SYMPLECTIC, sym_run
from .tableaux import RK_TABLEAUX

#: Run kernels of the methods that are not Runge-Kutta pairs, by kernel id. The Runge-Kutta
#: pairs take the ids 0 .. len(RK_TABLEAUX) - 1 (their positions); these start at
#: :data:`OTHER_KERNELS`, so a new pair never takes another method's id.
RUN_KERNELS = {SYMPLECTIC: sym_run}
#: The first kernel id of the methods that are not Runge-Kutta pairs.
OTHER_KERNELS = 100
#: Events a run that records nothing holds (a one-period run: the apsides it integrates to and
#: a terminal event; a fate run: its terminal event), scalar or on the lanes (:mod:`.lanes`).
RUN_EVENTS = 4


def check_kernel_ids(run_kernels: dict, n_tableaux: int) -> None:
    """Refuse (ValueError) kernel ids that the Runge-Kutta pairs could take, or that are not
    ints: each id names one kernel, whatever is appended to either table."""
    if n_tableaux > OTHER_KERNELS:
        raise ValueError(f"{n_tableaux} Runge-Kutta pairs reach the other kernels' ids")
    for kid in run_kernels:
        if not isinstance(kid, int) or kid < OTHER_KERNELS:
            raise ValueError(
                f"kernel id {kid!r} is not an int >= {OTHER_KERNELS} (below it the ids are the "
                "Runge-Kutta pairs' positions)"
            )


check_kernel_ids(RUN_KERNELS, len(RK_TABLEAUX))
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


# ------------------------------------------------------------------------- one radial period
@kernel
def period_apsides(effects):
    """Apsides a one-period run of ``effects`` integrates to: 1 (r_max; the period and the
    apsidal angle by time symmetry) for a conservative scene, 2 (the next r_min) for a
    dissipative one. Folds to a constant for a literal ``effects``."""
    return 2 if effects & DISSIPATIVE else 1


@kernel
def reduce_period(effects, p, y0, res, ev_t, ev_kind, ev_y):
    """(status, T, psi, precession, steps, drift, loss) from a run that stopped at its
    :func:`period_apsides`-th apsis. Conservative: T = twice the time to r_max, the drift
    measured at r_max; dissipative: T = the time to the next r_min, drift and loss there."""
    literally(effects)  # the model's kernels are picked by it (a call from Python too)
    nan = math.nan
    status = res[0]
    n_acc = res[1]
    n_ev = res[5]
    if status != OK:
        return status, nan, nan, nan, n_acc, nan, nan
    last = period_apsides(effects) - 1
    first = APOCENTRE if starts_inner(effects, p, y0) else PERICENTRE
    if n_ev <= last or ev_kind[0] != first or (last == 1 and ev_kind[1] == first):
        return NOT_BOUNDED, nan, nan, nan, n_acc, nan, nan
    T = ev_t[1] if last == 1 else 2.0 * ev_t[0]
    psi = abs(ev_y[0, 1])
    E0 = energy(y0, p, effects)
    E1 = energy(ev_y[last], p, effects)
    scale = max(abs(E0), kinetic_energy(y0, p))
    drift = abs(E1 - E0) / scale
    loss = E0 - E1 if effects & DISSIPATIVE else nan
    return OK, T, psi, (2.0 * psi - 2.0 * math.pi) / T, n_acc, drift, loss


@kernel
def one_period(method, effects, p, X, i, rtol, max_steps):
    """One radial period of point i (the columns ``X[:, i]`` of the points array, p holding its
    geometry), from the turning point where the model starts it (the cone's r_min: u = 0,
    theta = 0): integrated to the other turning point and doubled for a conservative scene, to
    the next one of its kind for a dissipative one (:func:`period_apsides`).

    Returns (status, period [s], apsidal angle [rad], precession rate [rad/s], accepted steps,
    energy drift [1], energy lost [J]). The drift is |E(t) - E(0)| / max(|E(0)|, KE(0)) at the
    run's end t (r_max, or the next r_min), KE the kinetic energy: relative to E, or to the
    kinetic energy where E ~ 0.
    """
    ok, y0, atol, orbit = period_start(effects, p, X, i, rtol)
    if not ok:
        return NOT_BOUNDED, math.nan, math.nan, math.nan, 0, math.nan, math.nan
    ev_t, ev_kind, ev_y = event_buffers(RUN_EVENTS, y0.shape[0])
    # Nothing is recorded: the event buffers stand in for the (unused) trajectory buffers.
    n_aps = np.int64(period_apsides(effects))
    res = run(method, effects, y0, p, orbit, rtol, atol, math.inf, n_aps, max_steps,
              np.int64(RECORD_NONE), 0.0, ev_t, ev_kind, ev_y, ev_t, ev_y, ev_y)  # fmt: skip
    return reduce_period(effects, p, y0, res, ev_t, ev_kind, ev_y)


@parallel_kernel
def integrate_points(X, params, method, effects, rtol, max_steps, out_f, out_n, out_status):
    """:func:`one_period` for every point (the columns of the points array X: the model's
    inputs, the cone's (alpha, calE, h, L_z)), in parallel (``method``, ``effects``: literal
    ints).

    Writes ``out_f`` float64[5, n] (rows :data:`PERIOD_ROWS`), ``out_n`` int64[n] accepted
    steps and ``out_status`` int8[n].
    """
    literally(method)
    literally(effects)
    n = X.shape[1]
    for i in prange(n):
        p = params.copy()
        set_point(p, X, i, effects)
        res = one_period(method, effects, p, X, i, rtol, max_steps)
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

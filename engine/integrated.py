"""Orbit geometry by integration: one radial period per point, in a parallel numba kernel.

:func:`evaluate_integrated` integrates each point's orbit from its inner turning point r_min
(u = 0, theta = 0) to the next r_min and reports the radial period, the apsidal angle (azimuth
swept from r_min to the next r_max), the precession rate, the work done (accepted steps), the
energy drift and a status code. With rolling resistance the same quantities are measured over the
first (decaying) radial period, plus the energy lost.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import literally, prange
from numba.core import types

from ._jit import kernel, parallel_kernel
from .kernels.integrators import (
    APOCENTRE,
    METHOD_IDS,
    NOT_BOUNDED,
    OK,
    PERICENTRE,
    RECORD_NONE,
    STATUS_MESSAGES,
    SYMPLECTIC,
    UNSUPPORTED,
    event_buffers,
    initial_state,
    orbit_start,
    rk_run,
    tolerance_scales,
)
from .kernels.scenes import (
    ATTITUDE,
    N_PARAMS,
    ROLLING_RESISTANCE,
    effects_mask,
    invariants,
    kinetic_energy,
    make_params,
    set_alpha,
)
from .kernels.symplectic import DEFAULT_ORDER, initial_z, sym_run
from .scene import Scene

__all__ = ["evaluate_integrated", "integrate_points", "STATUS_MESSAGES", "DEFAULT_MAX_STEPS"]

#: Step budget per orbit (accepted + rejected steps); beyond it the status is MAX_STEPS.
DEFAULT_MAX_STEPS = 1_000_000
#: Rows of the float output of :func:`integrate_points`.
_ROWS = ("period", "apsidal_angle", "precession_rate", "energy_drift", "energy_loss")


@kernel
def _start(p, effects, energy, h, Lz):
    """(ok, y0 at r_min with u = 0, r1, r2, rc)."""
    ok, r1, r2, rc = orbit_start(p, energy, h, Lz)
    y0 = initial_state(p, effects, r1 if ok else 1.0, energy, h, Lz)
    y0[2] = 0.0  # exactly at the turning point
    return ok, y0, r1, r2, rc


@kernel
def _reduce(effects, p, y0, res, ev_t, ev_kind, ev_y):
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
    loss = E0 - E1 if effects & ROLLING_RESISTANCE else nan
    return OK, T, psi, (2.0 * psi - 2.0 * math.pi) / T, n_acc, drift, loss


@kernel
def period_rk(method, effects, p, energy, h, Lz, rtol, max_steps):
    """One radial period from r_min with an RK method.

    Returns (status, period [s], apsidal angle [rad], precession rate [rad/s], accepted steps,
    energy drift [1], energy lost [J]). The drift is |E(T) - E(0)| / max(|E(0)|, KE(0)), KE the
    kinetic energy: relative to E, or to the kinetic energy where E ~ 0.
    """
    ok, y0, r1, r2, rc = _start(p, effects, energy, h, Lz)
    if not ok:
        return NOT_BOUNDED, math.nan, math.nan, math.nan, 0, math.nan, math.nan
    atol = tolerance_scales(p, effects, y0, energy, h, Lz, r1, r2, rc)
    atol *= rtol
    ev_t, ev_kind, ev_y = event_buffers(4, y0.shape[0])
    # Nothing is recorded: the event buffers stand in for the (unused) trajectory buffers.
    res = rk_run(method, effects, y0, p, rtol, atol, math.inf, np.int64(2), max_steps,
                 np.int64(RECORD_NONE), 0.0, ev_t, ev_kind, ev_y, ev_t, ev_y, ev_y)  # fmt: skip
    return _reduce(effects, p, y0, res, ev_t, ev_kind, ev_y)


@kernel
def period_symplectic(effects, p, energy, h, Lz, rtol, max_steps):
    """:func:`period_rk` with the time-transformed Yoshida integrator."""
    ok, y0, r1, r2, rc = _start(p, effects, energy, h, Lz)
    if not ok:
        return NOT_BOUNDED, math.nan, math.nan, math.nan, 0, math.nan, math.nan
    z0 = initial_z(p, r1, 0.0, energy, h, Lz)
    ev_t, ev_kind, ev_y = event_buffers(4, 5)
    res = sym_run(effects, z0, p, energy, h, Lz, np.int64(DEFAULT_ORDER), rtol, math.inf,
                  np.int64(2), max_steps, np.int64(RECORD_NONE), 0.0, ev_t, ev_kind, ev_y, ev_t,
                  ev_y)  # fmt: skip
    return _reduce(effects, p, y0, res, ev_t, ev_kind, ev_y)


@parallel_kernel
def integrate_points_rk(alpha, energy, h, Lz, params, method, effects, rtol, max_steps, out_f,
                        out_n, out_status):  # fmt: skip
    """:func:`integrate_points` for the RK methods (``method``, ``effects``: literal ints)."""
    literally(method)
    literally(effects)
    n = alpha.shape[0]
    for i in prange(n):
        p = params.copy()
        set_alpha(p, alpha[i])
        st, T, psi, prec, nst, drift, loss = period_rk(
            method, effects, p, energy[i], h[i], Lz[i], rtol, max_steps
        )
        out_status[i] = st
        out_f[0, i] = T
        out_f[1, i] = psi
        out_f[2, i] = prec
        out_f[3, i] = drift
        out_f[4, i] = loss
        out_n[i] = nst


@parallel_kernel
def integrate_points_symplectic(alpha, energy, h, Lz, params, effects, rtol, max_steps, out_f,
                                out_n, out_status):  # fmt: skip
    """:func:`integrate_points` for the symplectic method (``effects``: literal int)."""
    literally(effects)
    n = alpha.shape[0]
    for i in prange(n):
        p = params.copy()
        set_alpha(p, alpha[i])
        st, T, psi, prec, nst, drift, loss = period_symplectic(
            effects, p, energy[i], h[i], Lz[i], rtol, max_steps
        )
        out_status[i] = st
        out_f[0, i] = T
        out_f[1, i] = psi
        out_f[2, i] = prec
        out_f[3, i] = drift
        out_f[4, i] = loss
        out_n[i] = nst


def integrate_points(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    params: np.ndarray,
    method: int,
    effects: int,
    rtol: float,
    max_steps: int,
    out_f: np.ndarray,
    out_n: np.ndarray,
    out_status: np.ndarray,
) -> None:
    """One radial period from r_min for every point, in parallel (numba prange).

    alpha, energy, h, Lz: 1-D float64 [rad, J, m/s, kg m^2/s]; ``params`` the scene's parameter
    array (:func:`.kernels.scenes.make_params`; alpha is replaced per point); ``method`` a
    ``METHOD_IDS`` value and ``effects`` a bit mask (each pair is compiled once, then cached).
    Writes ``out_f`` float64[5, n] (period [s], apsidal angle [rad], precession rate [rad/s],
    energy drift [1], energy loss [J]), ``out_n`` int64[n] accepted steps and ``out_status``
    int8[n]. Never raises on bad points: they get a status code and NaN.
    """
    if method == SYMPLECTIC and effects & (ROLLING_RESISTANCE | ATTITUDE):
        out_f[:] = math.nan  # not a separable Hamiltonian: nothing to compile, nothing to run
        out_n[:] = 0
        out_status[:] = UNSUPPORTED
    elif method == SYMPLECTIC:
        args = (alpha, energy, h, Lz, params, effects, rtol, max_steps, out_f, out_n, out_status)
        call_specialized(integrate_points_symplectic, args, (5,))
    else:
        args = (alpha, energy, h, Lz, params, method, effects, rtol, max_steps, out_f, out_n,
                out_status)  # fmt: skip
        call_specialized(integrate_points_rk, args, (5, 6))


_ENTRIES: dict[tuple, Any] = {}


def call_specialized(dispatcher: Any, args: tuple, literal_positions: tuple[int, ...]) -> Any:
    """Call a kernel that makes some int arguments literal (``numba.literally``) without paying
    numba's literal dispatch on every call.

    A Python int never matches a literal signature directly, so each call would re-type the
    kernel's head (tens of ms). The first call per literal values goes through the dispatcher
    (compiling or loading the specialisation from the cache); later calls use that
    specialisation's compiled entry point. The other arguments must keep their types.
    """
    values = tuple(int(args[i]) for i in literal_positions)
    key = (dispatcher, values)
    entry = _ENTRIES.get(key)
    if entry is not None:
        return entry(*args)
    result = dispatcher(*args)
    for sig, cres in dispatcher.overloads.items():
        if all(
            isinstance(sig[i], types.IntegerLiteral) and sig[i].literal_value == v
            for i, v in zip(literal_positions, values, strict=True)
        ):
            _ENTRIES[key] = cres.entry_point
            break
    return result


def scene_params(scene: Scene, alpha: float = math.pi / 4) -> np.ndarray:
    """The float64 parameter array of a scene (layout ``engine.kernels.scenes.P_*``)."""
    mu = math.inf if scene.mu is None else float(scene.mu)
    p = make_params(alpha, scene.M, scene.g, scene.k, scene.a, scene.rim_or_inf, mu, scene.c_rr)
    assert p.shape == (N_PARAMS,)
    return p


def check_method(method: str, scene: Scene) -> int:
    """Method id of a method name; ValueError for unknown names and unsupported scenes."""
    if method not in METHOD_IDS:
        raise ValueError(f"method must be one of {', '.join(METHOD_IDS)}; got {method!r}")
    if method == "symplectic":
        bad = [e for e in scene.effects if e in ("rolling_resistance", "attitude")]
        if bad:
            raise ValueError(
                f"method 'symplectic' needs a conservative scene without attitude; "
                f"scene has {', '.join(bad)} (use method='rk45' or 'dop853')"
            )
    return METHOD_IDS[method]


def check_rtol(rtol: float) -> float:
    """rtol as a float in [1e-14, 1e-3]; ValueError otherwise."""
    try:
        r = float(rtol)
    except (TypeError, ValueError):
        raise ValueError(f"rtol must be a number; got {rtol!r}") from None
    if not (1e-14 <= r <= 1e-3):
        raise ValueError(f"rtol must lie in [1e-14, 1e-3]; got {rtol!r}")
    return r


def evaluate_integrated(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    scene: Scene,
    method: str = "rk45",
    rtol: float = 1e-10,
    *,
    max_steps: int = DEFAULT_MAX_STEPS,
) -> dict[str, np.ndarray]:
    """Integrate one radial period from r_min for each point.

    Parameters
    ----------
    alpha, energy, h, Lz : equal-length 1-D float64 arrays: half-aperture [rad], radial energy
        calE [J], spin invariant [m/s], axial angular momentum [kg m^2/s].
    scene : the scene (its effects are compiled in).
    method : "rk45", "dop853" or "symplectic" (conservative scenes without attitude).
    rtol : relative tolerance, in [1e-14, 1e-3]. The integrated period and apsidal angle are
        within 100 rtol kappa relative, kappa = max(1, (A/r1^2)/|calE|) the amplification of a
        velocity error at the pericentre into the radial energy: ~1 for most orbits, (1+e)/(1-e)
        for the period of a free-fall ellipse of eccentricity e (tests/test_integrators.py).
        For "symplectic" rtol sets the fixed step in the fictitious time (same target).
    max_steps : step budget per orbit.

    Returns
    -------
    dict of 1-D arrays: "period" [s], "apsidal_angle" [rad], "precession_rate" [rad/s],
    "n_steps" (int64, accepted steps), "energy_drift" (|E(T) - E(0)| / max(|E(0)|, KE(0)), KE the
    kinetic energy at the start: relative to the total energy E, or to the kinetic energy where
    E ~ 0), "status" (int8, meanings in ``STATUS_MESSAGES``); with rolling resistance also
    "energy_loss" [J] = E(0) - E(T) (and "energy_drift" is then that physical loss, scaled).
    Failed points have NaN and a nonzero status; a sphere that rolling resistance brings to rest
    within the period ends with "step size fell below 16 eps |t|" (the friction force turns
    discontinuously at zero speed).
    """
    mid = check_method(method, scene)
    r = check_rtol(rtol)
    arrays = []
    for name, arr in (("alpha", alpha), ("energy", energy), ("h", h), ("Lz", Lz)):
        a = np.ascontiguousarray(arr, dtype=np.float64)
        if a.ndim != 1:
            raise ValueError(f"{name} must be a 1-D array; got shape {a.shape}")
        arrays.append(a)
    n = arrays[0].shape[0]
    for name, a in zip(("energy", "h", "Lz"), arrays[1:], strict=True):
        if a.shape[0] != n:
            raise ValueError(f"{name} has length {a.shape[0]}, alpha has {n}")
    if int(max_steps) < 1:
        raise ValueError(f"max_steps must be >= 1; got {max_steps!r}")
    effects = effects_mask(scene.effects)
    params = scene_params(scene)
    out_f = np.empty((len(_ROWS), n))
    out_n = np.zeros(n, np.int64)
    out_status = np.zeros(n, np.int8)
    if n:
        integrate_points(*arrays, params, mid, effects, r, int(max_steps), out_f, out_n,
                         out_status)  # fmt: skip
    res = {name: out_f[i] for i, name in enumerate(_ROWS)}
    if not effects & ROLLING_RESISTANCE:
        del res["energy_loss"]
    res["n_steps"] = out_n
    res["status"] = out_status
    return res

"""The Runge-Kutta run kernel: convergence order, invariants at tight tolerance, energy drift over
long runs, and what the 8th-order pair buys."""

import numba
import numpy as np
import pytest
from cases import HARD, P003, integrate

import engine
from engine.kernels.cone_starts import initial_state, orbit_start
from engine.kernels.rk import rk_fixed
from engine.kernels.tableaux import RK_TABLEAUX
from engine.scene import Scene
from engine.simulate import simulate

RK45 = [t.name for t in RK_TABLEAUX].index("rk45")
DOP853 = [t.name for t in RK_TABLEAUX].index("dop853")


def _p003_start():
    sc = Scene()
    p = sc.params(P003["alpha"])
    ok, r1, r2, rc = orbit_start(p, P003["calE"], P003["h"], P003["Lz"])
    y0 = initial_state(p, 0, r1, P003["calE"], P003["h"], P003["Lz"])
    y0[2] = 0.0
    return p, y0


@numba.njit
def _fixed(method, y0, p, h, n):
    return rk_fixed(numba.literally(method), 0, y0, p, h, n)


@pytest.mark.parametrize("method,order", [(RK45, 5), (DOP853, 8)])
def test_fixed_step_convergence_order(method, order):
    """Error after a fixed time vs step size: slope of the log-log fit = the method's order."""
    p, y0 = _p003_start()
    t_span = 0.4
    ref = _fixed(DOP853, y0, p, t_span / 4000, 4000)
    ns = [40, 56, 80, 113] if method == RK45 else [12, 16, 20, 24]
    errs = [np.abs(_fixed(method, y0, p, t_span / n, n) - ref).max() for n in ns]
    slope = np.polyfit(np.log(t_span / np.array(ns)), np.log(errs), 1)[0]
    assert order - 0.35 < slope < order + 0.6, (errs, slope)


@pytest.mark.parametrize("method", ["rk45", "dop853"])
def test_rk_conserves_invariants_at_tight_tolerance(method):
    """rtol 1e-12: E, L_z and h stay within 1e-11 relative over five periods (h is conserved
    by the equations exactly, its drift is rounding)."""
    i = P003
    ds = simulate(i["alpha"], i["calE"], i["h"], i["Lz"], periods=5, method=method,
                         rtol=1e-12)  # fmt: skip
    assert np.abs(ds.E_drift).max() <= 1e-11 * abs(ds.attrs["E0"])
    assert np.abs(ds.Lz_drift).max() <= 1e-11 * abs(ds.attrs["Lz0"])
    assert np.abs(ds.h_drift).max() <= 1e-11 * abs(ds.attrs["h0"])


def _deciles(x):
    n = x.size
    return np.array([np.abs(x[k * n // 10 : (k + 1) * n // 10]).max() for k in range(10)])


def test_rk45_energy_drift_is_reported_over_1e4_periods():
    """RK45 is not symplectic: its energy error grows linearly, and simulate reports it."""
    i = P003
    T = float(engine.evaluate(i["alpha"], i["calE"], i["h"], i["Lz"]).period)
    ds = simulate(i["alpha"], i["calE"], i["h"], i["Lz"], periods=10_000,
                         method="rk45", rtol=1e-8, dt_out=0.77 * T)  # fmt: skip
    assert ds.E_drift.attrs["units"] == "J"
    dec = _deciles(ds.E_drift.values / ds.attrs["E0"])
    print("rk45 |dE/E| per decile of 10^4 periods:", dec)
    assert dec[-1] > 5 * dec[0]  # secular growth, visible in the output
    # the drift stays within the sum of the local error bounds
    assert dec[-1] <= ds.attrs["n_steps"] * 1e-8


def test_dop853_takes_fewer_steps_at_tight_tolerance():
    c = HARD["spin_dominated_hLz>0"]
    n45 = integrate(c, "rk45", rtol=1e-12)["n_steps"]
    n853 = integrate(c, "dop853", rtol=1e-12)["n_steps"]
    print(f"rtol 1e-12: rk45 {n45} steps, dop853 {n853} steps per period")
    assert n853 < n45 / 3

"""The symplectic run kernel: convergence order of the Yoshida compositions, and an energy error
that stays bounded over 10^4 periods."""

import numpy as np
import pytest
from cases import P003
from test_rk import _deciles, _p003_start

import engine
from engine.kernels import symplectic as sym
from engine.simulate import simulate


@pytest.mark.parametrize("order", [2, 4, 6])
def test_yoshida_convergence_order(order):
    """The TTL leapfrog composed by Yoshida: global error at a fixed fictitious time ~ h^order."""
    p, y0 = _p003_start()
    E, hh, Lz = P003["calE"], P003["h"], P003["Lz"]
    z0 = sym.initial_z(p, y0[0], 0.0, E, hh, Lz)
    s_span = 4.0
    ref = sym.sym_fixed(z0, p, E, hh, Lz, 6, s_span / 4096, 4096)
    ns = {2: [64, 128, 256, 512], 4: [32, 48, 64, 96], 6: [16, 24, 32, 48]}[order]
    errs = []
    for n in ns:
        z = sym.sym_fixed(z0, p, E, hh, Lz, order, s_span / n, n)
        errs.append(max(abs(z[0] - ref[0]) / ref[0], abs(z[2] - ref[2]), abs(z[3] - ref[3])))
    slope = np.polyfit(np.log(s_span / np.array(ns)), np.log(errs), 1)[0]
    assert order - 0.3 < slope < order + 0.6, (errs, slope)


def test_symplectic_energy_error_bounded_over_1e4_periods():
    """10^4 radial periods (rtol 1e-8, so the method's error dominates rounding): the energy
    error oscillates with a constant envelope, no secular growth, and stays below rtol."""
    i = P003
    T = float(engine.evaluate(i["alpha"], i["calE"], i["h"], i["Lz"]).period)
    ds = simulate(i["alpha"], i["calE"], i["h"], i["Lz"], periods=10_000,
                         method="symplectic", rtol=1e-8, dt_out=0.77 * T)  # fmt: skip
    dec = _deciles(ds.E_drift.values / ds.attrs["E0"])
    print("symplectic |dE/E| per decile of 10^4 periods:", dec)
    assert dec.max() <= 1e-8
    assert dec[-1] <= 1.2 * dec[0]
    assert ds.sizes["event"] == 20_000
    assert ds.event_time.values[-1] == pytest.approx(10_000 * T, rel=100 * 1e-8)

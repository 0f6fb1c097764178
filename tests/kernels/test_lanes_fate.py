"""Fate maps on the SIMD lanes (engine.kernels.lanes_fate): every output of the scalar fate
kernel (engine.kernels.fate.fate_points, one orbit per thread), bit for bit, on a few hundred
mixed launches that end in every fate, with a horizon in time and with one in revolutions."""

import math

import numpy as np
import pytest

from engine.integrated import fate_points
from engine.kernels.cone import coefficients
from engine.kernels.effects import REVOLUTIONS
from engine.kernels.fate import FATE_NAMES, FATE_ROWS
from engine.kernels.layouts import P_THETA_MAX
from engine.methods import METHODS
from engine.scene import Scene

SCENE = Scene(c_rr=0.3, rim=2.5, mu=1.5)


def launches(n, seed):
    """(alpha, calE, h, L_z, r_start) of n launches at rest radially (u = 0) at r0 with
    tangential speed v0 and spin w0, plus the edges: radial orbits from the vertex and from
    inside its region, starts beyond the rim, at rest, and not a number."""
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(0.3, 1.5, n)
    r0 = rng.uniform(0.05, 3.0, n)
    v0 = np.where(rng.uniform(size=n) < 0.15, 0.0, rng.uniform(-4.0, 4.0, n))
    w0 = rng.uniform(-3.0, 3.0, n)
    r0[:6] = (0.0, 0.0, 5e-5, 5e-5, math.nan, 2.6)  # vertex, inside its region, NaN, off the rim
    v0[:4] = 0.0
    s, c = np.sin(alpha), np.cos(alpha)
    Lz = SCENE.M * r0 * s * v0
    h = w0 - np.where(r0 > 0, Lz * c / (SCENE.M * np.where(r0 > 0, r0, 1.0) * s * s), 0.0)
    energy = np.empty(n)
    for i in range(n):
        A, B, C = coefficients(alpha[i], h[i], Lz[i], SCENE.M, SCENE.g, SCENE.k)
        r = r0[i] if r0[i] > 0 else 1.0
        energy[i] = (A / (r * r) if A else 0.0) + B / r + C * r
    energy[:2] = (3.0, 1e-4)  # radial energies at the vertex: one gets out, one does not
    return alpha, energy, h, Lz, r0


def run(pts, method, effects, theta_max, max_steps, lanes):
    n = pts[0].size
    params = SCENE.params()
    params[P_THETA_MAX] = theta_max
    out = np.full(n, -1, np.int8), np.full((len(FATE_ROWS), n), -7.0), np.full(n, -1, np.int64)
    fate_points(*pts, params, METHODS[method].kernel_id, effects, 1e-9, 3.0, max_steps, *out,
                lanes=lanes)  # fmt: skip
    return out


@pytest.mark.parametrize("revolutions", [None, 1.5])
def test_lanes_fate_maps_equal_the_scalar_kernel_bit_for_bit(revolutions):
    """Fate, every float row (as bits: -0.0 and NaN payloads too) and n_steps equal; every fate
    occurs, on the whole step budget and on one that some orbits exhaust. rk45 on the effect
    sets tests/test_fates.py compiles for the lanes (dop853, whose dense output has stages of
    its own, passes too: a compile more than the suite's budget allows)."""
    method = "rk45"
    pts = launches(300, 11)
    effects = SCENE.effects_mask
    theta_max = math.inf
    if revolutions is not None:
        effects |= REVOLUTIONS
        theta_max = 2.0 * math.pi * revolutions
    seen = set()
    for max_steps in (10**6, 150):
        want = run(pts, method, effects, theta_max, max_steps, lanes=False)
        got = run(pts, method, effects, theta_max, max_steps, lanes=True)
        np.testing.assert_array_equal(got[0], want[0], err_msg="fate")
        np.testing.assert_array_equal(got[1].view(np.int64), want[1].view(np.int64), "rows")
        np.testing.assert_array_equal(got[2], want[2], err_msg="n_steps")
        seen |= {FATE_NAMES[f] for f in want[0]}
    assert seen == set(FATE_NAMES), set(FATE_NAMES) - seen

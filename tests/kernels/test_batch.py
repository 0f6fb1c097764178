"""The closed form over arrays (engine.kernels.batch): the lanes give the scalar kernel's numbers
bit for bit, on every class and scene; the grid kernel gives the flat kernel's."""

import math

import numba
import numpy as np
import pytest
from numba import njit

from engine.evaluation import orbit_batch, orbit_grid
from engine.kernels.batch import (
    LANES,
    STAGES,
    minimum_energy_batch,
    profile_batch,
)
from engine.kernels.batch_rows import empty_outputs
from engine.kernels.geometry import BOUNDED, CLASS_NAMES, OUT_OF_RANGE, orbit_point, scene_params

# (M, g, k, a, rim, mu): gravity, extreme scales, free fall, a point particle, a rim, a
# friction limit, both.
SCENES = [
    (1.0, 9.81, 0.4, 0.0, math.inf, math.inf),
    (1e-3, 1e-3, 5.0, 0.0, math.inf, math.inf),
    (1e3, 50.0, 2 / 3, 0.0, math.inf, math.inf),
    (1.0, 0.0, 0.4, 0.0, math.inf, math.inf),
    (2.0, 1.0, 0.0, 0.0, math.inf, math.inf),
    (1.0, 9.81, 0.4, 0.01, 3.0, math.inf),
    (1.0, 9.81, 0.4, 0.01, math.inf, 0.3),
    (1.0, 0.0, 0.4, 0.02, 5.0, 0.5),
]


@njit
def _scalar(alpha, energy, h, Lz, p, cls, f):
    for i in range(alpha.size):
        c, r1, r2, rc, T, psi, prec, mur, er, et, eth = orbit_point(
            alpha[i], energy[i], h[i], Lz[i], p, 1e-12
        )
        cls[i] = c
        f[0, i], f[1, i], f[2, i], f[3, i], f[4, i] = r1, r2, rc, T, psi
        f[5, i], f[6, i], f[7, i], f[8, i], f[9, i] = prec, mur, er, et, eth


def _points(n, seed, M, g, k):
    """Points over the whole domain: alpha up to 1e-8 from 0 and pi/2, |h|, |L_z| over 12
    decades or 0, energies V_min + x |V_min| (x over 19 decades, 0 and negative) or absolute."""
    rng = np.random.default_rng(seed)

    def lu(lo, hi):
        return 10.0 ** rng.uniform(lo, hi, n)

    def sign():
        return rng.choice([-1.0, 1.0], n)

    alpha = np.where(rng.random(n) < 0.8, rng.uniform(1e-8, math.pi / 2, n), lu(-8, -6))
    alpha = np.where(rng.random(n) < 0.1, math.pi / 2 - lu(-15, -6), alpha)
    h = np.where(rng.random(n) < 0.2, 0.0, sign() * lu(-6, 6))
    Lz = np.where(rng.random(n) < 0.05, 0.0, sign() * lu(-6, 6))
    offset = np.where(rng.random(n) < 0.1, 0.0, lu(-16, 3) * np.where(rng.random(n) < 0.15, -1, 1))
    well = np.empty((2, n))
    minimum_energy_batch(alpha, h, Lz, scene_params(M, g, k), well)
    vmin = well[0]
    absolute = np.where(rng.random(n) < 0.2, 0.0, sign() * lu(-6, 6))
    relative = (rng.random(n) < 0.75) & np.isfinite(vmin)
    energy = np.where(relative, vmin + offset * np.abs(vmin), absolute)
    return alpha, energy, h, Lz


def _scalar_outputs(n):
    """Outputs of _scalar: class int8[n], float64[10, n]."""
    return np.empty(n, np.int8), np.empty((10, n))


def _same(a, b):
    return np.array_equal(a, b, equal_nan=True)


def _scene_id(s):
    return f"M{s[0]}-g{s[1]}-k{s[2]:.2g}-rim{s[4]}-mu{s[5]}"


@pytest.mark.parametrize("scene", SCENES, ids=_scene_id)
def test_lanes_equal_the_scalar_kernel_bit_for_bit(scene):
    M, g, k = scene[:3]
    alpha, energy, h, Lz = _points(20_000 + 7, 11, M, g, k)  # a partial last block too
    c1, f1 = empty_outputs(alpha.size)
    c2, f2 = _scalar_outputs(alpha.size)
    orbit_batch(alpha, energy, h, Lz, scene_params(*scene), 1e-12, c1, f1)
    _scalar(alpha, energy, h, Lz, scene_params(*scene), c2, f2)
    assert _same(c1, c2) and _same(np.stack(f1), f2)
    # the sample reaches several classes (the lanes' scalar path) besides bounded
    classes = {CLASS_NAMES[c] for c in np.unique(c1)}
    assert {"forbidden", "bounded"} <= classes and len(classes) >= 4


@pytest.mark.parametrize("n", [0, 1, LANES - 1, LANES, LANES + 1, 5 * LANES + 3])
def test_lanes_any_number_of_points(n):
    rng = np.random.default_rng(n)
    alpha = rng.uniform(0.2, 1.4, n)
    h = rng.uniform(-2, 2, n)
    Lz = rng.uniform(0.1, 2, n)
    energy = rng.uniform(-5, 30, n)
    c1, f1 = empty_outputs(n)
    c2, f2 = _scalar_outputs(n)
    orbit_batch(alpha, energy, h, Lz, scene_params(1.0, 9.81, 0.4), 1e-12, c1, f1)
    _scalar(alpha, energy, h, Lz, scene_params(1.0, 9.81, 0.4), c2, f2)
    assert _same(c1, c2) and _same(np.stack(f1), f2)


def test_rows_not_wanted_are_not_written():
    """A row of length 0 (not wanted) is skipped; the rows wanted are the full run's."""
    alpha, energy, h, Lz = _points(2000, 9, *SCENES[7][:3])
    p = scene_params(*SCENES[7])
    c1, f1 = empty_outputs(alpha.size)
    c2, f2 = empty_outputs(alpha.size, {"r_max", "mu_required", "end_time"})
    assert sum(row.size for row in f2) == 3 * alpha.size
    orbit_batch(alpha, energy, h, Lz, p, 1e-12, c1, f1)
    orbit_batch(alpha, energy, h, Lz, p, 1e-12, c2, f2)
    assert _same(c1, c2) and all(_same(a, b) for a, b in zip(f1, f2, strict=True) if b.size)


@pytest.mark.parametrize("relative", [True, False])
@pytest.mark.parametrize("scene", [SCENES[0], SCENES[3], SCENES[7]], ids=_scene_id)
def test_grid_equals_flat_kernel(relative, scene):
    M, g, k = scene[:3]
    alpha = np.array([1e-7, 0.3, 0.9, 1.4, math.pi / 2 - 1e-9])
    energy = np.concatenate([[-1e-3, 0.0, 1e-13], np.geomspace(1e-9, 30, 70)])
    if not relative:
        energy = np.concatenate([-energy[::-1], energy])
    h = np.array([-3.0, 0.0, 1e-5, 2.0])
    Lz = np.array([-2.0, -1e-4, 0.0, 1e-7, 0.05, 1.0, 3.0])
    n = alpha.size * energy.size * h.size * Lz.size
    cls, rows, e_abs = *empty_outputs(n), np.empty(n)
    orbit_grid(alpha, energy, h, Lz, relative, scene_params(*scene), 1e-12, cls, rows, e_abs)
    f = np.stack(rows)
    A, E, H, L = (x.reshape(-1) for x in np.meshgrid(alpha, energy, h, Lz, indexing="ij"))
    well = np.empty((2, n))
    minimum_energy_batch(A, H, L, scene_params(*scene), well)
    # r_circ is the family's r_c (stored on (alpha, h, Lz)): at every energy where the point
    # reports one, bit for bit; NaN elsewhere only where the point is out of range
    rc = f[2]
    assert np.array_equal(rc[~np.isnan(rc)], well[1][~np.isnan(rc)])
    assert (cls[np.isnan(rc) & ~np.isnan(well[1])] == OUT_OF_RANGE).all()
    if relative:
        vmin = well[0]
        E = vmin + E * np.abs(vmin)  # the rule of engine.evaluation (numpy arithmetic)
    assert _same(e_abs, E)
    c2, rows2 = empty_outputs(n)
    orbit_batch(A, E, H, L, scene_params(*scene), 1e-12, c2, rows2)
    f2 = np.stack(rows2)
    undefined = np.isnan(E)
    if relative:  # no V_min (L_z = 0 here): forbidden, nothing but r_circ
        assert undefined.any()
        c2[undefined] = 0
        f2[np.ix_([i for i in range(10) if i != 2], np.flatnonzero(undefined))] = np.nan
    assert _same(cls, c2) and _same(f, f2)
    assert len(np.unique(cls)) >= 3  # several classes, the lanes and their scalar path


def test_grid_with_one_triple_and_many_energies():
    energy = np.geomspace(1e-8, 10, 300)
    cls, f, e_abs = *empty_outputs(300), np.empty(300)
    p = scene_params(1.0, 9.81, 0.4)
    orbit_grid(np.array([0.6]), energy, np.array([1.0]), np.array([0.7]), True, p, 1e-12, cls, f,
               e_abs)  # fmt: skip
    c2, f2 = empty_outputs(300)
    n = np.ones(300)
    orbit_batch(0.6 * n, e_abs, n, 0.7 * n, p, 1e-12, c2, f2)
    assert _same(cls, c2) and _same(f, f2) and (cls == BOUNDED).all()


def test_profile_runs_the_real_stages():
    """The benchmark's stage profile times the kernel itself: all stages = orbit_batch."""
    rng = np.random.default_rng(3)
    n = 1000
    alpha, h, Lz = rng.uniform(0.2, 1.4, n), rng.uniform(-2, 2, n), rng.uniform(0.1, 2, n)
    energy = rng.uniform(0, 30, n)
    c1, f1 = empty_outputs(n)
    c2, f2 = empty_outputs(n)
    p = scene_params(1.0, 9.81, 0.4)
    profile_batch(alpha, energy, h, Lz, p, 1e-12, c1, f1, len(STAGES) - 1)
    orbit_batch(alpha, energy, h, Lz, p, 1e-12, c2, f2)
    assert _same(c1, c2) and _same(f1, f2)


def test_results_do_not_depend_on_the_number_of_threads():
    """The units of work are split among threads (engine.evaluation): 1 thread and all of them
    give the same numbers, flat and on a grid."""
    alpha, energy, h, Lz = _points(3000, 5, 1.0, 9.81, 0.4)
    axes = (np.array([0.3, 1.1]), np.geomspace(1e-6, 5, 90), np.array([-1.0, 2.0]), Lz[:40])
    ng = 2 * 90 * 2 * 40
    runs = []
    before = numba.get_num_threads()
    try:
        for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(threads)
            c1, f1 = empty_outputs(alpha.size)
            orbit_batch(alpha, energy, h, Lz, scene_params(*SCENES[0]), 1e-12, c1, f1)
            c2, f2, e2 = *empty_outputs(ng), np.empty(ng)
            orbit_grid(*axes, True, scene_params(*SCENES[0]), 1e-12, c2, f2, e2)
            runs.append((c1, f1, c2, f2, e2))
    finally:
        numba.set_num_threads(before)
    assert numba.config.NUMBA_NUM_THREADS == 1 or len(runs) == 2
    assert all(_same(a, b) for a, b in zip(runs[0], runs[-1], strict=True))

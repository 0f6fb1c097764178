"""Evaluating maps over flat points and survey blocks (engine.evaluation)."""

import numba
import numpy as np
import pytest

import engine
from engine.backends import compute_block
from engine.evaluation import bad_inputs, block_variables, evaluate_block, evaluate_flat
from engine.families import family_values, minimum_energy_flat
from engine.grid import Tiling
from engine.kernels.geometry import OUT_OF_RANGE
from engine.kernels.workqueue import CHECK_UNIT
from engine.plan import map_plan, survey_plan
from engine.schema import DIMS


def test_block_results_equal_pointwise_evaluation():
    axes = dict(
        alpha=np.array([0.3, 0.7]),
        energy=np.array([10.0, 20.0, 30.0]),
        h=np.array([-1.0, 1.0]),
        Lz=np.array([0.2, 0.5, 0.9]),
    )
    spec = survey_plan(DIMS, axes, engine.Scene(), "exact", circular_tol=1e-12, rtol=1e-10)
    block = evaluate_block(spec, (slice(1, 2), slice(0, 3), slice(0, 2), slice(1, 3)))
    assert block["period"].shape == (1, 3, 2, 2)
    ds = engine.evaluate(0.7, 20.0, 1.0, 0.9)
    assert int(ds.orbit_class) == 1
    assert block["period"][0, 1, 1, 1] == float(ds.period)


@pytest.mark.parametrize("relative", [True, False])
@pytest.mark.parametrize(
    "scene", [engine.Scene(), engine.Scene(g=0.0), engine.Scene(rim=3.0, mu=0.3)], ids=str
)
def test_grid_path_equals_flat_path_bit_for_bit(relative, scene):
    """A closed-form block runs the grid kernel (the family once per (alpha, h, L_z)); a point's
    numbers are those engine.evaluate's flat path gives it."""
    axes = dict(
        alpha=np.array([0.2, 0.7, 1.4]),
        energy=np.concatenate([[-1e-3, 0.0, 1e-13], np.geomspace(1e-9, 30, 20)])
        * (1.0 if relative else 3.0),
        h=np.array([-3.0, 0.0, 1.5]),
        Lz=np.array([-1.0, 0.0, 1e-6, 0.3, 2.0]),
    )
    spec = survey_plan(DIMS, axes, scene, "exact", energy_relative=relative, circular_tol=1e-12,
                       rtol=1e-10)  # fmt: skip
    block = evaluate_block(spec, (slice(0, 3), slice(0, 23), slice(0, 3), slice(0, 5)))
    assert set(block) == set(block_variables(spec))
    # into buffers (the survey reuses them from block to block): the same numbers bit for bit,
    # every value written (the buffers start full of other numbers)
    out = {n: np.full((3, 23, 3, 5), 7, dt) for n, dt in block_variables(spec).items()}
    got = evaluate_block(spec, (slice(0, 3), slice(0, 23), slice(0, 3), slice(0, 5)), out=out)
    assert got is out and all(out[n] is got[n] for n in out)
    for name, col in block.items():
        assert np.array_equal(out[name], col, equal_nan=True), name
    # r_circ and V_min are not in a block: stored on (alpha, h, Lz), computed once per triple
    fam = family_values(DIMS, axes, scene, spec.map_kind, spec.variables)
    assert set(fam) == ({"r_circ", "V_min"} if relative else {"r_circ"})
    assert all(v.shape == (3, 3, 5) for v in fam.values())
    per_point = {n: np.broadcast_to(v[:, None], (3, 23, 3, 5)).reshape(-1) for n, v in fam.items()}
    A, E, H, L = (x.reshape(-1) for x in np.meshgrid(*axes.values(), indexing="ij"))
    if relative:
        vmin = minimum_energy_flat(A, H, L, scene)
        assert np.array_equal(per_point["V_min"], vmin, equal_nan=True)
        E = vmin + E * np.abs(vmin)
    flat = evaluate_flat(A, E, H, L, map_plan(scene))
    undefined = np.isnan(E)  # no V_min: forbidden, nothing but r_circ
    flat["orbit_class"][undefined] = 0
    for name, col in flat.items():
        if name != "r_circ" and col.dtype.kind == "f":
            col[undefined] = np.nan
    # the family's r_circ is each point's, bit for bit, wherever the point reports one; a point
    # reports NaN only where it is out of range (its class says so)
    rc, fam_rc = flat.pop("r_circ"), per_point["r_circ"]
    assert np.array_equal(rc[~np.isnan(rc)], fam_rc[~np.isnan(rc)])
    assert (flat["orbit_class"][np.isnan(rc) & ~np.isnan(fam_rc)] == OUT_OF_RANGE).all()
    assert set(block) == set(flat)
    for name, col in flat.items():
        assert np.array_equal(block[name].reshape(-1), col, equal_nan=True), name
    assert len(np.unique(flat["orbit_class"])) >= 3


def test_threads_share_the_units_and_give_the_same_numbers():
    """run_units: the threads take units of work from one counter; whatever thread computes a
    unit, every output equals the one-thread run bit for bit, on flat points (more units than
    threads, a last unit shorter than the others) and on a grid block."""
    rng = np.random.default_rng(4)
    n = 5 * 512 + 37  # six units of 512 points, the last one short
    a, h, lz = rng.uniform(0.2, 1.4, n), rng.uniform(-2, 2, n), rng.uniform(0.05, 2, n)
    e = minimum_energy_flat(a, h, lz, engine.Scene()) * rng.uniform(0.5, 3.0, n)
    axes = dict(alpha=np.linspace(0.2, 1.4, 3), energy=np.geomspace(1e-6, 10, 130),
                h=np.linspace(-2, 2, 5), Lz=np.linspace(0.1, 2, 7))  # fmt: skip
    spec = survey_plan(DIMS, axes, engine.Scene(), "exact", energy_relative=True,
                       circular_tol=1e-12, rtol=1e-10)  # fmt: skip
    grid = (slice(0, 3), slice(0, 130), slice(0, 5), slice(0, 7))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = evaluate_flat(a, e, h, lz, map_plan(engine.Scene())), evaluate_block(spec, grid)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        for _ in range(3):
            many = evaluate_flat(a, e, h, lz, map_plan(engine.Scene())), evaluate_block(spec, grid)
            for res1, res2 in zip(one, many, strict=True):
                assert set(res1) == set(res2)
                for name in res1:
                    assert np.array_equal(res1[name], res2[name], equal_nan=True), name
    finally:
        numba.set_num_threads(before)
    assert len(np.unique(one[0]["orbit_class"])) >= 2


def test_inputs_are_checked_on_the_threads():
    """bad_inputs: each bad value (NaN, +-inf, out of the open interval) flagged in its own
    array, wherever it lies among the threads' units (the first and last point, both sides of
    a unit's edge); engine.evaluate on inputs of one shape names the first bad value of the
    first bad input, as for a scalar input, and its coordinates hold the inputs."""
    n = 2 * CHECK_UNIT + 5  # three units per array, the last one short
    rng = np.random.default_rng(9)
    a, e, h, lz = (rng.uniform(0.2, 1.4, n) for _ in range(4))
    lo, hi = (0.0, -np.inf, -np.inf, -np.inf), (np.pi / 2, np.inf, np.inf, np.inf)
    before = numba.get_num_threads()
    try:
        for nt in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(nt)
            assert not bad_inputs((a, e, h, lz), lo, hi).any()
            for i, value in ((0, np.nan), (CHECK_UNIT - 1, np.inf), (CHECK_UNIT, -np.inf),
                             (n - 1, np.nan)):  # fmt: skip
                for j, arr in enumerate((e, h, lz)):
                    x = arr.copy()
                    x[i] = value
                    arrays = [a, e, h, lz]
                    arrays[j + 1] = x
                    assert bad_inputs(tuple(arrays), lo, hi).tolist() == [
                        k == j + 1 for k in range(4)
                    ]
            for value in (0.0, np.pi / 2, -0.1, np.nan):
                x = a.copy()
                x[CHECK_UNIT + 1] = value
                assert bad_inputs((x, e, h, lz), lo, hi).tolist() == [1, 0, 0, 0]
            x, y = a.copy(), e.copy()
            x[n - 1], x[CHECK_UNIT + 3], y[0] = np.pi / 2, -0.5, np.nan
            with pytest.raises(ValueError, match=r"^alpha must .*; got -0\.5$"):
                engine.evaluate(x, y, h, lz)  # alpha before energy; its first bad value
            with pytest.raises(ValueError, match=r"^energy must .*; got nan$"):
                engine.evaluate(a, y, h, lz)
        ds = engine.evaluate(a[:100], e[:100], h[:100], lz[:100])
        for name, arr in zip(("alpha", "energy", "h", "Lz"), (a, e, h, lz), strict=True):
            assert np.array_equal(ds[name].values, arr[:100])
    finally:
        numba.set_num_threads(before)


def test_one_period_map_of_bounded_points_only_equals_the_mixed_map():
    """A one-period map whose points are all bounded takes the integrator's outputs as they
    are (no copies, no fill): the same numbers and dtypes, bit for bit, as the same points
    beside a forbidden one (where the bounded ones are picked out and put back)."""
    rng = np.random.default_rng(12)
    n = 40
    a, h, lz = rng.uniform(0.3, 1.2, n), rng.uniform(-1, 1, n), rng.uniform(0.3, 1.5, n)
    vmin = minimum_energy_flat(a, h, lz, engine.Scene())
    e = vmin + rng.uniform(0.2, 2.0, n) * np.abs(vmin)
    plan = map_plan(engine.Scene(), "dop853", rtol=1e-10)
    every = evaluate_flat(a, e, h, lz, plan)
    assert (every["orbit_class"] == 1).all() and (every["status"] == 0).all()
    mixed = evaluate_flat(*(np.append(x, v) for x, v in ((a, 0.5), (e, -1e3), (h, 0.0),
                                                         (lz, 1.0))), plan)  # fmt: skip
    assert mixed["orbit_class"][-1] == 0 and mixed["status"][-1] != 0
    assert set(every) == set(mixed)
    for name, col in every.items():
        assert col.dtype == mixed[name].dtype, name
        assert np.array_equal(col, mixed[name][:n], equal_nan=True), name


def _grid_spec(**kw):
    axes = dict(alpha=np.array([0.3, 0.7, 1.1]), energy=np.geomspace(1e-6, 20.0, 7),
                h=np.array([-1.0, 1.0]), Lz=np.array([0.0, 0.2, 0.5, 0.9]))  # fmt: skip
    return survey_plan(DIMS, axes, engine.Scene(), circular_tol=1e-12, rtol=1e-10,
                       energy_relative=True, **kw)  # fmt: skip


@pytest.mark.parametrize("precision", ["double", "single"])
def test_blocks_into_reused_buffers_equal_fresh_blocks(precision):
    """compute_block with buffers (1-D, room for the largest block; a survey reuses them):
    each block bit for bit the fresh one, float32 cast as the fresh block is (single)."""
    spec = _grid_spec(precision=precision, block_points=30)
    tiling = Tiling((3, 7, 2, 4), (1, 3, 2, 4), (1, 3, 2, 4))  # 9 blocks of 24 or 8 points
    assert tiling.nblocks > 2 and len({tiling.points(i) for i in range(tiling.nblocks)}) > 1
    names = block_variables(spec)
    assert names["period"] == (np.float32 if precision == "single" else np.float64)
    big = max(tiling.points(i) for i in range(tiling.nblocks))
    buffers = {n: np.full(big, -3, dt) for n, dt in names.items()}
    for i in range(tiling.nblocks):
        _, fresh = compute_block(spec, tiling, i)
        _, into = compute_block(spec, tiling, i, out=buffers)
        assert set(into) == set(fresh) == set(names)
        for name, col in fresh.items():
            assert into[name].dtype == col.dtype and into[name].shape == col.shape, name
            assert np.shares_memory(into[name], buffers[name]), name
            assert np.array_equal(into[name], col, equal_nan=True), (i, name)


def test_one_period_block_into_buffers_equals_the_fresh_block():
    """Maps other than the closed form are computed, then copied into the buffers."""
    axes = dict(alpha=np.array([0.5, 0.9]), energy=np.array([0.3, 1.0]), h=np.array([0.4]),
                Lz=np.array([0.6, 1.1]))  # fmt: skip
    spec = survey_plan(DIMS, axes, engine.Scene(), "dop853", energy_relative=True, rtol=1e-10)
    whole = (slice(0, 2), slice(0, 2), slice(0, 1), slice(0, 2))
    fresh = evaluate_block(spec, whole)
    out = {n: np.zeros((2, 2, 1, 2), dt) for n, dt in block_variables(spec).items()}
    assert set(fresh) == set(out) and "n_steps" in out
    evaluate_block(spec, whole, out=out)
    for name, col in fresh.items():
        assert np.array_equal(out[name], col, equal_nan=True), name


def test_buffers_that_do_not_fit_are_refused_naming_the_variable():
    spec = _grid_spec()
    whole = (slice(0, 3), slice(0, 7), slice(0, 2), slice(0, 4))
    good = {n: np.empty((3, 7, 2, 4), dt) for n, dt in block_variables(spec).items()}
    cases = [
        ({**good, "period": np.empty((3, 7, 2, 3))}, "out['period'] has shape (3, 7, 2, 3)"),
        ({**good, "r_min": np.empty((3, 7, 2, 4), np.float32)}, "out['r_min'] has dtype float32"),
        ({**good, "orbit_class": np.empty((3, 7, 2, 4))}, "out['orbit_class'] has dtype float64"),
        ({**good, "r_max": np.empty((4, 2, 7, 3)).T}, "out['r_max'] is not a writeable C-contig"),
        ({k: v for k, v in good.items() if k != "mu_required"}, "missing ['mu_required']"),
        ({**good, "r_circ": np.empty((3, 7, 2, 4))}, "unknown ['r_circ']"),
    ]
    for out, message in cases:
        with pytest.raises(ValueError) as err:
            evaluate_block(spec, whole, out=out)
        assert message in str(err.value)

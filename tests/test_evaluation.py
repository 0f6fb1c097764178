"""Evaluating maps over flat points and survey blocks (engine.evaluation)."""

import numpy as np
import pytest

import engine
from engine.evaluation import evaluate_block, evaluate_flat, minimum_energy_flat


def test_block_results_equal_pointwise_evaluation():
    axes = dict(
        alpha=np.array([0.3, 0.7]),
        energy=np.array([10.0, 20.0, 30.0]),
        h=np.array([-1.0, 1.0]),
        Lz=np.array([0.2, 0.5, 0.9]),
    )
    spec = dict(
        axes,
        scene=engine.Scene(),
        method="exact",
        energy_relative=False,
        circular_tol=1e-12,
        rtol=1e-10,
    )
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
    spec = dict(
        axes, scene=scene, method="exact", energy_relative=relative, circular_tol=1e-12, rtol=1e-10
    )
    block = evaluate_block(spec, (slice(0, 3), slice(0, 23), slice(0, 3), slice(0, 5)))
    A, E, H, L = (x.reshape(-1) for x in np.meshgrid(*axes.values(), indexing="ij"))
    if relative:
        vmin = minimum_energy_flat(A, H, L, scene)
        assert np.array_equal(block["energy_absolute"].reshape(-1), vmin + E * np.abs(vmin),
                              equal_nan=True)  # fmt: skip
        E = vmin + E * np.abs(vmin)
    flat = evaluate_flat(A, E, H, L, scene)
    undefined = np.isnan(E)  # no V_min: forbidden, nothing but r_circ
    flat["orbit_class"][undefined] = 0
    for name, col in flat.items():
        if name != "r_circ" and col.dtype.kind == "f":
            col[undefined] = np.nan
    assert set(block) == set(flat) | ({"energy_absolute"} if relative else set())
    for name, col in flat.items():
        assert np.array_equal(block[name].reshape(-1), col, equal_nan=True), name
    assert len(np.unique(flat["orbit_class"])) >= 3

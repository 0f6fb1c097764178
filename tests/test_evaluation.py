"""Evaluating maps over flat points and survey blocks (engine.evaluation)."""

import numpy as np

import engine
from engine.evaluation import evaluate_block


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

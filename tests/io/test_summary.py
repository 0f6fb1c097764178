"""The run's summary: value ranges over the finite values only, whatever NaN and infinities a
block holds (the one-pass fmin/fmax path and its fallback give the same ranges)."""

from __future__ import annotations

import numpy as np

from engine.io.summary import Summary


def test_ranges_skip_nan_and_infinities_and_all_nan_variables():
    s = Summary()
    s.add(
        {
            "r_min": np.array([[np.nan, 0.5], [2.0, np.nan]]),  # NaN only: the fast path
            "r_max": np.array([np.inf, 3.0, -1.0, -np.inf, np.nan]),  # infinities: fallback
            "period": np.full(4, np.nan),  # nothing finite: no range
            "apsidal_angle": np.array([1.5, 2.5], np.float32),
        }
    )
    s.add({"r_min": np.array([-4.0, np.nan]), "r_max": np.array([np.nan, np.inf])})
    ranges = s.ranges
    assert ranges["r_min"][:2] == (-4.0, 2.0)
    assert ranges["r_max"][:2] == (-1.0, 3.0)
    assert "period" not in ranges
    assert ranges["apsidal_angle"][:2] == (1.5, 2.5)


def test_ranges_come_in_the_order_of_the_schema_whatever_order_the_blocks_bring():
    """A Zarr run hands its blocks' variables over in another order than a netCDF run (the
    variables on fewer dims first); the summary lists them in one order either way."""
    names = ["V_min", "r_circ", "mu_required", "r_min", "period", "r_max"]
    orders = []
    for order in (names, names[::-1]):
        s = Summary()
        s.add({n: np.array([1.0, 2.0]) for n in order})
        orders.append(list(s.ranges))
    assert orders[0] == orders[1] == ["r_min", "r_max", "r_circ", "period", "mu_required", "V_min"]

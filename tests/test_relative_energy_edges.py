"""A relative energy axis at extreme |L_z| says what an absolute one says (issue 19, item 10).

Where the effective potential's coefficients leave float64 (|L_z| = 1e-170 or 1e155), V_min is
NaN and ``evaluate`` classes every energy ``out_of_range``; a relative survey used to class the
same points ``forbidden``. Ordinary points (and L_z = 0, which has no minimum) keep their class.
"""

import numpy as np
import pytest

import engine
from engine.kernels.geometry import FORBIDDEN, OUT_OF_RANGE

EXTREME_LZ = [1e-170, -1e-170, 1e155, -1e155]


@pytest.mark.parametrize("method", ["exact", "rk45"])
def test_relative_survey_is_out_of_range_where_evaluate_is(method):
    alpha, h = 0.3, 0.0
    for Lz in EXTREME_LZ:
        assert np.isnan(engine.minimum_energy(alpha, h, Lz))
        for energy in (-1.0, 0.0, 1.0, 1e3):
            assert int(engine.evaluate(alpha, energy, h, Lz, method=method).orbit_class) == (
                OUT_OF_RANGE
            )
    ds = engine.survey([alpha], [-0.5, 0.0, 0.5, 2.0], [h], [0.0, 0.01, *EXTREME_LZ],
                       method=method, energy_relative=True)  # fmt: skip
    cls = ds.orbit_class.values[0, :, 0, :]
    assert (cls[:, 2:] == OUT_OF_RANGE).all(), cls
    assert (cls[:, 0] == FORBIDDEN).all(), cls  # L_z = 0: no minimum, forbidden as before
    assert np.isnan(ds.cone.energy_absolute().values[0, :, 0, 2:]).all()
    # an ordinary L_z: the class of the absolute energy V_min + offset |V_min|
    e_abs = ds.cone.energy_absolute().values[0, :, 0, 1]
    want = [int(engine.evaluate(alpha, e, h, 0.01, method=method).orbit_class) for e in e_abs]
    assert list(cls[:, 1]) == want
    assert OUT_OF_RANGE not in want

"""The run protocol shared by every integrator: events (apsides) located as roots of the cubic,
for each method."""

import numpy as np
import pytest
from cases import METHODS, P003, RTOL

from engine.kernels.cone import coefficients
from engine.scene import Scene
from engine.simulate import simulate


@pytest.mark.parametrize("method", METHODS)
def test_apsides_are_roots_of_the_cubic(method):
    """Event radii = positive roots of C r^3 - calE r^2 + B r + A (numpy.roots), within
    10 rtol relative (r is stationary at an apsis, so a timing error enters squared)."""
    i = P003
    sc = Scene()
    A, B, C = coefficients(i["alpha"], i["h"], i["Lz"], sc.M, sc.g, sc.k)
    roots = np.sort(np.roots([C, -i["calE"], B, A]).real)
    r1, r2 = roots[1], roots[2]
    assert roots[0] < 0 < r1 < r2
    ds = simulate(i["alpha"], i["calE"], i["h"], i["Lz"], periods=3, method=method)
    kinds = ds.event_kind.values
    np.testing.assert_array_equal(kinds, [1, 0, 1, 0, 1, 0])  # apocentre, pericentre, ...
    r_ev = ds.event_r.values
    np.testing.assert_allclose(r_ev[kinds == 1], r2, rtol=10 * RTOL)
    np.testing.assert_allclose(r_ev[kinds == 0], r1, rtol=10 * RTOL)
    # u = 0 at the events: the trajectory's last point is the last event
    assert ds.time.values[-1] == ds.event_time.values[-1]
    assert abs(ds.u.values[-1]) <= 1e-7 * abs(ds.v.values[-1])

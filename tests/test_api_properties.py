"""Property-based tests (hypothesis): invalid API inputs are named in the error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import engine

PI_2 = math.pi / 2
BELOW_PI_2 = math.nextafter(PI_2, 0.0)
EPS = 2.220446049250313e-16
FLOAT_NAMES = (
    "r_min",
    "r_max",
    "r_circ",
    "period",
    "apsidal_angle",
    "precession_rate",
    "mu_required",
)

# --- 4. invalid API inputs --------------------------------------------------------------------

nonfinite = st.sampled_from([math.nan, math.inf, -math.inf])
GOOD = {"alpha": 0.5, "energy": 1.0, "h": 0.3, "Lz": 0.7}


@settings(max_examples=80, deadline=None)
@given(
    name=st.sampled_from(list(GOOD)),
    bad=st.one_of(nonfinite, st.floats(max_value=0.0), st.floats(min_value=PI_2)),
    n=st.integers(1, 5),
    data=st.data(),
)
def test_invalid_api_inputs_name_the_argument(name, bad, n, data):
    if name != "alpha":
        assume(not math.isfinite(bad))
    i = data.draw(st.integers(0, n - 1))
    values = {key: np.full(n, v) for key, v in GOOD.items()}
    values[name][i] = bad
    if data.draw(st.booleans()):  # scalar, broadcast against the others
        values[name] = bad
    for fn in (engine.evaluate, engine.survey):
        with pytest.raises(ValueError) as info:
            fn(**values)
        assert str(info.value).startswith(name), str(info.value)


@settings(max_examples=30, deadline=None)
@given(bad=st.one_of(nonfinite, st.floats(max_value=-5e-324)))
def test_invalid_circular_tol_is_named(bad):
    with pytest.raises(ValueError) as info:
        engine.evaluate(**GOOD, circular_tol=bad)
    assert str(info.value).startswith("circular_tol")


@settings(max_examples=20, deadline=None)
@given(bad=st.one_of(nonfinite, st.floats(max_value=0.0)))
def test_invalid_rtol_is_named_by_the_integrators(bad):
    # method="exact" never uses rtol; the integrator methods validate it
    with pytest.raises(ValueError) as info:
        engine.evaluate(**GOOD, method="rk45", rtol=bad)
    assert str(info.value).startswith("rtol")


@settings(max_examples=40, deadline=None)
@given(field=st.sampled_from(["M", "g", "a", "k", "rim", "mu", "c_rr"]), bad=nonfinite)
def test_non_finite_scene_fields_are_named(field, bad):
    with pytest.raises(ValueError) as info:
        engine.Scene(**{field: bad})
    assert str(info.value).startswith(f"Scene.{field}")

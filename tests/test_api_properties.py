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


# --- strict types: strings, booleans, masks (issue 11) -----------------------------------------

NOT_NUMBERS = [
    "0.5",
    True,
    np.bool_(False),
    np.array(["0.5", "0.6"]),
    np.array([True, False]),
    np.array([0.5, "0.6"], dtype=object),
    np.array([0.5, None], dtype=object),
    np.array([0.5 + 0j]),
    np.array(["2024-01-01"], dtype="datetime64[D]"),
]


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(list(GOOD)), bad=st.sampled_from(NOT_NUMBERS))
def test_text_booleans_and_complex_are_not_numbers(name, bad):
    """np.asarray("0.5", float) is 0.5 and True is 1.0: the API refuses both, naming the
    argument, in evaluate, survey and minimum_energy."""
    values = dict(GOOD, **{name: bad})
    calls = [engine.evaluate, engine.survey]
    if name != "energy":
        calls.append(lambda **kw: engine.minimum_energy(kw["alpha"], kw["h"], kw["Lz"]))
    for fn in calls:
        with pytest.raises(ValueError) as info:
            fn(**values)
        assert str(info.value).startswith(name), str(info.value)


@pytest.mark.parametrize("name", list(GOOD))
def test_masked_values_are_refused_and_an_empty_mask_is_the_data(name):
    data = np.array([0.5, 0.7, 0.9]) if name == "alpha" else np.array([0.3, 1.0, 2.0])
    masked = np.ma.masked_array(data, mask=[False, True, False])
    with pytest.raises(ValueError) as info:
        engine.evaluate(**dict(GOOD, **{name: masked}))
    assert str(info.value).startswith(f"{name} has 1 masked value(s)")
    with pytest.raises(ValueError, match=f"^{name} has 1 masked"):
        engine.survey(**dict(GOOD, **{name: masked}))
    plain = engine.evaluate(**dict(GOOD, **{name: data}))
    unmasked = engine.evaluate(**dict(GOOD, **{name: np.ma.masked_array(data, mask=False)}))
    for var in plain.data_vars:
        np.testing.assert_array_equal(unmasked[var].values, plain[var].values)


@pytest.mark.parametrize("flag", ["no", "yes", 1, 0, None, "False"])
def test_energy_relative_is_a_strict_boolean(flag):
    with pytest.raises(ValueError, match=f"^energy_relative must be True or False; got {flag!r}"):
        engine.survey(**GOOD, energy_relative=flag)


def test_numpy_booleans_are_booleans():
    a = engine.survey(**GOOD, energy_relative=np.True_)
    b = engine.survey(**GOOD, energy_relative=True)
    assert a.identical(b)


@pytest.mark.parametrize(
    ("kwargs", "starts"),
    [
        ({"circular_tol": True}, "circular_tol must be a number"),
        ({"circular_tol": "1e-12"}, "circular_tol must be a number"),
        ({"rtol": "1e-8"}, "rtol must be a number"),  # exact does not use rtol, but its type
        ({"rtol": True, "method": "rk45"}, "rtol must be a number"),
        ({"block_points": True}, "block_points must be a positive integer"),
        ({"block_points": 1.5e6}, "block_points must be a positive integer"),
        ({"block_points": 0}, "block_points must be a positive integer"),
    ],
)
def test_tolerances_and_counts_have_strict_types(kwargs, starts):
    fn = engine.survey if "block_points" in kwargs else engine.evaluate
    with pytest.raises(ValueError) as info:
        fn(**GOOD, **kwargs)
    assert str(info.value).startswith(starts), str(info.value)

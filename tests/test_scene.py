import math

import numpy as np
import pytest

from engine import Scene


@pytest.mark.parametrize(
    "field,value",
    [
        ("M", 0.0),
        ("M", -1.0),
        ("g", -9.81),
        ("a", 0.0),
        ("k", -0.1),
        ("rim", 0.0),
        ("rim", -2.0),
        ("M", math.nan),
        ("g", math.inf),
        ("mu", 0.0),
        ("c_rr", -1.0),
        ("k", "x"),
    ],
)
def test_invalid_values_name_field_and_value(field, value):
    with pytest.raises(ValueError) as err:
        Scene(**{field: value})
    msg = str(err.value)
    assert f"Scene.{field}" in msg and repr(value) in msg


def test_defaults_and_effects():
    s = Scene()
    assert (s.M, s.g, s.k, s.rim) == (1.0, 9.81, 0.4, None)
    assert s.effects == ()
    assert Scene(rim=3.0, mu=0.2, c_rr=1e-3, attitude=True).effects == (
        "rolling_resistance",
        "rim",
        "slip_check",
        "attitude",
    )
    assert Scene(g=0.0, k=0.0).g == 0.0  # free fall and point particle are valid


def test_attrs_are_netcdf_safe():
    for v in Scene(rim=2.0).as_attrs().values():
        assert isinstance(v, (int, float, str)) and not isinstance(v, bool)


@pytest.mark.parametrize("value", [True, False, np.True_, "1.0", "x", None, [1.0], 1 + 0j])
@pytest.mark.parametrize("field", ["M", "g", "a", "k", "c_rr", "rim", "mu"])
def test_booleans_strings_and_other_types_are_not_numbers(field, value):
    """Scene(M=True) was taken as M = 1 (issue 11); a string that looks like a number too."""
    if value is None and field in ("rim", "mu"):
        return  # None is these fields' "absent"
    with pytest.raises(ValueError) as err:
        Scene(**{field: value})
    assert str(err.value) == f"Scene.{field} must be a real number, got {value!r}"


def test_numpy_and_integer_numbers_are_numbers():
    s = Scene(M=np.float64(2.0), g=np.int64(3), a=1, k=np.float32(0.5))
    assert (s.M, s.g, s.a, s.k) == (2.0, 3.0, 1.0, 0.5)
    assert all(type(x) is float for x in (s.M, s.g, s.a, s.k))


def test_an_integer_beyond_the_doubles_is_not_finite():
    with pytest.raises(ValueError, match="Scene.M must be finite"):
        Scene(M=10**400)

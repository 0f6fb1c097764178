import math

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

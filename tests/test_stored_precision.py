"""engine.precision: the float32 rule against numpy's own statement of float32's range, on
values drawn across it and on its edges."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from engine.precision import PrecisionError, at, stored

F32 = np.finfo(np.float32)
EDGES = [0.0, -0.0, np.inf, -np.inf, np.nan, float(F32.max), -float(F32.max), float(F32.tiny),
         float(F32.tiny) * 0.999, float(F32.max) * 1.001,
         float(F32.max) * (1 + 2**-26), 1e-300, 1e300, 5e-324, 1.0]  # fmt: skip


def _holds(x: float) -> bool:
    """float32 holds ``x`` as what it is (stated independently of engine.precision)."""
    if not np.isfinite(x) or x == 0:
        return True
    with np.errstate(over="ignore"):
        y = np.float32(x)  # rounded to nearest: just above the largest is still the largest
    return bool(np.isfinite(y) and abs(x) >= F32.tiny)


@given(st.lists(st.one_of(st.sampled_from(EDGES), st.floats(allow_nan=True)), min_size=1,
                max_size=40))  # fmt: skip
def test_refused_exactly_where_float32_does_not_hold_the_value(xs):
    x = np.array(xs, np.float64)
    bad = [i for i, v in enumerate(xs) if not _holds(v)]
    if bad:
        with pytest.raises(PrecisionError, match=r"cannot store v = .* at i = "):
            stored("v", x, np.float32, where=lambda i: f"i = {i}")
    else:
        with np.errstate(over="ignore"):
            want = x.astype(np.float32)
        got = stored("v", x, np.float32)
        assert got.dtype == np.float32 and np.array_equal(got, want, equal_nan=True)


def test_the_message_names_the_first_value_and_its_point():
    x = np.array([[1.0, 2.0], [4e38, 1e-40]])
    out = np.empty_like(x, np.float32)
    with pytest.raises(PrecisionError) as exc:
        stored("r_max", x, np.float32, out, at(("a", "b"), [np.array([0.5, 0.7]),
                                                          np.array([1.0, 3.0])]))  # fmt: skip
    text = str(exc.value)
    assert "r_max = 4e+38 at a = 0.7, b = 1" in text and "read back as inf" in text, text


def test_other_casts_are_plain():
    assert stored("n", np.array([1, 2], np.int64), np.int8).dtype == np.int8
    x = np.array([1e300, 1e-300])
    assert stored("v", x, np.float64) is x

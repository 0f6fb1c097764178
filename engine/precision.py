"""How a survey's results are stored: ``precision = "single"`` rounds the float results once to
float32, and never to a float32 that means something else.

float32 holds magnitudes from its smallest normal number, 1.18e-38, to its largest, 3.40e+38,
with ~7 significant digits. Rounded to float32, a finite value beyond the largest becomes
+inf or -inf (in these surveys +inf is the r_max of an escape: a bounded orbit would read as
one) and one below the smallest becomes a subnormal of a few digits or 0 (the r_min of the
radial class). :func:`stored` refuses such a value (:class:`PrecisionError`, naming the
variable, the value, where it is and float32's range) instead of storing it; NaN, the
infinities and 0 are stored as they are. Every cast of a result to its stored type goes
through :func:`stored`: the blocks of a streamed run (:func:`engine.evaluation.evaluate_block`,
:func:`engine.backends.compute_block`), the variables on fewer dims
(:func:`engine.families.family_values`) and the in-memory survey.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["HUGE", "TINY", "PrecisionError", "at", "stored"]

#: The smallest and the largest magnitude float32 holds with all its digits.
TINY = float(np.finfo(np.float32).tiny)
HUGE = float(np.finfo(np.float32).max)


class PrecisionError(ValueError):
    """A result ``precision = "single"`` cannot store as what it is."""


def _first_lost(x: np.ndarray, y: np.ndarray) -> int | None:
    """The flat index of the first value of ``x`` that ``y`` (``x`` rounded to float32) does
    not hold as what it is: finite and +-inf in ``y``, or non-zero and below :data:`TINY` in
    magnitude; None if there is none."""
    lost = np.isinf(y)
    if lost.any():
        lost &= np.isfinite(x)
    else:
        lost = None
    small = np.abs(y) < TINY  # with every 0
    if np.count_nonzero(small) != np.count_nonzero(x == 0):  # more small ones than zeros
        small &= x != 0
        lost = small if lost is None else lost | small
    if lost is None or not lost.any():
        return None
    return int(np.flatnonzero(lost.ravel())[0])


def stored(
    name: str,
    values: np.ndarray,
    dtype: np.dtype | type,
    out: np.ndarray | None = None,
    where: Callable[[int], str] | None = None,
) -> np.ndarray:
    """``values`` of the result ``name`` as stored in ``dtype`` (into ``out`` if given, as
    ``ndarray.astype`` and ``numpy.copyto`` cast). A float result rounded to float32 that is
    not what it was (see the module's docstring) raises :class:`PrecisionError`;
    ``where(flat index)`` says where it is for the message."""
    dtype = np.dtype(dtype)
    values = np.asarray(values)
    narrowed = dtype == np.float32 and values.dtype.kind == "f" and values.dtype.itemsize > 4
    if out is None:
        with np.errstate(over="ignore", under="ignore"):
            out = values.astype(dtype, copy=False)
    else:
        with np.errstate(over="ignore", under="ignore"):
            np.copyto(out, values, casting="same_kind")
    if narrowed and (i := _first_lost(values, out)) is not None:
        value = values.reshape(-1)[i]
        at = f" at {where(i)}" if where is not None else ""
        raise PrecisionError(
            f'precision = "single" cannot store {name} = {value:.6g}{at}: float32 holds '
            f"magnitudes from {TINY:.3g} to {HUGE:.3g} (this value would read back as "
            f'{float(out.reshape(-1)[i]):.6g}); store this survey with precision = "double"'
        )
    return out


def at(dims: tuple[str, ...], axes: list[np.ndarray]) -> Callable[[int], str]:
    """``where`` for :func:`stored` of values on the grid of the 1-D ``axes`` (named
    ``dims``, in C order): the point of a flat index, as ``alpha = 0.7, h = -1, ...``."""

    def where(i: int) -> str:
        idx = np.unravel_index(i, tuple(a.size for a in axes))
        return ", ".join(f"{d} = {a[k]:.6g}" for d, a, k in zip(dims, axes, idx, strict=True))

    return where

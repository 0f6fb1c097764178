"""The summary a run prints and `info` shows: counts of every flag variable (orbit classes,
fates, statuses) and the finite value ranges of the results, gathered block by block."""

from __future__ import annotations

import numpy as np

from ..kernels.geometry import CLASS_NAMES
from ..schema import RESULTS, flag_count, variable_attrs

__all__ = ["Summary"]


class Summary:
    """Counts of every flag variable (orbit classes, fates, statuses) and finite value ranges
    of the results, gathered block by block."""

    def __init__(self) -> None:
        self.flags: dict[str, np.ndarray] = {}
        self._lo: dict[str, float] = {}
        self._hi: dict[str, float] = {}

    @property
    def counts(self) -> np.ndarray:
        """Counts of the orbit classes."""
        return self.flags.get("orbit_class", np.zeros(len(CLASS_NAMES), np.int64))

    def add(self, block: dict[str, np.ndarray]) -> None:
        """Count the flags of ``block`` and widen the ranges of its float variables."""
        for name, arr in block.items():
            meanings = RESULTS[name].flags if name in RESULTS else None
            if meanings is not None:
                n = flag_count(name)  # a code's count at its index
                seen = np.bincount(arr.ravel(), minlength=n)[:n]
                self.flags[name] = self.flags.get(name, np.zeros(n, np.int64)) + seen
            elif arr.dtype.kind == "f" and arr.size:
                # fmin/fmax skip NaN in one pass each (8x a copy of the finite values); an
                # infinity among the values, or no value but NaN, takes the long way
                lo, hi = np.fmin.reduce(arr, axis=None), np.fmax.reduce(arr, axis=None)
                if not (np.isfinite(lo) and np.isfinite(hi)):
                    fin = arr[np.isfinite(arr)]
                    if not fin.size:
                        continue
                    lo, hi = fin.min(), fin.max()
                self._lo[name] = min(self._lo.get(name, np.inf), float(lo))
                self._hi[name] = max(self._hi.get(name, -np.inf), float(hi))

    @property
    def ranges(self) -> dict[str, tuple[float, float, str]]:
        """(min, max, units) of each float variable over its finite values, in the order of
        :data:`engine.schema.RESULTS` (the same for a netCDF and a Zarr run)."""
        order = {name: i for i, name in enumerate(RESULTS)}  # the schema's, in every format
        names = sorted(self._lo, key=lambda n: order.get(n, len(order)))
        return {n: (self._lo[n], self._hi[n], variable_attrs(n).get("units", "")) for n in names}

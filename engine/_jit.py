"""The one place that decides how conesurvey compiles its numba kernels.

Environment overrides (read once, at import):

- ``CONESURVEY_NO_CACHE=1``: do not write or read numba's on-disk compile cache.
- ``CONESURVEY_THREADING_LAYER``: force a numba threading layer (default: ``omp``, then
  ``tbb``, then ``workqueue``, whichever loads first). ``omp`` launches a parallel region in a few
  microseconds; ``workqueue`` aborts when two threads call a parallel kernel at once.
"""

from __future__ import annotations

import os

# Passive OpenMP waiting: with the other core busy, spin-waiting costs milliseconds per launch.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402

CACHE = os.environ.get("CONESURVEY_NO_CACHE", "0") in ("", "0", "false", "False")
THREADING_LAYER = os.environ.get("CONESURVEY_THREADING_LAYER", "")
if THREADING_LAYER:
    numba.config.THREADING_LAYER = THREADING_LAYER
else:
    # OpenMP first; tbb is safe too but a pip-installed tbb is not found in a venv.
    numba.config.THREADING_LAYER_PRIORITY = ["omp", "tbb", "workqueue"]

_COMMON = {"cache": CACHE, "error_model": "numpy", "fastmath": False, "nogil": True}


def kernel(fn=None, **overrides):
    """Decorate a scalar kernel: ``njit`` with the project's options (cache, no fastmath)."""
    opts = {**_COMMON, **overrides}
    if fn is None:
        return lambda f: numba.njit(**opts)(f)
    return numba.njit(**opts)(fn)


def parallel_kernel(fn=None, **overrides):
    """Decorate an array kernel that loops with ``numba.prange`` over independent points."""
    return kernel(fn, parallel=True, **overrides)


def threading_layer() -> str:
    """The threading layer numba actually uses (after the first parallel launch)."""
    try:
        return numba.threading_layer()
    except ValueError:
        return "not yet chosen (no parallel region has run)"

"""The one place that decides how conesurvey compiles its numba kernels, and where it caches them.

Environment overrides (read once, at import):

- ``CONESURVEY_NO_CACHE=1``: do not write or read numba's on-disk compile cache.
- ``CONESURVEY_CACHE_DIR``: where the compile cache lives (default: ``$XDG_CACHE_HOME/conesurvey``
  or ``~/.cache/conesurvey``). The package never writes into its own install directory (it is
  read-only in many installs, and files left there outlive ``pip uninstall``).
- ``CONESURVEY_THREADING_LAYER``: force a numba threading layer (default: ``omp``, then
  ``tbb``, then ``workqueue``, whichever loads first). ``omp`` launches a parallel region in a few
  microseconds; ``workqueue`` aborts when two threads call a parallel kernel at once.

The cache directory's name carries a hash of the kernel sources, so editing any kernel module
(or a tableau) starts a fresh cache: numba's own cache does not notice changes to functions in
other modules (numba#1833).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path
from typing import Any

# Passive OpenMP waiting: with the other core busy, spin-waiting costs milliseconds per launch.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402
from numba.core import caching, types  # noqa: E402

CACHE = os.environ.get("CONESURVEY_NO_CACHE", "0") in ("", "0", "false", "False")
THREADING_LAYER = os.environ.get("CONESURVEY_THREADING_LAYER", "")
if THREADING_LAYER:
    numba.config.THREADING_LAYER = THREADING_LAYER
else:
    # OpenMP first; tbb is safe too but a pip-installed tbb is not found in a venv.
    numba.config.THREADING_LAYER_PRIORITY = ["omp", "tbb", "workqueue"]

_PACKAGE = Path(__file__).resolve().parent


def _sources_hash() -> str:
    """Hash of everything the compiled kernels depend on: the kernel modules and this one."""
    h = hashlib.sha256(numba.__version__.encode())
    for path in sorted([*(_PACKAGE / "kernels").glob("*.py"), Path(__file__)]):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _cache_root() -> Path:
    base = os.environ.get("CONESURVEY_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = os.path.join(xdg, "conesurvey")
    return Path(base) / f"numba-{_sources_hash()}"


#: Where the compiled kernels are cached (None when caching is off).
CACHE_DIR: Path | None = _cache_root() if CACHE else None

_Locator = getattr(caching, "UserProvidedCacheLocator", None) or caching._UserProvidedCacheLocator
_Impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl


class _EngineCacheLocator(_Locator):
    """numba cache locator for this package's kernels: :data:`CACHE_DIR` (or, if that cannot be
    written, a per-user directory under the system's temporary directory), never the package."""

    def __init__(self, py_func: Any, py_file: str, root: Path) -> None:
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = str(root / self.get_suitable_cache_subpath(py_file))

    def get_cache_path(self) -> str:
        return self._cache_path

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> Any:
        if CACHE_DIR is None or not os.path.exists(py_file):
            return None
        if _PACKAGE not in Path(py_file).resolve().parents:
            return None
        user = getattr(os, "getuid", lambda: 0)()
        fallback = Path(tempfile.gettempdir()) / f"conesurvey-{user}" / CACHE_DIR.name
        for root in (CACHE_DIR, fallback):
            locator = cls(py_func, py_file, root)
            try:
                locator.ensure_cache_path()
            except OSError:
                continue
            return locator
        return None


if CACHE and _EngineCacheLocator not in _Impl._locator_classes:
    _Impl._locator_classes.insert(0, _EngineCacheLocator)

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


_ENTRIES: dict[tuple, Any] = {}


def call_specialized(dispatcher: Any, args: tuple, literal_positions: tuple[int, ...]) -> Any:
    """Call a kernel that makes some int arguments literal (``numba.literally``) without paying
    numba's literal dispatch on every call.

    A Python int never matches a literal signature directly, so each call would re-type the
    kernel's head (tens of ms). The first call per literal values goes through the dispatcher
    (compiling or loading the specialisation from the cache); later calls use that
    specialisation's compiled entry point. The other arguments must keep their types.
    """
    values = tuple(int(args[i]) for i in literal_positions)
    key = (dispatcher, values)
    entry = _ENTRIES.get(key)
    if entry is not None:
        return entry(*args)
    result = dispatcher(*args)
    for sig, cres in dispatcher.overloads.items():
        if all(
            isinstance(sig[i], types.IntegerLiteral) and sig[i].literal_value == v
            for i, v in zip(literal_positions, values, strict=True)
        ):
            _ENTRIES[key] = cres.entry_point
            break
    return result

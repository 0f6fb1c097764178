"""The one place that decides how conesurvey compiles its numba kernels, and where it caches them.

Environment overrides (read once, at import):

- ``CONESURVEY_NO_CACHE=1``: do not write or read numba's on-disk compile cache.
- ``CONESURVEY_CACHE_DIR``: where the compile cache lives (default: ``$XDG_CACHE_HOME/conesurvey``
  or ``~/.cache/conesurvey``). The package never writes into its own install directory (it is
  read-only in many installs, and files left there outlive ``pip uninstall``).
- ``CONESURVEY_COMPILE_NOTICES=0``: do not say on stderr that a kernel is compiling
  (:mod:`engine._compiling`; ``engine.set_compile_notices(False)`` does it in a session).
- ``CONESURVEY_THREADING_LAYER``: force a numba threading layer (default: ``omp``, then
  ``tbb``, then ``workqueue``, whichever loads first). ``omp`` launches a parallel region in a few
  microseconds; ``workqueue`` aborts when two threads call a parallel kernel at once.

Each cached entry point is keyed on what it compiles (:func:`compile_key`): its own code and the
code of every kernel it calls, the values of the module-level constants it and they read (the
tableaux, the effect masks, the parameter slots), the compile options and the numba version;
numba adds the signature (with the literal method id and effect set) and the Python version.
Code is compared as bytecode, names and constants without the docstring, so a docstring, a
comment, a line moved or a change in a kernel it does not call recompiles nothing; and as
content, not as a path, so one version of the source has one cache whichever way it was
installed (editable or not, in any directory). numba's own key (the source file's time stamp
and the function's line) would miss changes in the kernels a function calls (numba#1833) and
differs between two installs.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
import pickle
import sys
import tempfile
from pathlib import Path
from typing import Any

# Passive OpenMP waiting: with the other core busy, spin-waiting costs milliseconds per launch.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402
import numpy as np  # noqa: E402
from numba.core import caching, types  # noqa: E402
from numba.core.dispatcher import Dispatcher  # noqa: E402

from ._compiling import listen  # noqa: E402

CACHE = os.environ.get("CONESURVEY_NO_CACHE", "0") in ("", "0", "false", "False")
THREADING_LAYER = os.environ.get("CONESURVEY_THREADING_LAYER", "")
if THREADING_LAYER:
    numba.config.THREADING_LAYER = THREADING_LAYER
else:
    # OpenMP first; tbb is safe too but a pip-installed tbb is not found in a venv.
    numba.config.THREADING_LAYER_PRIORITY = ["omp", "tbb", "workqueue"]

_PACKAGE = Path(__file__).resolve().parent


def _cache_root() -> Path:
    base = os.environ.get("CONESURVEY_CACHE_DIR")
    if not base:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        base = os.path.join(xdg, "conesurvey")
    return Path(base) / "numba-keyed"


#: Where the compiled kernels are cached (None when caching is off).
CACHE_DIR: Path | None = _cache_root() if CACHE else None

_Locator = getattr(caching, "UserProvidedCacheLocator", None) or caching._UserProvidedCacheLocator
_Impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl


def _in_package(module_name: str | None) -> bool:
    """Whether a module is one of this package's (not this one: it decorates, it is not
    compiled)."""
    if module_name == __name__:
        return False
    module = sys.modules.get(module_name or "")
    path = getattr(module, "__file__", None)
    return path is not None and _PACKAGE in Path(path).resolve().parents


def _code_digest(code: Any) -> str:
    """A function's code without its docstring, line numbers or file: the bytecode, names and
    constants (nested functions and comprehensions included)."""
    consts = list(code.co_consts)
    if consts and isinstance(consts[0], str) and not code.co_name.startswith("<"):
        consts[0] = "<doc>"  # a named function's first constant is its docstring or None
    parts = [code.co_code.hex(), repr(code.co_names), repr(code.co_varnames)]
    for c in consts:
        parts.append(_code_digest(c) if inspect.iscode(c) else f"{type(c).__name__}:{c!r}")
    return hashlib.sha256("|".join(parts).encode()).hexdigest()


def _global_names(code: Any) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if inspect.iscode(const):
            names |= _global_names(const)
    return names


class _Keys:
    """The closure of a kernel: every function and package module it reaches (the kernels it
    calls, the jit-only stubs and the modules whose ``@overload`` generates their code), each
    with a digest of itself alone (its code, the names it reads and the values of the
    constants among them). A key is the sorted set of these digests, so it does not depend on
    the order the closure is walked in. Memoised for the process (the sources do not change
    under a running interpreter: a changed file is a new process)."""

    def __init__(self) -> None:
        self.local: dict[tuple[str, int], tuple[str, list]] = {}

    def closure(self, fn: Any) -> list[str]:
        """The digests of everything ``fn`` reaches, sorted."""
        seen: set[tuple[str, int]] = set()
        out = []
        stack: list[tuple[str, Any]] = [("f", fn)]
        while stack:
            kind, obj = stack.pop()
            node = (kind, id(obj))
            if node in seen:
                continue
            seen.add(node)
            if node not in self.local:
                self.local[node] = (self._function if kind == "f" else self._module)(obj)
            digest, children = self.local[node]
            out.append(digest)
            stack.extend(children)
        return sorted(out)

    def _function(self, fn: Any) -> tuple[str, list]:
        parts, children = [fn.__module__, fn.__qualname__, _code_digest(fn.__code__)], []
        glob = fn.__globals__
        for name in sorted(_global_names(fn.__code__)):
            if name in glob:
                parts.append(f"{name}={self.ref(glob[name], children)}")
        return hashlib.sha256(";".join(parts).encode()).hexdigest(), children

    def _module(self, module: Any) -> tuple[str, list]:
        parts, children = [module.__name__], []
        for key, obj in sorted(vars(module).items()):
            if not key.startswith("__"):
                parts.append(f"{key}={self.ref(obj, children)}")
        return hashlib.sha256(";".join(parts).encode()).hexdigest(), children

    def ref(self, obj: Any, children: list) -> str:
        """How a function or module refers to ``obj``: a constant by its value, a function or a
        module by its name (added to ``children``, whose own digests join the closure)."""
        if isinstance(obj, Dispatcher):
            children.append(("f", obj.py_func))
            name = f"{obj.py_func.__module__}.{obj.py_func.__qualname__}"
            return f"jit {name} {sorted(obj.targetoptions.items())}"
        if hasattr(obj, "__wrapped__") and callable(obj):
            return self.ref(obj.__wrapped__, children)
        if inspect.isfunction(obj) or hasattr(obj, "_defn"):  # plain functions and intrinsics
            fn = getattr(obj, "_defn", obj)
            if _in_package(fn.__module__):  # a stub: its module's @overload makes its code
                children.append(("f", fn))
                children.append(("m", sys.modules[fn.__module__]))
            return f"fn {fn.__module__}.{fn.__qualname__}"
        if inspect.ismodule(obj):
            if _in_package(obj.__name__):  # read as module.NAME
                children.append(("m", obj))
            return f"module {obj.__name__}"
        if isinstance(obj, np.ndarray):
            head = repr((obj.dtype.str, obj.shape)).encode()
            return hashlib.sha256(head + obj.tobytes()).hexdigest()
        if isinstance(obj, tuple | list):
            return type(obj).__name__ + "(" + ",".join(self.ref(x, children) for x in obj) + ")"
        if isinstance(obj, dict):
            items = sorted((self.ref(k, children), self.ref(v, children)) for k, v in obj.items())
            return "{" + ",".join(f"{k}:{v}" for k, v in items) + "}"
        if isinstance(obj, set | frozenset):
            return "{" + ",".join(sorted(self.ref(x, children) for x in obj)) + "}"
        if obj is None or isinstance(obj, bool | int | float | complex | str | bytes | np.generic):
            return f"{type(obj).__name__}:{obj!r}"
        if inspect.isclass(obj):
            return f"class {obj.__module__}.{obj.__qualname__}"
        return type(obj).__qualname__


_KEYS = _Keys()


def compile_key(py_func: Any) -> str:
    """What a cached entry point's compiled code depends on (module docstring), as a hex digest:
    its own code and the kernels it calls, the constants they read, the compile options and the
    numba version."""
    h = hashlib.sha256(f"numba {numba.__version__}; {sorted(_COMMON.items())};".encode())
    for digest in _KEYS.closure(py_func):
        h.update(digest.encode())
    return h.hexdigest()


class _LazyKey:
    """The source stamp numba stores in a cache index: :func:`compile_key`, computed when numba
    first compares or saves it (a function's callees may be defined after it), pickled as the
    plain string."""

    def __init__(self, py_func: Any) -> None:
        self._py_func = py_func

    @functools.cached_property
    def value(self) -> str:
        return compile_key(self._py_func)

    def __eq__(self, other: object) -> bool:
        return self.value == (other.value if isinstance(other, _LazyKey) else other)

    def __ne__(self, other: object) -> bool:
        return not self == other

    def __hash__(self) -> int:
        return hash(self.value)

    def __reduce__(self) -> tuple:
        return (str, (self.value,))


class _EngineCacheLocator(_Locator):
    """numba cache locator for this package's kernels: :data:`CACHE_DIR` (or, if that cannot be
    written, a per-user directory under the system's temporary directory), never the package;
    files named by module and function (not by line or install path), stamped with
    :func:`compile_key` (not the source file's time stamp)."""

    def __init__(self, py_func: Any, py_file: str, root: Path) -> None:
        self._py_file = py_file
        self._py_func = py_func
        rel = Path(py_file).resolve().parent.relative_to(_PACKAGE)
        self._cache_path = str(root / "_".join(("engine", *rel.parts)))

    def get_cache_path(self) -> str:
        return self._cache_path

    def get_source_stamp(self) -> Any:
        return _LazyKey(self._py_func)

    def get_disambiguator(self) -> str:
        return "k"

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


class _ReadableIndex(caching.IndexDataCacheFile):
    """A kernel's cache index that this version of the package cannot read is a cache miss, as
    an index of another numba version is, and the next save writes it anew. numba pickles a
    kernel's signatures into its index: an index written by another version of the package can
    name a class, a module or a value this one has not (seen: ``AttributeError: Can't get
    attribute 'Family'`` after a named tuple became a plain tuple), and numba would raise it."""

    def _load_index(self) -> dict:
        try:
            return super()._load_index()
        except (AttributeError, ImportError, pickle.UnpicklingError, EOFError, TypeError,
                ValueError):  # fmt: skip
            return {}


def _readable_index(dispatcher: Any) -> Any:
    """``dispatcher`` with its cache index read as :class:`_ReadableIndex` (a package kernel)."""
    index = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if type(index) is caching.IndexDataCacheFile:
        index.__class__ = _ReadableIndex
    return dispatcher


if CACHE and _EngineCacheLocator not in _Impl._locator_classes:
    _Impl._locator_classes.insert(0, _EngineCacheLocator)
listen(kept=CACHE)  # a compile longer than a second is announced on stderr (engine._compiling)

_COMMON = {"cache": CACHE, "error_model": "numpy", "fastmath": False, "nogil": True}


def kernel(fn=None, **overrides):
    """Decorate a scalar kernel: ``njit`` with the project's options (cache, no fastmath)."""
    opts = {**_COMMON, **overrides}
    if fn is None:
        return lambda f: _readable_index(numba.njit(**opts)(f))
    return _readable_index(numba.njit(**opts)(fn))


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


@functools.cache
def _positions(dispatcher: Any, literal: tuple[str, ...]) -> tuple[int, ...]:
    """The places of the parameters named ``literal`` in the kernel's signature."""
    params = list(inspect.signature(dispatcher.py_func).parameters)
    missing = [name for name in literal if name not in params]
    if missing:
        raise TypeError(f"{dispatcher.py_func.__qualname__} has no parameter {missing[0]!r}")
    return tuple(params.index(name) for name in literal)


def call_specialized(dispatcher: Any, args: tuple, literal: tuple[str, ...]) -> Any:
    """Call a kernel that makes the int arguments named ``literal`` literal
    (``numba.literally``) without paying numba's literal dispatch on every call.

    A Python int never matches a literal signature directly, so each call would re-type the
    kernel's head (tens of ms). The first call per literal values goes through the dispatcher
    (compiling or loading the specialisation from the cache); later calls use that
    specialisation's compiled entry point. The other arguments must keep their types.
    """
    literal_positions = _positions(dispatcher, literal)
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

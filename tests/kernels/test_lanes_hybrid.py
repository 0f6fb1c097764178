"""Hybrid fate maps on the SIMD lanes (engine.kernels.lanes_hybrid): every output of the scalar
kernel (engine.kernels.hybrid.hybrid_fate_points, one launch per thread), bit for bit, on
launches whose stories end in every fate, slip and roll again several times, and outnumber
the lanes (each lane takes launch after launch, the stories of uneven lengths)."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from numba.core.dispatcher import Dispatcher

from engine import launch
from engine.hybrid import hybrid_fates
from engine.kernels.hybrid import HYBRID_FATE_NAMES
from engine.scene import Scene

#: The scene of tests/test_hybrid.py's step-budget test and scripts/bench_slide.py (so the
#: lanes kernels for dop853 are the ones the suite compiles already).
BENCH = dict(mu=0.3, mu_k=0.25, c_rr=0.02, rim=1.0)


def launches(n, seed):
    """(alpha, calE at rest radially, h, L_z, r0, u0, slip_u, slip_v) of n launches: rolling
    and thrown, on narrow, wide and nearly flat cones (where rolling resistance holds a ball
    at rest), from the rim's neighbourhood down to the vertex, plus the edges: a start beyond
    the rim, one inside the vertex region."""
    rng = np.random.default_rng(seed)
    alpha = rng.choice([0.35, 0.6, 0.9, 1.2, 1.56], n)
    r0 = rng.uniform(0.05, 0.9, n)
    v0 = rng.uniform(-1.5, 1.5, n) * (rng.uniform(size=n) > 0.15)
    w0 = rng.uniform(-2.0, 2.0, n)
    u0 = rng.uniform(-1.0, 1.0, n) * (rng.uniform(size=n) > 0.5)
    thrown = rng.uniform(size=n) < 0.4
    slip_u = np.where(thrown, rng.uniform(-2.0, 2.0, n), 0.0)
    slip_v = np.where(thrown, rng.uniform(-1.0, 1.0, n), 0.0)
    r0[:2] = (1.2, 1e-5)  # beyond the rim, inside the vertex region
    v0[:2] = 0.0
    u0[:2] = 0.0
    alpha[2:4] = 1.56  # slow on a nearly flat cone: rolling resistance stops it and holds it
    v0[2:4] = (0.2, 0.0)
    w0[2:4] = (0.0, 0.0)  # the one rolling comes to rest spinning, the one thrown radially not
    u0[2:4] = (0.0, 0.3)
    slip_u[2:4] = (0.0, 0.4)
    sc = Scene(**BENCH)
    inv = launch.invariants(alpha, r0, u0, v0, w0, sc)
    e_rest = inv["energy"] - 0.5 * sc.M * u0 * u0  # as a launch map computes it
    return alpha, e_rest, inv["h"], inv["Lz"], r0, u0, slip_u, slip_v


PTS = launches(64, 19)


@pytest.mark.parametrize("method", ["dop853", "rk45"])
def test_lanes_hybrid_maps_equal_the_scalar_kernel_bit_for_bit(method):
    """Fate, every float row (as bits: -0.0 and NaN too) and n_steps equal, on the whole step
    budget and on one that some stories exhaust (in a rolling stretch or a sliding one); the
    fates cover every fate a hybrid map has (a slip is a transition: never ``slipped``). Without
    spin friction: with it, engine.hybrid runs one launch per thread (every stretch is on the
    hybrid steps, scalar on the lanes too); the lanes kernel with spin friction passes this
    test as well (on scripts/bench_slide.py's launches too), a compile more than the suite's
    budget allows."""
    sc = Scene(**BENCH)
    *pts, u0, su, sv = PTS
    seen = set()
    episodes = 0
    for max_steps in (10**6, 400):
        kw = dict(u0=u0, slip_u=su, slip_v=sv, max_steps=max_steps)
        want = hybrid_fates(*pts, sc, method, 1e-9, 2.0, math.inf, lanes=False, **kw)
        got = hybrid_fates(*pts, sc, method, 1e-9, 2.0, math.inf, lanes=True, **kw)
        for name, w in want.items():
            g = got[name]
            if w.dtype == np.float64:
                g, w = g.view(np.int64), w.view(np.int64)
            np.testing.assert_array_equal(g, w, err_msg=name)
        seen |= {HYBRID_FATE_NAMES[f] for f in want["fate"]}
        episodes = max(episodes, int(want["slip_episodes"].max()))
    # (the cone's normal force never vanishes: no lifted_off)
    assert seen == set(HYBRID_FATE_NAMES) - {"slipped", "lifted_off"}, set(HYBRID_FATE_NAMES) - seen
    assert episodes >= 3  # stories that slip, roll again and slip again


def test_lanes_equal_the_scalar_kernel_with_strong_rolling_resistance():
    """c_rr > mu_k (the same compiled effect set, other values): stories that slide without
    turning, slide to rest, start beyond the friction limit or within the rest threshold
    (decided at a stretch's start, by the same piece on the lanes as in the scalar kernel),
    every output bit for bit, none failed."""
    sc = Scene(mu=0.3, mu_k=0.2, c_rr=0.5, rim=1.0)
    *pts, u0, su, sv = launches(48, 23)
    kw = dict(u0=u0, slip_u=su, slip_v=sv)
    want = hybrid_fates(*pts, sc, "dop853", 1e-9, 2.0, math.inf, lanes=False, **kw)
    got = hybrid_fates(*pts, sc, "dop853", 1e-9, 2.0, math.inf, lanes=True, **kw)
    for name, w in want.items():
        g = got[name]
        if w.dtype == np.float64:
            g, w = g.view(np.int64), w.view(np.int64)
        np.testing.assert_array_equal(g, w, err_msg=name)
    names = {HYBRID_FATE_NAMES[f] for f in want["fate"]}
    assert "failed" not in names and {"rest", "vertex"} <= names, names
    assert (want["slip_episodes"] >= 1).sum() >= 10


def _package_classes(ty) -> list[str]:
    """Classes of this package inside a numba type (a named tuple's class, at any depth)."""
    found = []
    cls = getattr(ty, "instance_class", None)
    if cls is not None and cls.__module__.split(".")[0] == "engine":
        found.append(f"{cls.__module__}.{cls.__qualname__}")
    for inner in getattr(ty, "types", ()):
        found += _package_classes(inner)
    return found


def test_no_cached_kernel_signature_carries_a_class_of_the_package():
    """After a hybrid map on the lanes and one launch per thread, no kernel compiled in this
    process or stored in the compile cache's index takes an argument whose numba type names a
    class of the package: numba pickles the signatures into the cache's index by class name,
    and a version of the package without that class cannot read that index (engine/_jit.py
    then takes it as a cache miss: tests/test_jit_cache.py)."""
    import engine.kernels as kernels_pkg

    *pts, u0, su, sv = (c[:3] for c in PTS)
    for lanes in (True, False):
        hybrid_fates(*pts, Scene(**BENCH), "dop853", 1e-9, 2.0, math.inf, lanes=lanes, u0=u0,
                     slip_u=su, slip_v=sv)  # fmt: skip

    pkg_dir = Path(kernels_pkg.__file__).parent
    seen, bad = 0, []
    for path in sorted(pkg_dir.glob("*.py")):
        mod = sys.modules.get(f"engine.kernels.{path.stem}")
        for name, obj in vars(mod).items() if mod is not None else ():
            if isinstance(obj, Dispatcher) and obj.py_func.__module__ == mod.__name__:
                # compiled in this process, and in the cache's index (loaded: not compiled here)
                index = getattr(getattr(obj, "_cache", None), "_cache_file", None)
                stored = [key[0] for key in index._load_index()] if index is not None else []
                for sig in [*obj.signatures, *stored]:
                    seen += 1
                    bad += [f"{name}: {c}" for t in sig for c in _package_classes(t)]
    assert seen > 20 and not bad, (seen, bad)

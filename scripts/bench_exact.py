"""Throughput of the exact (closed-form) path, measured side by side in one run.

    python scripts/bench_exact.py                 # ~1e6 points, best of 3 (about a minute)
    python scripts/bench_exact.py -n 200000 -r 5  # quicker

Prints, for the same random bounded points under gravity:

(a) ``engine.kernels.geometry.orbit_batch`` (class, turning points, T_r, psi, precession rate and
    mu_required per point) on 1 and 2 numba threads: points/s and the 2-thread speedup;
(b) the peer: T_r and psi from Carlson's R_F, R_D, R_J in numpy with
    ``scipy.special.elliprf/elliprd/elliprj`` (vectorised, one core), given the turning points
    precomputed by the engine (so the peer skips the root finding the engine does);
(c) the ratio exact / peer, next to the targets (exact >= 4x the numpy Carlson evaluation on the
    same core count; 2-thread speedup >= 1.8);
(d) first-call time of ``orbit_batch`` in a fresh interpreter: cold (empty ``NUMBA_CACHE_DIR``:
    compile) and warm (default on-disk cache: load).

scipy is a benchmark extra (``pip install conesurvey[bench]``), imported here only.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable

import numba
import numpy as np

import engine
from engine.kernels.geometry import BOUNDED, CIRCULAR_TOL, empty_outputs, orbit_batch

M, G, K = 1.0, 9.81, 0.4
TARGET_VS_PEER = 4.0
TARGET_SPEEDUP = 1.8


def random_bounded_points(n: int, seed: int = 20240601) -> dict[str, np.ndarray]:
    """n random bounded orbits under gravity: alpha [rad], energy [J], h [m/s], Lz [kg m^2/s].

    alpha uniform in [10, 80] deg, h uniform in [-3, 3] m/s, L_z log-uniform in [0.05, 3] with
    random sign, energy offset (calE - V_min)/|V_min| log-uniform in [1e-6, 10].
    """
    rng = np.random.default_rng(seed)
    m = int(n * 1.05) + 16
    alpha = np.radians(rng.uniform(10.0, 80.0, m))
    h = rng.uniform(-3.0, 3.0, m)
    Lz = np.exp(rng.uniform(math.log(0.05), math.log(3.0), m)) * rng.choice([-1.0, 1.0], m)
    offset = np.exp(rng.uniform(math.log(1e-6), math.log(10.0), m))
    scene = engine.Scene(M=M, g=G, k=K)
    vmin = engine.minimum_energy(alpha, h, Lz, scene)
    energy = vmin + offset * np.abs(vmin)
    cls, f = empty_outputs(m)
    orbit_batch(alpha, energy, h, Lz, M, G, K, math.inf, CIRCULAR_TOL, cls, f)
    keep = np.flatnonzero(cls == BOUNDED)[:n]
    if keep.size < n:
        raise RuntimeError(f"only {keep.size} of {n} random points are bounded")
    pts = {"alpha": alpha, "energy": energy, "h": h, "Lz": Lz}
    out = {k: np.ascontiguousarray(v[keep]) for k, v in pts.items()}
    out["r1"] = np.ascontiguousarray(f[0, keep])
    out["r2"] = np.ascontiguousarray(f[1, keep])
    out["T"] = np.ascontiguousarray(f[3, keep])
    out["psi"] = np.ascontiguousarray(f[4, keep])
    return out


def carlson_numpy(
    alpha: np.ndarray, Lz: np.ndarray, r1: np.ndarray, r2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(T_r [s], psi [rad]) from Carlson's forms with scipy.special, given r1 < r2 [m].

    r3 = -A/(C r1 r2); T_r = 2 sqrt(M/2C) [2 r1 R_F(0, r1-r3, r2-r3)
    + 2/3 (r2-r1)(r1-r3) R_D(0, r2-r3, r1-r3)]; psi = 2 K sqrt(M/2C) [R_F(0, 1-m, 1)
    + n/3 R_J(0, 1-m, 1, 1-n)] / (r2 sqrt(r2-r3)), m = (r2-r1)/(r2-r3), n = (r2-r1)/r2.
    """
    from scipy.special import elliprd, elliprf, elliprj

    s = np.sin(alpha)
    c = np.cos(alpha)
    s2 = s * s
    kk = K / (1.0 + K)
    A = Lz * Lz / (2.0 * M * s2) * (1.0 + kk * (c * c) / s2)
    C = M * G * c / (1.0 + K)
    r3 = -A / (C * r1 * r2)
    sc = np.sqrt(M / (2.0 * C))
    d21 = r2 - r1
    d13 = r1 - r3
    d23 = r2 - r3
    T = (
        2.0
        * sc
        * (2.0 * r1 * elliprf(0.0, d13, d23) + (2.0 / 3.0) * d21 * d13 * elliprd(0.0, d23, d13))
    )
    m1 = d13 / d23  # 1 - m
    n = d21 / r2
    Kang = np.abs(Lz) / (M * s2)
    psi = (
        2.0
        * Kang
        * sc
        * (elliprf(0.0, m1, 1.0) + n / 3.0 * elliprj(0.0, m1, 1.0, 1.0 - n))
        / (r2 * np.sqrt(d23))
    )
    return T, psi


def best_time(fn: Callable[[], object], repeats: int) -> float:
    """Smallest wall time [s] of ``repeats`` calls of ``fn``."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


_PROBE = """
import json, math, time
t0 = time.perf_counter()
import numpy as np
from engine.kernels.geometry import empty_outputs, orbit_batch
t1 = time.perf_counter()
a = np.full(64, 0.5); e = np.full(64, 10.0); h = np.full(64, 1.0); lz = np.full(64, 1.0)
cls, f = empty_outputs(64)
orbit_batch(a, e, h, lz, 1.0, 9.81, 0.4, math.inf, 1e-12, cls, f)
t2 = time.perf_counter()
orbit_batch(a, e, h, lz, 1.0, 9.81, 0.4, math.inf, 1e-12, cls, f)
t3 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "first": t2 - t1, "second": t3 - t2}))
"""


def first_call(cache_dir: str | None) -> dict[str, float]:
    """Import and first/second ``orbit_batch`` call times [s] in a fresh interpreter."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env.pop("CONESURVEY_NO_CACHE", None)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    t0 = time.perf_counter()
    res = subprocess.run(
        [sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True
    )
    out = json.loads(res.stdout.strip().splitlines()[-1])
    out["process"] = time.perf_counter() - t0
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", type=int, default=1_000_000, help="points (default %(default)s)")
    parser.add_argument("-r", "--repeats", type=int, default=3, help="best of (default 3)")
    parser.add_argument("--no-compile", action="store_true", help="skip the compile-time probe")
    args = parser.parse_args(argv)
    import scipy

    t_start = time.perf_counter()
    n = args.n
    ncpu = os.cpu_count() or 1
    print(f"machine: {platform.platform()}, {platform.machine()}, os.cpu_count() = {ncpu}")
    print(
        f"python {platform.python_version()}, numba {numba.__version__}, numpy {np.__version__}, "
        f"scipy {scipy.__version__}, conesurvey {engine.__version__}"
    )
    if hasattr(os, "getloadavg"):
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        print(f"load average before the run (1, 5, 15 min): {load}")

    pts = random_bounded_points(n)
    a, e, h, lz = pts["alpha"], pts["energy"], pts["h"], pts["Lz"]
    cls, f = empty_outputs(n)

    def exact() -> None:
        orbit_batch(a, e, h, lz, M, G, K, math.inf, CIRCULAR_TOL, cls, f)

    def peer() -> None:
        carlson_numpy(a, lz, pts["r1"], pts["r2"])

    # Agreement first: the two evaluations must compute the same numbers.
    T_peer, psi_peer = carlson_numpy(a, lz, pts["r1"], pts["r2"])
    dT = float(np.max(np.abs(T_peer / pts["T"] - 1.0)))
    dpsi = float(np.max(np.abs(psi_peer / pts["psi"] - 1.0)))

    threads = [1, 2] if numba.config.NUMBA_NUM_THREADS >= 2 else [1]
    t_exact = {}
    for nt in threads:
        numba.set_num_threads(nt)
        exact()  # warm the thread pool
        t_exact[nt] = best_time(exact, args.repeats)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    t_peer = best_time(peer, args.repeats)
    layer = numba.threading_layer()

    print(
        f"\n{n} random bounded points (g = {G}, k = {K}), best of {args.repeats}; "
        f"threading layer {layer}"
    )
    print(f"peer vs engine on these points: max |rel diff| T_r {dT:.1e}, psi {dpsi:.1e}\n")
    head = f"{'evaluation':46s} {'threads':>7s} {'best [s]':>9s} {'points/s':>10s} {'vs peer':>8s}"
    print(head)
    print("-" * len(head))
    for nt in threads:
        rate = n / t_exact[nt]
        print(
            f"{'(a) exact: orbit_batch (all outputs)':46s} {nt:7d} {t_exact[nt]:9.3f} "
            f"{rate:10.3g} {t_peer / t_exact[nt]:7.2f}x"
        )
    print(
        f"{'(b) peer: numpy + scipy elliprf/rd/rj (T, psi)':46s} {1:7d} {t_peer:9.3f} "
        f"{n / t_peer:10.3g} {1.0:7.2f}x"
    )
    ratio1 = t_peer / t_exact[1]
    ok = "meets" if ratio1 >= TARGET_VS_PEER else "MISSES"
    print(
        f"\n(c) exact / peer, 1 thread each: {ratio1:.2f}x   (target >= {TARGET_VS_PEER:g}x: {ok})"
    )
    if 2 in t_exact:
        speedup = t_exact[1] / t_exact[2]
        ok = "meets" if speedup >= TARGET_SPEEDUP else "MISSES"
        print(
            f"    exact / peer, 2 threads vs 1 core: {t_peer / t_exact[2]:.2f}x\n"
            f"    2-thread speedup {speedup:.2f} (parallel efficiency {speedup / 2:.0%}; "
            f"target speedup >= {TARGET_SPEEDUP:g}: {ok})"
        )

    if not args.no_compile:
        with tempfile.TemporaryDirectory(prefix="numba-cold-") as tmp:
            cold = first_call(tmp)
        warm = min((first_call(None) for _ in range(2)), key=lambda d: d["first"])
        print("\n(d) orbit_batch in a fresh interpreter [s]")
        print(f"{'cache':34s} {'import':>8s} {'1st call':>9s} {'2nd call':>9s} {'process':>8s}")
        for label, d in (
            ("cold (empty NUMBA_CACHE_DIR)", cold),
            ("warm (default on-disk cache)", warm),
        ):
            print(
                f"{label:34s} {d['import']:8.3f} {d['first']:9.3f} {d['second']:9.5f} "
                f"{d['process']:8.3f}"
            )
        print(f"compile / cache load: {cold['first'] / max(warm['first'], 1e-9):.0f}x")
    print(f"\ntotal benchmark time {time.perf_counter() - t_start:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

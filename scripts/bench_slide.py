"""Hybrid fate maps (sliding, rolling again, spin friction) beside today's rolling fate map on
the same launches: orbits per second per core and the 2-thread speedup.

The task: N rolling launches (alpha in [0.3, 1.3], r0 in [0.1, 0.5] m, v0 in [0.2, 1.5] m/s,
w0 in [-2, 2] m/s; M = 1, g = 9.81, k = 0.4, a = 1 cm) followed by rk45 at rtol 1e-9 on a
cone with rolling resistance c_rr = 0.02, mu = 0.3 and a rim at 1 m, to their fate or 5 s:

- rolling: today's fate map (a slip ends the run: ``slipped``);
- hybrid: the same scene with mu_k = 0.25 (a slip is a transition);
- hybrid + spin: and c_spin = 0.01.

Timed side by side in one process, best of ``--repeats``, on 1 and 2 numba threads; the
machine load is printed.

    python scripts/bench_slide.py [--points 400] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os

import numba
import numpy as np
from bench_common import best

from engine import launch
from engine.fates import Horizon, fates
from engine.hybrid import hybrid_fates
from engine.kernels.fate import FATE_NAMES
from engine.kernels.hybrid import HYBRID_FATE_NAMES
from engine.scene import Scene

T_MAX = 5.0


def sample(n: int, seed: int = 3) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(0.3, 1.3, n)
    r0 = rng.uniform(0.1, 0.5, n)
    inv = launch.invariants(alpha, r0, 0.0, rng.uniform(0.2, 1.5, n), rng.uniform(-2, 2, n))
    return alpha, inv["energy"], inv["h"], inv["Lz"], r0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--method", default="rk45", help="rk45 (default) or dop853")
    ap.add_argument(
        "--tiny", action="store_true", help="a short smoke run: 8 launches, dop853 (the tests')"
    )
    args = ap.parse_args()
    if args.tiny:
        args.points, args.repeats, args.method = 8, 1, "dop853"
    method = args.method
    pts = sample(args.points)
    base = dict(mu=0.3, c_rr=0.02, rim=1.0)
    runs = {
        "rolling": lambda: fates(*pts, Scene(**base), method, 1e-9, Horizon(time=T_MAX)),
        "hybrid": lambda: hybrid_fates(
            *pts, Scene(mu_k=0.25, **base), method, 1e-9, T_MAX, float("inf")
        ),  # fmt: skip
        "hybrid + spin": lambda: hybrid_fates(
            *pts, Scene(mu_k=0.25, c_spin=0.01, **base), method, 1e-9, T_MAX, float("inf")
        ),  # fmt: skip
    }
    print(f"{args.points} launches, best of {args.repeats}")
    for name, fn in runs.items():
        res = fn()  # compile
        names = FATE_NAMES if name == "rolling" else HYBRID_FATE_NAMES
        counts = np.bincount(res["fate"], minlength=len(names))
        fates_text = ", ".join(f"{n} {c}" for n, c in zip(names, counts, strict=True) if c)
        print(f"{name:14s} fates: {fates_text}; steps {int(res['n_steps'].sum())}")
    one = {}
    for name, fn in runs.items():
        t = {}
        for threads in (1, 2):
            numba.set_num_threads(threads)
            t[threads] = best(fn, args.repeats)
        one[name] = t[1]
        print(f"{name:14s} {args.points / t[1]:9.1f} orbits/s on 1 thread, "
              f"{args.points / t[2]:9.1f} on 2; 2-thread speedup {t[1] / t[2]:.2f}; "
              f"load average {os.getloadavg()[0]:.2f} (2 cores)")  # fmt: skip
    for name in ("hybrid", "hybrid + spin"):
        print(
            f"{name:14s} per core: {one[name] / one['rolling']:.2f} x the rolling fate "
            "map's time per orbit (same launches, same run)"
        )


if __name__ == "__main__":
    main()

"""Fate maps: orbits per second per core and the 2-thread speedup, and what the fate machinery
costs a scene that does not use it.

The task: N launch orbits (alpha in [0.3, 1.3], L_z in [0.3, 1.5], h in [-2, 2], energy 0.2-3
|V_min| above V_min; M = 1, g = 9.81, k = 0.4) followed by rk45 at rtol 1e-9 on a cone with
rolling resistance c_rr = 0.02 and a rim, to their fate or 20 s. Timed side by side in one
process, best of ``--repeats``, on 1 and 2 numba threads; the machine load is printed. The last
rows compare the one-period map of the ideal scene (no fate machinery compiled in) with the same
map before fate maps existed (scripts/bench_effects.py measures that against a hand-written
kernel).

    python scripts/bench_fates.py [--points 400] [--repeats 5]
"""

from __future__ import annotations

import argparse
import os

import numba
import numpy as np
from bench_common import best

import engine


def sample(n: int, seed: int = 3) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(0.3, 1.3, n)
    h = rng.uniform(-2.0, 2.0, n)
    Lz = rng.uniform(0.3, 1.5, n)
    vmin = engine.minimum_energy(alpha, h, Lz)
    return alpha, vmin + np.abs(vmin) * rng.uniform(0.2, 3.0, n), h, Lz


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument(
        "--tiny", action="store_true", help="a seconds-long smoke run (tests/test_scripts.py)"
    )
    args = ap.parse_args()
    if args.tiny:
        args.points, args.repeats = 16, 1
    pts = sample(args.points)
    fate_scene = engine.Scene(c_rr=0.02, rim=4.0)

    def fate():
        return engine.evaluate(*pts, scene=fate_scene, method="rk45", rtol=1e-9,
                               horizon_time=20.0)  # fmt: skip

    def period():
        return engine.evaluate(*pts, method="rk45", rtol=1e-9)

    ds = fate()
    period()
    print(f"load average {os.getloadavg()[0]:.2f} (2 cores); {args.points} orbits, best of "
          f"{args.repeats}")  # fmt: skip
    names = engine.FATE_NAMES
    counts = np.bincount(ds.fate.values, minlength=len(names))
    print("fates: " + ", ".join(f"{n} {c}" for n, c in zip(names, counts, strict=True) if c))
    steps = int(ds.n_steps.sum())
    times = {}
    for threads in (1, 2):
        numba.set_num_threads(threads)
        times[threads] = best(fate, args.repeats)
        t_period = best(period, args.repeats)
        print(f"{threads} thread(s): fate map {args.points / times[threads]:9.1f} orbits/s "
              f"({1e9 * times[threads] / steps:6.1f} ns/step); one-period map of the ideal "
              f"scene {args.points / t_period:9.1f} orbits/s")  # fmt: skip
    print(f"2-thread speedup of the fate map: {times[1] / times[2]:.2f}")


if __name__ == "__main__":
    main()

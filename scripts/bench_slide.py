"""Hybrid fate maps (sliding, rolling again, spin friction) beside today's rolling fate map on
the same launches: orbits per second per core and the 2-thread speedup.

The task: N rolling launches (alpha in [0.3, 1.3], r0 in [0.1, 0.5] m, v0 in [0.2, 1.5] m/s,
w0 in [-2, 2] m/s; M = 1, g = 9.81, k = 0.4, a = 1 cm) followed by rk45 at rtol 1e-9 on a
cone with rolling resistance c_rr = 0.02, mu = 0.3 and a rim at 1 m, to their fate or 5 s:

- rolling: today's fate map (a slip ends the run: ``slipped``);
- hybrid: the same scene with mu_k = 0.25 (a slip is a transition), on the SIMD lanes (the
  rolling stretches several launches at once) and one launch per thread (``lanes=False``);
- hybrid + spin: and c_spin = 0.01, one launch per thread (every stretch is on the hybrid
  steps, which the lanes would run in scalar code too: ``engine.hybrid`` does not send it
  there).

Timed side by side in one process (interleaved rounds, the best of ``--repeats``), on 1 and 2
numba threads; the machine load is printed.

    .venv/bin/python scripts/bench_slide.py [--points 400] [--repeats 3]
"""

from __future__ import annotations

import argparse

import numba
import numpy as np
from bench_common import interleaved, load

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
    sliding = Scene(mu_k=0.25, **base)
    spinning = Scene(mu_k=0.25, c_spin=0.01, **base)

    def hybrid(scene: Scene, lanes: bool):
        return lambda: hybrid_fates(*pts, scene, method, 1e-9, T_MAX, float("inf"), lanes=lanes)

    runs = {
        "rolling": lambda: fates(*pts, Scene(**base), method, 1e-9, Horizon(time=T_MAX)),
        "hybrid lanes": hybrid(sliding, True),
        "hybrid 1/thread": hybrid(sliding, False),
        "spin 1/thread": hybrid(spinning, False),
    }
    print(f"{args.points} launches, {method}, best of {args.repeats}; load average {load()}")
    for name, fn in runs.items():
        res = fn()  # compile
        names = FATE_NAMES if name == "rolling" else HYBRID_FATE_NAMES
        counts = np.bincount(res["fate"], minlength=len(names))
        fates_text = ", ".join(f"{n} {c}" for n, c in zip(names, counts, strict=True) if c)
        print(f"{name:16s} fates: {fates_text}; steps {int(res['n_steps'].sum())}")
    t = {}
    for threads in (1, 2):
        numba.set_num_threads(threads)
        t[threads] = {k: v[0] for k, v in interleaved(runs, args.repeats).items()}
    for name in runs:
        print(f"{name:16s} {args.points / t[1][name]:9.1f} orbits/s on 1 thread, "
              f"{args.points / t[2][name]:9.1f} on 2; 2-thread speedup "
              f"{t[1][name] / t[2][name]:.2f}")  # fmt: skip
    lanes, one, spin = t[1]["hybrid lanes"], t[1]["hybrid 1/thread"], t[1]["spin 1/thread"]
    print(f"hybrid per core: lanes {one / lanes:.2f} x the one-launch-per-thread map's "
          f"throughput; time per orbit {lanes / t[1]['rolling']:.2f} x the rolling fate map's on "
          f"the lanes ({one / t[1]['rolling']:.2f} x one per thread)")  # fmt: skip
    print(
        f"spin   per core: time per orbit {spin / t[1]['rolling']:.2f} x the rolling fate "
        "map's (one launch per thread)"
    )
    print(f"load average {load()} (2 cores)")


if __name__ == "__main__":
    main()

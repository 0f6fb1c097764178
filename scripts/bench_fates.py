"""Fate maps: orbits per second per core on the SIMD lanes and one orbit per thread (the scalar
fate kernel), and the lanes' 2-thread speedup, in one run.

The task: N orbits (alpha in [0.3, 1.3], L_z in [0.3, 1.5], h in [-2, 2], energy 0.2-3
|V_min| above V_min; M = 1, g = 9.81, k = 0.4) started at r_min and followed by rk45 at rtol
1e-9 on a cone with rolling resistance c_rr = 0.02 and a rim, to their fate or 20 s (the map
``engine.evaluate(..., scene=Scene(c_rr=0.02, rim=4.0), method="rk45", horizon_time=20.0)``
computes). Per core = CPU time of the calling thread at 1 numba thread; the 2-thread speedup
is wall time, beside a compute-only prange loop timed in the same interleaved rounds (2.0 on
two free cores: below that it measures what the machine's other jobs left). Both paths must
give the same outputs bit for bit (checked here too). The load average is printed before and
after, and the serial share of the map through ``engine.evaluate`` (scripts/bench_common.py).

    .venv/bin/python scripts/bench_fates.py [--points 400] [--rounds 3] [--min-time 1.0] [--where]
"""

from __future__ import annotations

import argparse
import math
import time

import numba
import numpy as np
from bench_common import MACHINE, load, serial_share, spin

import engine
from engine.integrated import fate_points
from engine.kernels.fate import FATE_NAMES, FATE_ROWS
from engine.kernels.lanes_step import LANES, lanes_attempt, lanes_control_fate, layout
from engine.kernels.layouts import P_THETA_MAX, state_size_of
from engine.methods import METHODS

SCENE = engine.Scene(c_rr=0.02, rim=4.0)
METHOD, RTOL, T_MAX = "rk45", 1e-9, 20.0


def sample(n: int, seed: int = 3) -> tuple[np.ndarray, ...]:
    """(alpha, calE, h, L_z, r_start = r_min) of the task's n orbits."""
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(0.3, 1.3, n)
    h = rng.uniform(-2.0, 2.0, n)
    Lz = rng.uniform(0.3, 1.5, n)
    vmin = engine.minimum_energy(alpha, h, Lz)
    energy = vmin + np.abs(vmin) * rng.uniform(0.2, 3.0, n)
    r_min = engine.evaluate(alpha, energy, h, Lz).r_min.values
    return alpha, energy, h, Lz, np.ascontiguousarray(r_min)


class FateMap:
    """One call of the fate map's kernel on the task (``lanes``: the SIMD lanes or one orbit
    per thread), its outputs kept."""

    def __init__(self, pts: tuple[np.ndarray, ...], lanes: bool):
        self.pts, self.lanes = pts, lanes
        self.params = SCENE.params()
        self.params[P_THETA_MAX] = math.inf
        n = pts[0].size
        self.out = (np.zeros(n, np.int8), np.empty((len(FATE_ROWS), n)), np.zeros(n, np.int64))

    def __call__(self) -> None:
        fate_points(*self.pts, self.params, METHODS[METHOD].kernel_id, SCENE.effects_mask, RTOL,
                    T_MAX, 10_000_000, *self.out, lanes=self.lanes)  # fmt: skip


class Timed:
    """Best per-call wall and thread-CPU time [s] of a callable over interleaved rounds."""

    def __init__(self, fn, threads: int, min_time: float):
        self.fn, self.threads = fn, threads
        numba.set_num_threads(threads)
        t0 = time.perf_counter()
        fn()
        self.calls = max(1, math.ceil(min_time / max(time.perf_counter() - t0, 1e-6)))
        self.wall = self.cpu = math.inf

    def round(self) -> None:
        numba.set_num_threads(self.threads)
        c0, w0 = time.thread_time(), time.perf_counter()
        for _ in range(self.calls):
            self.fn()
        w1, c1 = time.perf_counter(), time.thread_time()
        self.wall = min(self.wall, (w1 - w0) / self.calls)
        self.cpu = min(self.cpu, (c1 - c0) / self.calls)


@numba.njit(nogil=True)
def _attempts(method, effects, W, rtol, n):
    numba.literally(method)
    numba.literally(effects)
    for _ in range(n):
        lanes_attempt(method, effects, W, rtol)


@numba.njit(nogil=True)
def _controls(method, effects, W, n, active, h):
    numba.literally(method)
    numba.literally(effects)
    for _ in range(n):
        for lane in range(LANES):  # every lane active, every attempt of the same size
            W[active * LANES + lane] = 1.0
            W[h * LANES + lane] = 1e-3
        lanes_control_fate(method, effects, W, 10**12)


def where_time_goes(rounds: int, calls: int = 200_000) -> tuple[float, float]:
    """CPU time [ns] per orbit and step of the lanes' two vector parts, each timed alone on a
    work array of plausible values (the task's scene at alpha 0.7): the step (the tableau's
    stages, the error and its root) and the step-size control (the PI controller, the terminal
    events' functions, the step budget, the horizon)."""
    method, effects = METHODS[METHOD].kernel_id, SCENE.effects_mask
    ly = layout(method, state_size_of(effects))
    W = np.random.default_rng(1).uniform(0.5, 1.5, ly.n_slots * LANES)
    for k, v in enumerate(SCENE.params(0.7)):
        W[(ly.P + k) * LANES : (ly.P + k + 1) * LANES] = v if math.isfinite(v) else 1e300
    W[ly.H * LANES : (ly.H + 1) * LANES] = 1e-3
    W[ly.T_END * LANES : (ly.T_END + 1) * LANES] = 1e9
    parts = (
        lambda w, n: _attempts(method, effects, w, RTOL, n),
        lambda w, n: _controls(method, effects, w, n, ly.ACTIVE, ly.H),
    )
    best = [math.inf, math.inf]
    for j, part in enumerate(parts):
        part(W.copy(), 1)
        for _ in range(rounds):
            w = W.copy()
            c0 = time.thread_time()
            part(w, calls)
            best[j] = min(best[j], 1e9 * (time.thread_time() - c0) / (calls * LANES))
    return best[0], best[1]


def same_bits(a: FateMap, b: FateMap) -> bool:
    return all(
        np.array_equal(x.view(np.int64) if x.dtype == np.float64 else x,
                       y.view(np.int64) if y.dtype == np.float64 else y)
        for x, y in zip(a.out, b.out, strict=True)
    )  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=400)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--min-time", type=float, default=1.0, help="seconds per timed call group")
    ap.add_argument(
        "--tiny", action="store_true", help="a seconds-long smoke run (tests/test_scripts.py)"
    )
    ap.add_argument("--where", action="store_true", help="also time the lanes' step and control")
    args = ap.parse_args(argv)
    if args.tiny:
        args.points, args.rounds, args.min_time = 16, 1, 0.0
        # The smoke run adds a slip check that never fires (mu 1e3): the kernels of rk45 on
        # rolling resistance, a rim and the slip check, which tests/test_fates.py and
        # tests/kernels/test_lanes_fate.py compile already (the suite compiles no others).
        global SCENE
        SCENE = engine.Scene(c_rr=0.02, rim=4.0, mu=1e3)
    pts = sample(args.points)
    maps = {
        "lanes 1": (FateMap(pts, True), 1),
        "scalar 1": (FateMap(pts, False), 1),
        "lanes 2": (FateMap(pts, True), 2),
        "scalar 2": (FateMap(pts, False), 2),
    }
    before = load()
    timers = {k: Timed(fn, threads, args.min_time) for k, (fn, threads) in maps.items()}
    timers["control 1"] = Timed(lambda: spin(64, 20_000), 1, args.min_time)
    timers["control 2"] = Timed(lambda: spin(64, 20_000), 2, args.min_time)
    for _ in range(args.rounds):
        for t in timers.values():
            t.round()

    def api():
        return engine.evaluate(*pts[:4], scene=SCENE, method=METHOD, rtol=RTOL,
                               horizon_time=T_MAX)  # fmt: skip

    serial = serial_share(api, engine.integrated, "call_specialized", rounds=max(args.rounds, 5),
                          also=[(engine.evaluation, "run_queued")])  # fmt: skip
    after = load()
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    lanes, scalar = maps["lanes 1"][0], maps["scalar 1"][0]
    if not same_bits(lanes, scalar) or not same_bits(maps["lanes 2"][0], scalar):
        print("the lanes' outputs differ from the scalar kernel's")
        return 1
    n = args.points
    fates, steps = lanes.out[0], int(lanes.out[2].sum())
    counts = np.bincount(fates, minlength=len(FATE_NAMES))
    per_core = {k: n / timers[k].cpu for k in ("lanes 1", "scalar 1")}
    print(f"Fate maps ({MACHINE}; load average {before} before, {after} after; {n} orbits, "
          f"{METHOD} rtol {RTOL:g}, c_rr 0.02, rim 4, horizon {T_MAX:g} s; best of "
          f"{args.rounds} interleaved rounds)")  # fmt: skip
    print("fates: " + ", ".join(f"{f} {c}" for f, c in zip(FATE_NAMES, counts, strict=True) if c)
          + f"; {steps / n:.0f} steps per orbit; outputs bit for bit equal")  # fmt: skip
    print(f"per core (CPU time, 1 thread): lanes {per_core['lanes 1']:.0f} orbits/s "
          f"({1e9 * timers['lanes 1'].cpu / steps:.0f} ns/step), one orbit per thread "
          f"{per_core['scalar 1']:.0f} orbits/s ({1e9 * timers['scalar 1'].cpu / steps:.0f} "
          f"ns/step): {per_core['lanes 1'] / per_core['scalar 1']:.2f}x (goal >= 3)")  # fmt: skip
    sp = {k: timers[f"{k} 1"].wall / timers[f"{k} 2"].wall for k in ("lanes", "scalar", "control")}
    print(
        f"2-thread speedup of the fate map (wall): lanes {sp['lanes']:.2f}, one orbit per thread "
        f"{sp['scalar']:.2f}, compute-only control loop {sp['control']:.2f} (same rounds)"
    )
    if args.where:
        step, control = where_time_goes(args.rounds)
        print(f"where the lanes' time goes (CPU ns per orbit and step, each part timed alone): "
              f"the step {step:.0f}, the step-size control {control:.0f} (both vector "
              "code)"
              )  # fmt: skip
    print(
        f"serial share of engine.evaluate's fate map at 1 thread (wall time outside the fate "
        f"kernel and the closed form's parallel regions: the plan, the Dataset): {serial:.1%} "
        "(goal <= 3%)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

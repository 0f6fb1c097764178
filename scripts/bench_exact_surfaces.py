"""Exact orbit maps on surfaces of revolution (Routh's reduction, ``engine.routh``) against the
engine's own dop853 one-period map on the same orbits, side by side in one run.

    .venv/bin/python scripts/bench_exact_surfaces.py          # 2000 orbits per surface, 3 rounds
    .venv/bin/python scripts/bench_exact_surfaces.py -n 500 -r 5
    .venv/bin/python scripts/bench_exact_surfaces.py --tiny   # seconds on a warm compile cache

For a spherical bowl (R = 1 m, a = 2 cm) and a funnel (z = -1/rho, hole 5 cm, a = 1 cm), each
on random bounded launches at a turning point (rho0, v0 within a factor of the circular speed,
spin w0), it prints:

(a) the per-surface setup: building the surface's fundamental solution (``build_table``, not
    cached: best of the rounds), its panels and trailing-coefficient size (target < 50 ms);
(b) the rtol at which dop853's apsidal angles are all within 1e-10 rad of the exact map's (the
    largest of 1e-10 ... 1e-13 that meets it), and the largest error there;
(c) per core (CPU time, one numba thread, best of interleaved rounds): the exact map
    (``engine.routh.exact_map``, tables cached) and dop853 at that rtol, microseconds per
    orbit, and their ratio (target >= 3x); and what both pay for turning each launch's rho0
    into its meridian parameter (``surface_starts.launch_q``), with the ratio without it;
(d) on 2 numba threads: the exact map's wall time and its speedup over 1 thread (target
    >= 1.8), beside the speedup of a compute-only control loop as long as it
    (``bench_common.spin``) in the same rounds: what the machine offers at the moment (other
    jobs take from it; the load average is printed).

dop853 runs through the kernels with the surface model's ``effects`` key
(``scene_key(SURFACE, 0)``): ``engine.kernels.lanes.integrate_points_lanes`` (SIMD lanes, the
headline ratio) and ``engine.kernels.orbit.integrate_points`` (one point per thread); the API's
surface maps are not wired to them yet. Their first call compiles them (minutes, once).
"""

from __future__ import annotations

import argparse
import math
import time

import numba
import numpy as np
from bench_common import MACHINE, interleaved, load, matched_inner, spin, verdict

from engine import routh
from engine.kernels import meridian as mer
from engine.kernels.lanes import integrate_points_lanes
from engine.kernels.layouts import SLOTS
from engine.kernels.model import SURFACE, make_params, scene_key
from engine.kernels.orbit import integrate_points
from engine.kernels.routh import BOUNDED
from engine.kernels.surface_starts import launch_q, set_point
from engine.kernels.tableaux import RK_TABLEAUX

DOP853 = [t.name for t in RK_TABLEAUX].index("dop853")
EFFECTS = scene_key(SURFACE, 0)
RTOLS = (1e-10, 1e-11, 1e-12, 1e-13)
PSI_ERROR = 1e-10
#: name -> (kind, shape1, shape2, a [m], rho0 range [m], v0 / v_circular range, |w0| max)
SURFACES = {
    "bowl R=1": (mer.BOWL, 1.0, 0.0, 0.02, (0.05, 0.7), (0.5, 1.5), 0.5),
    "funnel c=1": (mer.FUNNEL, 1.0, 0.05, 0.01, (0.3, 3.0), (0.8, 1.2), 0.3),
}


def params(kind: int, a: float) -> np.ndarray:
    slots = np.array([SLOTS["rim"], SLOTS["mu"]], np.int64)
    p = make_params(1.0, 9.81, 0.4, a, slots, np.array([math.inf, math.inf]))
    p[mer.P_KIND] = kind
    return p


def launches(name: str, n: int, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """(params, points X) of n bounded launches at a turning point on the surface."""
    kind, s1, s2, a, rho, vrange, wmax = SURFACES[name]
    p = params(kind, a)
    rng = np.random.default_rng(seed)
    m = 3 * n
    X = np.zeros((6, m))
    X[0], X[1] = s1, s2
    X[2] = rng.uniform(*rho, m)
    X[4] = rng.uniform(-wmax, wmax, m)
    q = p.copy()
    set_point(q, X, 0)
    for i in range(m):
        r, z, cb, sb = mer.centre(q, launch_q(q, X[2, i]))[:4]
        X[3, i] = rng.uniform(*vrange) * math.sqrt(9.81 * r * sb / (cb * 1.4))
    keep = routh.exact_map(p, X)["orbit_class"] == BOUNDED
    return p, np.ascontiguousarray(X[:, keep][:, :n])


def dop853(p: np.ndarray, X: np.ndarray, rtol: float, lanes: bool = True) -> np.ndarray:
    """dop853's one-period map of the points: on the SIMD lanes (``integrate_points_lanes``,
    one worker per thread) or one point per thread (``integrate_points``)."""
    n = X.shape[1]
    out_f, out_n, st = np.zeros((5, n)), np.zeros(n, np.int64), np.zeros(n, np.int8)
    if lanes:
        integrate_points_lanes(X, p, DOP853, EFFECTS, rtol, 1_000_000, numba.get_num_threads(),
                               out_f, out_n, st)  # fmt: skip
    else:
        integrate_points(X, p, DOP853, EFFECTS, rtol, 1_000_000, out_f, out_n, st)
    return out_f


@numba.njit(cache=True)
def _launch_qs(p: np.ndarray, X: np.ndarray) -> float:
    s = 0.0
    for i in range(X.shape[1]):
        s += launch_q(p, X[2, i])
    return s


def setup_ms(p: np.ndarray, X: np.ndarray, rounds: int) -> tuple[float, routh.Table]:
    q = p.copy()
    set_point(q, X, 0)
    best = math.inf
    for _ in range(rounds):
        t0 = time.perf_counter()
        t = routh.build_table(q, 4.0)
        best = min(best, time.perf_counter() - t0)
    return 1e3 * best, t


def surface(name: str, n: int, rounds: int) -> None:
    """Lines (a)-(d) of one surface."""
    p, X = launches(name, n)
    exact = routh.exact_map(p, X)
    ms, t = setup_ms(p, X, max(rounds, 3))
    print(f"\n{name}: {X.shape[1]} bounded orbits")
    print(f"  (a) setup {ms:.2f} ms ({int(t.meta[routh.K.N_PANELS])} panels, trailing "
          f"{t.error:.1e}); target < 50 ms: {verdict(50.0, ms)}")  # fmt: skip
    chosen, err = RTOLS[-1], math.inf
    for rtol in RTOLS:
        err = float(np.max(np.abs(dop853(p, X, rtol)[1] - exact["apsidal_angle"])))
        if err <= PSI_ERROR:
            chosen = rtol
            break
    print(f"  (b) dop853 at rtol {chosen:.0e}: largest |psi - psi_exact| {err:.1e} rad")
    numba.set_num_threads(1)
    fns = {"exact": lambda: routh.exact_map(p, X), "lanes": lambda: dop853(p, X, chosen),
           "scalar": lambda: dop853(p, X, chosen, lanes=False)}  # fmt: skip
    cpu = interleaved(fns, rounds, (time.process_time,))
    us = {k: 1e6 * v[0] / X.shape[1] for k, v in cpu.items()}
    ratio = us["lanes"] / us["exact"]
    print(f"  (c) per core: exact {us['exact']:.2f} us/orbit; dop853 {us['lanes']:.2f} us/orbit "
          f"on the SIMD lanes, {us['scalar']:.2f} one point per thread: dop853 (lanes) / "
          f"exact = {ratio:.1f}x; target >= 3x: {verdict(ratio, 3.0)}")  # fmt: skip
    q = p.copy()
    set_point(q, X, 0)
    _launch_qs(q, X)
    lq = 1e6 * interleaved({"q": lambda: _launch_qs(q, X)}, rounds, (time.process_time,))["q"][
        0] / X.shape[1]  # fmt: skip
    print(
        f"      of which both pay {lq:.2f} us/orbit for the launch's meridian parameter "
        f"(surface_starts.launch_q); without it {(us['lanes'] - lq) / (us['exact'] - lq):.1f}x"
    )
    walls = {}
    inner = matched_inner(spin, fns["exact"])
    for threads in (1, 2):
        numba.set_num_threads(threads)
        walls[threads] = interleaved({"e": fns["exact"], "c": lambda: spin(64, inner)}, rounds)
    speed = walls[1]["e"][0] / walls[2]["e"][0]
    control = walls[1]["c"][0] / walls[2]["c"][0]
    one, two = 1e3 * walls[1]["e"][0], 1e3 * walls[2]["e"][0]
    print(f"  (d) exact on 2 threads: {two:.2f} ms (1 thread {one:.2f} ms): 2-thread speedup "
          f"{speed:.2f}, the control loop's {control:.2f} (what the machine offers now); "
          f"target >= 1.8: {verdict(speed, 1.8)}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=2000, help="orbits per surface")
    ap.add_argument("-r", "--rounds", type=int, default=3)
    ap.add_argument("--tiny", action="store_true", help="64 orbits, 1 round")
    args = ap.parse_args()
    n, rounds = (64, 1) if args.tiny else (args.n, args.rounds)
    print(f"machine: {MACHINE}; load average {load()}")
    print(f"exact map (Routh) vs dop853 one-period map (kernels), {n} orbits per surface")
    for name in SURFACES:
        surface(name, n, rounds)
    print(f"\nload average after: {load()}")


if __name__ == "__main__":
    main()

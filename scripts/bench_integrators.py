"""The integrator goals of the performance issue, measured side by side in one run.

    .venv/bin/python scripts/bench_integrators.py             # 200 orbits, 3 rounds (~1 min)
    .venv/bin/python scripts/bench_integrators.py --doc       # also rewrite docs/performance.md
    .venv/bin/python scripts/bench_integrators.py -n 1000 --rounds 5
    .venv/bin/python scripts/bench_integrators.py --compile   # also: first call, cold and cached

The task (``integrator_peers.typical_orbits``): 200 typical bounded orbits, half a radial
period each (r_min to r_max), apsidal angle psi compared with the closed form. Goals:

- the dop853 map through the API (``engine.integrated.evaluate_integrated``, what
  ``engine.evaluate(method="dop853")`` and surveys call) at the rtol that gives max psi error
  <= 1e-10 over the orbits: >= 3x heyoka's scalar ``taylor_adaptive`` loop (tol 1e-10,
  terminal event) per core;
- the same against scipy ``solve_ivp`` DOP853 at rtol = atol = 1e-10: >= 600x per core;
- 2 threads against 1: >= 1.8.

"Per core" is the best, over interleaved rounds, of the calling thread's CPU time per orbit
(``time.thread_time``: what one core spends, whatever else the shared machine runs); wall-clock
figures are printed beside it. Each contender is timed for at least ``--min-time`` seconds per
round, the contenders one after the other in every round. A conservative scene's one-period map
integrates r_min -> r_max and doubles (time symmetry), like the peers: the rows are the batch
kernel alone (``engine.kernels.lanes``), the API (``evaluate_integrated``: validation, outputs,
the energy drift at r_max) and ``engine.evaluate`` (also the closed form of every point and
the xarray Dataset: a fixed cost that 200 orbits do not amortise). The peers and the matching
of tolerances: ``integrator_peers``. The 2-thread figure (on at least 2000 orbits: a survey's
blocks are large) comes with the serial share (wall time outside the parallel kernel at 1
thread, :func:`serial_share`), the speedups of two compute-only prange loops timed in the same
rounds (2.0 on two free cores; one on the vector units, as the lanes are) and the load
average: on a shared machine the second core is often not free.
"""

from __future__ import annotations

import argparse
import datetime
import math
import platform
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np

import engine
from engine._jit import call_specialized
from engine.integrated import evaluate_integrated, points
from engine.kernels.lanes import integrate_points_lanes
from engine.kernels.lanes_step import LANES, lanes_attempt, layout
from engine.kernels.protocol import LITERAL
from engine.methods import METHODS

sys.path.insert(0, str(Path(__file__).resolve().parent))
import integrator_peers as peers  # noqa: E402
from bench_common import (  # noqa: E402
    MACHINE,
    fresh_interpreter,
    load,
    matched_inner,
    serial_share,
    spin,
    spin_vector,
)
from readme_block import update_readme  # noqa: E402

#: Where ``--doc`` writes the table (between ``<!-- bench_integrators: start/end -->``).
DOC = Path(__file__).resolve().parents[1] / "docs" / "performance.md"

TARGET_ERR = 1e-10
GOAL_VS_HEYOKA = 3.0
GOAL_VS_SCIPY = 600.0
GOAL_SPEEDUP = 1.8
#: Interleaved rounds of the 2-thread section (at least).
TWO_THREAD_ROUNDS = 8
#: Time outside the parallel kernel at 1 thread, as a share of the whole call.
GOAL_SERIAL = 0.03
#: Tolerance ladder (1, 2, 5 per decade) for "the loosest tolerance that reaches the target".
LADDER = tuple(m * 10.0**-e for e in range(5, 16) for m in (5, 2, 1))


# ------------------------------------------------------------------------------ the engine
class EngineKernel:
    """The engine's RK batch kernel on the task's orbits (one-period map: to r_max), psi."""

    def __init__(self, o: dict[str, np.ndarray], method: str, rtol: float, workers: int = 1):
        self.args_in = [o[k] for k in ("alpha", "energy", "h", "Lz")]
        self.params = engine.Scene(M=peers.M, g=peers.G, k=peers.K).params()
        self.method = METHODS[method].kernel_id
        self.rtol = float(rtol)
        self.workers = workers
        n = o["alpha"].size
        self.f = np.empty((5, n))
        self.steps = np.empty(n, np.int64)
        self.status = np.empty(n, np.int8)

    def __call__(self) -> np.ndarray:
        args = (points(*self.args_in), self.params, self.method, 0, self.rtol, 1_000_000,
                self.workers, self.f, self.steps, self.status)  # fmt: skip
        call_specialized(integrate_points_lanes, args, LITERAL)
        return self.f[1]


class EngineAPI:
    """The API's one-period map (``evaluate_integrated``), or with ``public`` the whole of
    ``engine.evaluate(method=...)``."""

    def __init__(self, o: dict[str, np.ndarray], method: str, rtol: float, public: bool = False):
        self.args = [o[k] for k in ("alpha", "energy", "h", "Lz")]
        self.scene = engine.Scene(M=peers.M, g=peers.G, k=peers.K)
        self.method = method
        self.rtol = rtol
        self.public = public

    def __call__(self) -> np.ndarray:
        if self.public:
            ds = engine.evaluate(*self.args, self.scene, method=self.method, rtol=self.rtol)
            return ds.apsidal_angle.values
        return evaluate_integrated(*self.args, self.scene, self.method, self.rtol)["apsidal_angle"]


# ------------------------------------------------------------------------------- measuring
def loosest(make: Callable[[float], Callable], ladder, ref: np.ndarray) -> tuple[float, dict]:
    """Loosest tolerance of the ladder whose max psi error over the orbits is <= TARGET_ERR,
    walking from loose to tight; (tol or NaN, {tol: max error} of the rungs tried)."""
    tried = {}
    for tol in ladder:
        err = float(np.max(peers.rel_err(make(tol)(), ref)))
        tried[tol] = err
        if err <= TARGET_ERR:
            return tol, tried
    return math.nan, tried


class Timed:
    """Best per-call wall and thread-CPU time [s] of a callable over interleaved rounds."""

    def __init__(self, fn: Callable[[], object], min_time: float, threads: int = 1):
        self.fn = fn
        self.threads = threads
        numba.set_num_threads(threads)
        t0 = time.perf_counter()
        fn()
        single = max(time.perf_counter() - t0, 1e-6)
        self.calls = max(1, math.ceil(min_time / single))
        self.wall = math.inf
        self.cpu = math.inf

    def round(self) -> None:
        numba.set_num_threads(self.threads)
        c0, w0 = time.thread_time(), time.perf_counter()
        for _ in range(self.calls):
            self.fn()
        w1, c1 = time.perf_counter(), time.thread_time()
        self.wall = min(self.wall, (w1 - w0) / self.calls)
        self.cpu = min(self.cpu, (c1 - c0) / self.calls)


# ------------------------------------------------------------------------------------ the run
def calibrate(o, y0, scales, hy: bool) -> dict[str, tuple[float, dict]]:
    """Each solver's loosest tolerance for max psi error <= TARGET_ERR."""
    ref = o["psi"]
    numba.set_num_threads(1)
    out = {
        "engine dop853": loosest(lambda t: EngineKernel(o, "dop853", t), LADDER, ref),
        "engine rk45": loosest(lambda t: EngineKernel(o, "rk45", t), LADDER, ref),
    }
    ladder = [t for t in LADDER if t <= 1e-9]
    out["scipy DOP853"] = loosest(
        lambda t: peers.scipy_runner(o, y0, t * scales, "DOP853", t), ladder, ref
    )
    if hy:
        out["heyoka"] = loosest(lambda t: peers.heyoka_loop_runner(o, y0, t), LADDER, ref)
    return out


def contenders(o, y0, scales, tol: dict, hy: bool) -> dict[str, tuple[str, Callable]]:
    """name -> (tolerance text, callable returning psi), 1 thread each."""
    r853, r45 = tol["engine dop853"][0], tol["engine rk45"][0]
    c = {
        "engine dop853, API": (f"rtol {r853:g}", EngineAPI(o, "dop853", r853)),
        "engine dop853, batch kernel": (f"rtol {r853:g}", EngineKernel(o, "dop853", r853)),
        "engine rk45, batch kernel": (f"rtol {r45:g}", EngineKernel(o, "rk45", r45)),
        "engine.evaluate(dop853)": (f"rtol {r853:g}", EngineAPI(o, "dop853", r853, True)),
        "scipy DOP853 (goal's peer)": (
            "rtol = atol = 1e-10",
            peers.scipy_runner(o, y0, 1e-10, "DOP853", 1e-10),
        ),
    }
    ts = tol["scipy DOP853"][0]
    if not math.isnan(ts):
        run = peers.scipy_runner(o, y0, ts * scales, "DOP853", ts)
        c["scipy DOP853, matched"] = (f"rtol {ts:g}, atol rtol x scales", run)
    if hy:
        th = tol["heyoka"][0]
        c["heyoka loop (goal's peer)"] = ("tol 1e-10", peers.heyoka_loop_runner(o, y0, 1e-10))
        if not math.isnan(th):
            c["heyoka loop, matched"] = (f"tol {th:g}", peers.heyoka_loop_runner(o, y0, th))
            c["heyoka batch (SIMD), matched"] = (f"tol {th:g}",
                                                 peers.heyoka_batch_runner(o, y0, th))  # fmt: skip
    return c


def per_core(o, cands, rounds: int, min_time: float) -> dict[str, dict]:
    """The 1-thread table: errors, and best CPU and wall time per orbit over the rounds."""
    n = o["alpha"].size
    rows = {}
    timers = {}
    for name, (tol, fn) in cands.items():
        err = peers.rel_err(np.array(fn(), copy=True), o["psi"])
        quick = min_time if name.startswith(("engine", "heyoka")) else 0.0
        timers[name] = Timed(fn, quick)
        rows[name] = {"tol": tol, "err": err}
    for _ in range(rounds):
        for t in timers.values():
            t.round()
    for name, t in timers.items():
        rows[name].update(cpu=t.cpu / n, wall=t.wall / n)
    return rows


def two_threads(n: int, r853: float, r45: float, rounds: int, min_time: float) -> dict[str, float]:
    """Wall time per orbit at 1 and 2 threads on ``n`` orbits of the task: the engine's batch,
    the API (dop853 and rk45) and two compute-only control loops as long as the API's call
    (``spin``, one latency-bound chain; ``spin_vector``, bound by the vector units like the
    lanes), all in the same interleaved rounds (so the controls see the same machine as the
    engine); the serial shares at 1 thread
    of the API's two maps and of ``engine.evaluate(method="dop853")`` (outside the lanes
    kernel and the closed form's parallel regions: its fixed cost, the validation and the
    Dataset, is ~2 ms a call). heyoka's 2-thread form, its ensemble
    propagation, copies the integrator for every orbit and runs ~100x slower than its loop at
    this orbit size: it is not a peer here."""
    o = peers.typical_orbits(n, seed=7)
    out = {"n": n, "load before": load()}
    api = EngineAPI(o, "dop853", r853)
    api()
    inner = matched_inner(spin, api)
    inner_v = matched_inner(spin_vector, api)
    timers = {
        "engine 1": Timed(EngineKernel(o, "dop853", r853, 1), min_time, 1),
        "engine 2": Timed(EngineKernel(o, "dop853", r853, 2), min_time, 2),
        "api 1": Timed(EngineAPI(o, "dop853", r853), min_time, 1),
        "api 2": Timed(EngineAPI(o, "dop853", r853), min_time, 2),
        "rk45 1": Timed(EngineAPI(o, "rk45", r45), min_time, 1),
        "rk45 2": Timed(EngineAPI(o, "rk45", r45), min_time, 2),
        "control 1": Timed(lambda: spin(64, inner), min_time, 1),
        "control 2": Timed(lambda: spin(64, inner), min_time, 2),
        "vector 1": Timed(lambda: spin_vector(64, inner_v), min_time, 1),
        "vector 2": Timed(lambda: spin_vector(64, inner_v), min_time, 2),
    }
    # more rounds than the per-core table: a 2-thread best needs both cores free at once
    for _ in range(max(rounds, TWO_THREAD_ROUNDS)):
        for t in timers.values():
            t.round()
    out.update({k: t.wall / n for k, t in timers.items()})
    lanes = (engine.integrated, "call_specialized")
    out["serial"] = serial_share(EngineAPI(o, "dop853", r853), *lanes, rounds=max(rounds, 15))
    out["serial rk45"] = serial_share(EngineAPI(o, "rk45", r45), *lanes, rounds=max(rounds, 15))
    regions = {"rounds": max(rounds, 15), "also": [(engine.evaluation, "run_queued")]}
    out["serial evaluate"] = serial_share(EngineAPI(o, "dop853", r853, True), *lanes, **regions)
    # its fixed cost per call (~1-2 ms: the plan, the Dataset) on 10x the orbits
    big = peers.typical_orbits(10 * n, seed=8)
    out["serial evaluate big"] = serial_share(EngineAPI(big, "dop853", r853, True), *lanes,
                                              **regions)  # fmt: skip
    out["control"] = timers["control 1"].wall / timers["control 2"].wall
    out["vector"] = timers["vector 1"].wall / timers["vector 2"].wall
    out["load after"] = load()
    numba.set_num_threads(1)
    return out


@numba.njit(nogil=True)
def _steps(method, W, rtol, n):
    numba.literally(method)
    for _ in range(n):
        lanes_attempt(method, 0, W, rtol)
    return W[0]


def step_cost(method: str, rtol: float) -> float:
    """CPU time [s] of one step of one lane: the generated step over all lanes in a loop (on a
    fixed, harmless state), divided by the lanes."""
    m = METHODS[method].kernel_id
    ly = layout(m, 5)
    W = np.ones(ly.n_slots * LANES)
    W[ly.H * LANES : (ly.H + 1) * LANES] = 1e-3
    call_specialized(_steps, (m, W, rtol, 10), ("method",))
    best = math.inf
    for _ in range(5):
        c0 = time.thread_time()
        call_specialized(_steps, (m, W, rtol, 20_000), ("method",))
        best = min(best, (time.thread_time() - c0) / 20_000)
    return best / LANES


_PROBE = """
import json, time
t0 = time.perf_counter()
import numpy as np
import engine
from engine.integrated import evaluate_integrated
out = {"import": time.perf_counter() - t0}
sc = engine.Scene()
a, h, lz = np.full(64, 0.5), np.full(64, 1.0), np.full(64, 0.5)
e = engine.minimum_energy(a, h, lz, sc) * 0.7
for m in ("rk45", "dop853"):
    t1 = time.perf_counter()
    evaluate_integrated(a, e, h, lz, sc, m, 1e-10)
    out[m] = time.perf_counter() - t1
print(json.dumps(out))
"""


def first_call(cache_dir: str | None) -> dict:
    """Import time and the first evaluate_integrated per RK method in a fresh interpreter [s]:
    with an empty compile cache (``cache_dir``) or the user's."""
    return fresh_interpreter(_PROBE, cache_dir)


# ------------------------------------------------------------------------------------ report
def goals(rows: dict, thr: dict, tol: dict, hy: bool) -> list[dict]:
    """The goal rows (the API's dop853 map against each peer, 2 threads against 1, the serial
    share): figure, peer, ratio, target, met."""
    eng = rows["engine dop853, API"]
    out = []
    for peer, target in (("heyoka loop (goal's peer)", GOAL_VS_HEYOKA),
                         ("scipy DOP853 (goal's peer)", GOAL_VS_SCIPY)):  # fmt: skip
        r = rows.get(peer)
        if r is None:
            out.append({"goal": f"dop853 vs {peer.split(' (')[0]}", "figure": 1 / eng["cpu"],
                        "peer": None, "ratio": math.nan, "target": target, "met": "no peer "
                        "(heyoka not installed)"})  # fmt: skip
            continue
        ratio = r["cpu"] / eng["cpu"]
        ok = ratio >= target and np.max(eng["err"]) <= TARGET_ERR
        out.append({"goal": f"dop853 map, API (rtol {tol['engine dop853'][0]:g}) vs "
                    f"{peer.split(' (')[0]}, per core", "figure": 1 / eng["cpu"],
                    "peer": 1 / r["cpu"], "peer_err": float(np.max(r["err"])),
                    "ratio": ratio, "wall_ratio": r["wall"] / eng["wall"], "target": target,
                    "met": "met" if ok else "MISSED"})  # fmt: skip
    sp = thr["api 1"] / thr["api 2"]
    out.append({"goal": "dop853 map, API, 2 threads vs 1", "figure": 1 / thr["api 2"],
                "peer": None, "ratio": sp, "target": GOAL_SPEEDUP,
                "met": "met" if sp >= GOAL_SPEEDUP else "MISSED"})  # fmt: skip
    sp = thr["rk45 1"] / thr["rk45 2"]
    out.append({"goal": "rk45 map, API, 2 threads vs 1", "figure": 1 / thr["rk45 2"],
                "peer": None, "ratio": sp, "target": GOAL_SPEEDUP,
                "met": "met" if sp >= GOAL_SPEEDUP else "MISSED"})  # fmt: skip
    n = thr["n"]
    for label, key in (("dop853 map, API", "serial"), ("rk45 map, API", "serial rk45"),
                       ("engine.evaluate(dop853)", "serial evaluate"),
                       ("engine.evaluate(dop853)", "serial evaluate big")):  # fmt: skip
        share = thr[key]
        size = f"{10 * n if key.endswith('big') else n} orbits"
        out.append({"goal": f"{label}, serial share at 1 thread ({size})", "figure": math.nan,
                    "peer": None, "ratio": share, "target": GOAL_SERIAL,
                    "met": "met" if share <= GOAL_SERIAL else "MISSED"})  # fmt: skip
    return out


def print_report(o, rows, thr, tol, gl, prof, hy) -> None:
    n = o["alpha"].size
    print("\n1. Calibration: loosest tolerance (1, 2, 5 per decade) with max psi error <= "
          f"{TARGET_ERR:g} over the {n} orbits")  # fmt: skip
    for name, (t, tried) in tol.items():
        looser = [f"{k:g}: {v:.1e}" for k, v in tried.items() if k != t][-1:]
        note = f" (one rung looser, {looser[0]})" if looser else ""
        print(f"   {name:14s} {'none on the ladder' if math.isnan(t) else f'{t:g}'}{note}")
    print("\n2. Per core (1 thread): best of the rounds, CPU time of the calling thread (wall)")
    head = (f"   {'contender':34s} {'tolerance':30s} {'max psi err':>11s} {'orbits/s':>10s} "
            f"{'us/orbit':>9s} {'wall orbits/s':>14s}")  # fmt: skip
    print(head + "\n   " + "-" * (len(head) - 3))
    for name, r in rows.items():
        print(f"   {name:34s} {r['tol']:30s} {np.max(r['err']):11.1e} {1 / r['cpu']:10.3g} "
              f"{r['cpu'] * 1e6:9.2f} {1 / r['wall']:14.3g}")  # fmt: skip
    e = rows["engine dop853, batch kernel"]
    print("   (engine.evaluate also computes the closed form of every orbit and builds an xarray "
          "Dataset: a fixed ~1 ms per call)")  # fmt: skip
    print("\n3. Where the time goes (engine dop853, 1 thread, per orbit)")
    print(f"   {prof['steps']:.1f} accepted steps (to r_max) x {prof['step'] * 1e9:.0f} ns (one "
          f"lane's share of a step on {LANES} lanes) = {prof['steps'] * prof['step'] * 1e6:.2f} "
          "us; the rest, "
          f"{(e['cpu'] - prof['steps'] * prof['step']) * 1e6:.2f} us of {e['cpu'] * 1e6:.2f}: "
          "rejected steps, step control, the start (turning points, tolerances, first step), "
          "the apsis (location, polishing step) and the result")  # fmt: skip
    print("\n4. Two threads (wall per orbit, best of the rounds, interleaved)")
    sp = thr["api 1"] / thr["api 2"]
    sk = thr["engine 1"] / thr["engine 2"]
    s45 = thr["rk45 1"] / thr["rk45 2"]
    print(f"   {thr['n']} orbits; dop853 map, API: {1 / thr['api 1']:.3g} -> "
          f"{1 / thr['api 2']:.3g} orbits/s, speedup {sp:.2f}; batch kernel alone "
          f"{sk:.2f}; rk45 map, API: {1 / thr['rk45 1']:.3g} -> {1 / thr['rk45 2']:.3g} "
          f"orbits/s, speedup {s45:.2f}")  # fmt: skip
    print(f"   serial share at 1 thread (wall time outside the parallel kernels / the whole "
          f"call): dop853 API {thr['serial']:.1%}, rk45 API {thr['serial rk45']:.1%}, "
          f"engine.evaluate(dop853) {thr['serial evaluate']:.1%} ({10 * thr['n']} orbits: "
          f"{thr['serial evaluate big']:.1%})")  # fmt: skip
    print(f"   controls (compute-only prange loops as long as the API's call, same rounds): "
          f"scalar {thr['control']:.2f}, vector units {thr['vector']:.2f} (2.0 on two free "
          f"cores); load average {thr['load before']} -> {thr['load after']}")  # fmt: skip
    print("\n5. Goals")
    for g in gl:
        if g["target"] == GOAL_SERIAL:
            print(f"   {g['goal']}: {g['ratio']:.1%}; goal <= "
                  f"{g['target']:.0%}: {g['met']}")  # fmt: skip
            continue
        peer = "" if g["peer"] is None else f", peer {g['peer']:.3g} orbits/s"
        wall = f" (wall {g['wall_ratio']:.0f}x)" if "wall_ratio" in g else ""
        ratio = f"{g['ratio']:.2f}" if g["ratio"] < 10 else f"{g['ratio']:.0f}"
        print(f"   {g['goal']}: {g['figure']:.3g} orbits/s{peer}; ratio {ratio}{wall}; goal >= "
              f"{g['target']:g}: {g['met']}")  # fmt: skip
    if any(g["met"] == "MISSED" and g["target"] == GOAL_SPEEDUP for g in gl):
        print(f"   2 threads: the control loops reached {thr['control']:.2f} (scalar) and "
              f"{thr['vector']:.2f} (vector units) in the same rounds; the engine reached "
              f"{sp / thr['vector']:.0%} of the vector one (what the controls miss is the "
              "second core's other work: rerun on a quiet machine)")  # fmt: skip


def markdown(o, rows, thr, gl, compiled) -> str:
    """The integrator table of docs/performance.md (from this run's numbers)."""
    n = o["alpha"].size
    e = rows["engine dop853, API"]
    date = datetime.date.today().isoformat()
    lines = [
        f"Integrators, {n} typical orbits, one-period map (r_min -> r_max, doubled) per orbit "
        f"(`.venv/bin/python scripts/bench_integrators.py`, {date}; {MACHINE}; load average "
        f"{thr['load before']} before the threads section, {thr['load after']} after; per core "
        f"= CPU time of one thread, best of 3 interleaved rounds; 2 threads: wall time, best of "
        f"{TWO_THREAD_ROUNDS}):",
        "",
        "| goal | engine | peer | ratio | target | |",
        "|---|---|---|---|---|---|",
    ]
    for g in gl:
        if g["target"] == GOAL_SERIAL:
            lines.append(f"| {g['goal']} | {g['ratio']:.1%} | - | - | "
                         f"<= {g['target']:.0%} | {g['met']} |")  # fmt: skip
            continue
        peer = "-" if g["peer"] is None else f"{g['peer']:.3g} orbits/s"
        if g["peer"] is not None and "peer_err" in g:
            peer += f" (max psi error {g['peer_err']:.1e})"
        ratio = "-" if math.isnan(g["ratio"]) else (
            f"{g['ratio']:.2f}" if g["ratio"] < 10 else f"{g['ratio']:.0f}")  # fmt: skip
        fig = f"{g['figure']:.3g} orbits/s"
        if g["target"] == GOAL_SPEEDUP:
            fig += (f" ({thr['n']} orbits; compute-only control loops: scalar "
                    f"{thr['control']:.2f}, vector {thr['vector']:.2f})")  # fmt: skip
        lines.append(f"| {g['goal']} | {fig} | {peer} | {ratio} | >= {g['target']:g} | "
                     f"{g['met']} |")  # fmt: skip
    for name in ("engine dop853, batch kernel", "engine.evaluate(dop853)"):
        lines.append(f"| {name}, per core | {1 / rows[name]['cpu']:.3g} orbits/s | | | | |")
    if compiled is not None:
        cold, warm = compiled
        lines.append(f"| numba compile of the rk45 / dop853 batch, first run / from cache | "
                     f"{cold['rk45']:.0f} s / {warm['rk45']:.2f} s, {cold['dop853']:.0f} s / "
                     f"{warm['dop853']:.2f} s | | | | |")  # fmt: skip
    lines.append("")
    lines.append(f"dop853's max psi error over the orbits: {np.max(e['err']):.1e}.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", type=int, default=200, help="orbits (default %(default)s)")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (3)")
    parser.add_argument(
        "--min-time", type=float, default=0.2, help="seconds per call block, engine, heyoka (0.2)"
    )
    parser.add_argument("--doc", action="store_true", help="rewrite docs/performance.md's table")
    parser.add_argument("--compile", action="store_true", help="time the first call, cold/cached")
    parser.add_argument(
        "--tiny", action="store_true", help="a seconds-long smoke run (tests/test_scripts.py)"
    )
    args = parser.parse_args(argv)
    if args.tiny:
        args.n, args.rounds, args.min_time, args.doc, args.compile = 2, 1, 0.0, False, False
    import scipy

    hy_version = peers.heyoka_version()
    hy = hy_version is not None
    t_start = time.perf_counter()
    print(f"machine: {MACHINE}, {platform.platform()}, numba threading layer "
          f"{numba.config.THREADING_LAYER}")  # fmt: skip
    print(f"python {platform.python_version()}, numba {numba.__version__}, numpy "
          f"{np.__version__}, scipy {scipy.__version__}, heyoka {hy_version or 'not installed'}, "
          f"conesurvey {engine.__version__}")  # fmt: skip
    print(f"load average before the run (1, 5, 15 min): {load()}")
    o = peers.typical_orbits(args.n)
    y0, scales = peers.start_states(o)
    print(f"task: {args.n} typical bounded orbits, one-period map (to r_max); median half "
          f"period {np.median(o['T']) / 2:.2f} s")  # fmt: skip
    tol = calibrate(o, y0, scales, hy)
    rows = per_core(o, contenders(o, y0, scales, tol, hy), args.rounds, args.min_time)
    r853 = tol["engine dop853"][0]
    kern = EngineKernel(o, "dop853", r853)
    kern()
    prof = {"steps": float(np.mean(kern.steps)), "step": step_cost("dop853", r853)}
    r45 = tol["engine rk45"][0]
    if math.isnan(r45):  # no rung reached the target (a --tiny run): the default
        r45 = 1e-10
    thr = two_threads(args.n if args.tiny else max(args.n, 2000), r853, r45, args.rounds,
                      args.min_time)  # fmt: skip
    gl = goals(rows, thr, tol, hy)
    print_report(o, rows, thr, tol, gl, prof, hy)
    compiled = None
    if args.compile:
        with tempfile.TemporaryDirectory(prefix="conesurvey-cold-") as tmp:
            cold = first_call(tmp)
        warm = first_call(None)
        compiled = (cold, warm)
        print("\n6. First call of evaluate_integrated (64 orbits) in a fresh interpreter [s]: "
              + "; ".join(f"{m} {cold[m]:.1f} compiling, {warm[m]:.2f} from the cache"
                          for m in ("rk45", "dop853")))  # fmt: skip
    md = markdown(o, rows, thr, gl, compiled)
    print("\ndocs/performance.md table:\n" + md)
    if args.doc:
        update_readme("bench_integrators", md, DOC)
        print(f"\nwrote it into {DOC}")
    print(f"\nload average at the end: {load()}; benchmark time "
          f"{time.perf_counter() - t_start:.0f} s")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Throughput of the integrator path against scipy and heyoka, measured side by side in one run.

    python scripts/bench_integrators.py                  # 200 orbits (a few minutes)
    python scripts/bench_integrators.py -n 100 --no-compile

The task: the same ``-n`` typical bounded orbits under gravity (M = 1 kg, g = 9.81 m/s2, k = 0.4),
each integrated for one half radial period, from the inner turning point r_min (u = 0) to the
outer one r_max (the next u = 0), giving the apsidal angle psi (azimuth swept) to compare with the
closed form (``engine.evaluate``, method "exact").

(a) The engine's integrators (rk45, dop853, symplectic) at rtol 1e-6, 1e-9, 1e-10, 1e-12 on 1 and
    2 numba threads: orbits/s, 2-thread speedup and parallel efficiency. "half period" is a
    prange kernel defined here that calls the engine's own run kernel
    (``engine.kernels.orbit.run``) with the engine's start (``orbit_start``,
    ``initial_state``, ``tolerance_scales``) and stops at the
    first apsis (n_apsides = 1); "API, full period" is ``engine.integrated.evaluate_integrated``,
    which integrates r_min -> r_max -> r_min (twice the work) and is what ``engine.evaluate``
    runs.
(b) Peers at matched accuracy, same equations of motion (physics.md), same start, a terminal
    event u = 0 (u decreasing) after r_min: scipy.integrate.solve_ivp RK45 and DOP853 (atol =
    rtol x the engine's per-component scales) and heyoka (taylor_adaptive driven by a Python loop
    over orbits; its ensemble propagation; taylor_adaptive_batch, SIMD lanes), if importable.
    Each solver's tolerance is the loosest of a decade ladder whose largest apsidal-angle error
    over a calibration subset is <= the accuracy level; the error over all orbits is printed.
(c) The targets: integrator path at rtol 1e-10 with apsidal-angle error <= 1e-10 at least 3x
    heyoka's scalar loop and 500x scipy DOP853 (1 thread each); 2-thread speedup >= 1.8.
(d) First call of the integrator kernel in a fresh interpreter: cold (empty NUMBA_CACHE_DIR:
    compile) and warm (the on-disk cache).

scipy and heyoka are benchmark extras, imported here only.
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
from numba import literally, prange

import engine
from engine._jit import call_specialized
from engine.integrated import evaluate_integrated
from engine.kernels.model import set_alpha
from engine.kernels.orbit import initial_state, orbit_start, run, tolerance_scales
from engine.kernels.protocol import APOCENTRE, OK, RECORD_NONE, event_buffers
from engine.methods import METHODS as REGISTRY

M, G, K = 1.0, 9.81, 0.4
METHODS = ("rk45", "dop853", "symplectic")
ENGINE_RTOLS = (1e-6, 1e-9, 1e-10, 1e-12)
LEVELS = (1e-6, 1e-9, 1e-10, 1e-12)  # accuracy levels: max apsidal-angle error over the orbits
LADDER = tuple(10.0**-j for j in range(3, 16))  # tolerance ladder for matching
TARGET_RTOL = 1e-10
TARGET_ERR = 1e-10
TARGET_VS_HEYOKA = 3.0
TARGET_VS_SCIPY = 500.0
TARGET_SPEEDUP = 1.8
NAN = math.nan


# ---------------------------------------------------------------------------- orbits, reference
def typical_orbits(n: int, seed: int = 20240612) -> dict[str, np.ndarray]:
    """n typical bounded orbits: alpha uniform in [10, 80] deg, h uniform in [-3, 3] m/s, |L_z|
    log-uniform in [0.05, 3] kg m2/s with random sign, offset (calE - V_min)/|V_min| log-uniform
    in [1e-3, 10]; with their closed-form r_min, r_max, T_r and psi."""
    rng = np.random.default_rng(seed)
    m = 2 * n + 16
    alpha = np.radians(rng.uniform(10.0, 80.0, m))
    h = rng.uniform(-3.0, 3.0, m)
    Lz = np.exp(rng.uniform(math.log(0.05), math.log(3.0), m)) * rng.choice([-1.0, 1.0], m)
    off = np.exp(rng.uniform(math.log(1e-3), math.log(10.0), m))
    scene = engine.Scene(M=M, g=G, k=K)
    energy = engine.minimum_energy(alpha, h, Lz, scene)
    energy = energy + off * np.abs(energy)
    ex = engine.evaluate(alpha, energy, h, Lz, scene)
    keep = np.flatnonzero(ex.orbit_class.values == engine.CLASS_NAMES.index("bounded"))[:n]
    if keep.size < n:
        raise RuntimeError(f"only {keep.size} of {n} random orbits are bounded")
    out = {"alpha": alpha, "energy": energy, "h": h, "Lz": Lz}
    out = {k: np.ascontiguousarray(v[keep]) for k, v in out.items()}
    for name, var in (("r1", "r_min"), ("r2", "r_max"), ("T", "period"), ("psi", "apsidal_angle")):
        out[name] = np.ascontiguousarray(ex[var].values[keep])
    return out


def start_states(o: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(y0 [n, 5], atol scales [n, 5]): the engine's initial state at r_min (u = 0) and its
    per-component tolerance scales (atol = rtol * scale)."""
    scene = engine.Scene(M=M, g=G, k=K)
    n = o["alpha"].size
    y0 = np.empty((n, 5))
    sc = np.empty((n, 5))
    for i in range(n):
        p = scene.params(float(o["alpha"][i]))
        args = (float(o["energy"][i]), float(o["h"][i]), float(o["Lz"][i]))
        ok, r1, r2, rc = orbit_start(p, *args)
        y = initial_state(p, 0, r1, *args)
        y[2] = 0.0
        y0[i] = y
        sc[i] = tolerance_scales(p, 0, y, *args, r1, r2, rc)
    return y0, sc


# --------------------------------------------------------------- engine: half-period kernel
_JIT = {"parallel": True, "cache": True, "nogil": True, "error_model": "numpy"}


@numba.njit(**_JIT)
def half_period(alpha, energy, h, Lz, params, method, rtol, max_steps, psi, t_half, steps):
    """Integrate each orbit from r_min to the first apsis (r_max) with the engine's run kernel
    of the literal ``method`` id; writes psi [rad] (NaN on failure), the time [s] and the
    accepted steps."""
    literally(method)
    for i in prange(alpha.shape[0]):
        p = params.copy()
        set_alpha(p, alpha[i])
        psi[i] = math.nan
        t_half[i] = math.nan
        steps[i] = 0
        ok, r1, r2, rc = orbit_start(p, energy[i], h[i], Lz[i])
        if not ok:
            continue
        y0 = initial_state(p, 0, r1, energy[i], h[i], Lz[i])
        y0[2] = 0.0
        atol = tolerance_scales(p, 0, y0, energy[i], h[i], Lz[i], r1, r2, rc) * rtol
        ev_t, ev_kind, ev_y = event_buffers(2, y0.shape[0])
        res = run(method, 0, y0, p, (energy[i], h[i], Lz[i]), rtol, atol, math.inf,
                  np.int64(1), max_steps, np.int64(RECORD_NONE), 0.0, ev_t, ev_kind, ev_y, ev_t,
                  ev_y, ev_y)  # fmt: skip
        steps[i] = res[1]
        if res[0] == OK and res[5] >= 1 and ev_kind[0] == APOCENTRE:
            psi[i] = abs(ev_y[0, 1])
            t_half[i] = ev_t[0]


@numba.njit(**_JIT)
def _spin(n_items, n_inner):
    """A compute-only prange loop (no memory traffic): the machine's available parallelism."""
    acc = np.zeros(n_items)
    for i in prange(n_items):
        x = 0.0
        for j in range(n_inner):
            x += math.sin(x + j)
        acc[i] = x
    return acc.sum()


def reference_speedup(threads: list[int], repeats: int) -> float:
    """2-thread speedup of :func:`_spin` (about 2 on two free cores, 1 when one is busy)."""
    t = {}
    for nt in threads:
        numba.set_num_threads(nt)
        _spin(64, 20_000)
        t[nt] = best_time(lambda: _spin(64, 20_000), repeats)
    numba.set_num_threads(threads[-1])
    return t[threads[0]] / t[threads[-1]]


class EngineHalf:
    """Callable: the half-period kernel on the orbit set for one method and rtol."""

    def __init__(self, o: dict[str, np.ndarray], method: str, rtol: float):
        self.args_in = [o[k] for k in ("alpha", "energy", "h", "Lz")]
        self.params = engine.Scene(M=M, g=G, k=K).params()
        self.method = REGISTRY[method].kernel_id
        self.rtol = float(rtol)
        n = o["alpha"].size
        self.psi = np.empty(n)
        self.t = np.empty(n)
        self.steps = np.empty(n, np.int64)

    def __call__(self) -> np.ndarray:
        out = (self.psi, self.t, self.steps)
        args = (*self.args_in, self.params, self.method, self.rtol, 1_000_000, *out)
        call_specialized(half_period, args, (5,))
        return self.psi


class EngineFull:
    """Callable: the public batch path (full radial period) for one method and rtol."""

    def __init__(self, o: dict[str, np.ndarray], method: str, rtol: float):
        self.args = [o[k] for k in ("alpha", "energy", "h", "Lz")]
        self.scene = engine.Scene(M=M, g=G, k=K)
        self.method = method
        self.rtol = rtol

    def __call__(self) -> np.ndarray:
        return evaluate_integrated(*self.args, self.scene, self.method, self.rtol)["apsidal_angle"]


# -------------------------------------------------------------------------------------- peers
def scipy_runner(o, y0, scales, method: str, rtol: float, idx: np.ndarray) -> Callable:
    """solve_ivp over the orbits ``idx``, one after the other; returns psi per orbit."""
    from scipy.integrate import solve_ivp

    kk = K / (1.0 + K)

    def make(i):
        a = float(o["alpha"][i])
        isin = 1.0 / math.sin(a)
        cot = math.cos(a) * isin
        gc = G * math.cos(a) / (1.0 + K)

        def fun(t, y):
            r, _, u, v, w = y.tolist()
            ir = 1.0 / r
            kap = cot * ir
            return np.array(
                [u, v * isin * ir, v * v * ir + kk * kap * v * w - gc, -u * v * ir, -kap * u * v]
            )

        def apsis(t, y):
            return y[2]

        apsis.terminal = True
        apsis.direction = -1.0
        return fun, apsis

    funcs = {int(i): make(i) for i in idx}
    psi = np.full(o["alpha"].size, NAN)

    def run() -> np.ndarray:
        for i in idx:
            fun, apsis = funcs[int(i)]
            sol = solve_ivp(fun, (0.0, 10.0 * o["T"][i]), y0[i], method=method, rtol=rtol,
                            atol=rtol * scales[i], events=apsis)  # fmt: skip
            ev = sol.y_events[0]
            psi[i] = abs(ev[0][1]) if len(ev) else NAN
        return psi

    return run


_HY_CACHE: dict[tuple, object] = {}


def _heyoka_system():
    import heyoka as hy

    r, th, u, v, w = hy.make_vars("r", "th", "u", "v", "w")
    isin, cot, kk, gc = hy.par[0], hy.par[1], hy.par[2], hy.par[3]
    return [
        (r, u),
        (th, v * isin / r),
        (u, v * v / r + kk * cot / r * v * w - gc),
        (v, -u * v / r),
        (w, -cot / r * u * v),
    ], u


def _pars(a: np.ndarray) -> np.ndarray:
    s = np.sin(a)
    c = np.cos(a)
    return np.array([1.0 / s, c / s, np.full_like(a, K / (1.0 + K)), G * c / (1.0 + K)])


def heyoka_scalar(tol: float):
    """A heyoka taylor_adaptive of the equations of motion with the terminal apsis event
    (built once per tolerance; the build, an LLVM compilation, is not timed)."""
    import heyoka as hy

    key = ("scalar", tol)
    if key not in _HY_CACHE:
        sys_, u = _heyoka_system()
        ev = hy.t_event(u, direction=hy.event_direction.negative)
        _HY_CACHE[key] = hy.taylor_adaptive(sys_, [1.0, 0, 0, 1, 1], tol=tol, t_events=[ev],
                                            pars=[1.0, 1.0, 0.0, 0.0])  # fmt: skip
    return _HY_CACHE[key]


def heyoka_loop_runner(o, y0, tol: float, idx: np.ndarray) -> Callable:
    """The scalar integrator driven by a Python loop over the orbits ``idx``."""
    ta = heyoka_scalar(tol)
    pars = _pars(o["alpha"]).T.copy()
    psi = np.full(o["alpha"].size, NAN)
    t_max = 10.0 * o["T"]

    def run() -> np.ndarray:
        for i in idx:
            ta.time = 0.0
            ta.state[:] = y0[i]
            ta.pars[:] = pars[i]
            ta.reset_cooldowns()
            res = ta.propagate_until(float(t_max[i]))
            psi[i] = abs(ta.state[1]) if int(res[0]) == -1 else NAN
        return psi

    return run


def heyoka_ensemble_runner(o, y0, tol: float, idx: np.ndarray, workers: int) -> Callable:
    """heyoka.ensemble_propagate_until (thread pool) over the orbits ``idx``."""
    import heyoka as hy

    ta = heyoka_scalar(tol)
    pars = _pars(o["alpha"]).T.copy()
    psi = np.full(o["alpha"].size, NAN)
    t_max = float(10.0 * np.max(o["T"][idx]))

    def gen(tc, j):
        i = idx[j]
        tc.time = 0.0
        tc.state[:] = y0[i]
        tc.pars[:] = pars[i]
        tc.reset_cooldowns()
        return tc

    def run() -> np.ndarray:
        out = hy.ensemble_propagate_until(ta, t_max, len(idx), gen, algorithm="thread",
                                          max_workers=workers)  # fmt: skip
        for j, res in enumerate(out):
            psi[idx[j]] = abs(res[0].state[1]) if int(res[1]) == -1 else NAN
        return psi

    return run


def heyoka_batch_runner(o, y0, tol: float, idx: np.ndarray) -> Callable:
    """taylor_adaptive_batch (SIMD lanes) over the orbits ``idx``, ``recommended_simd_size``
    orbits at a time. A terminal event in one lane stops the whole batch, so the batch is
    propagated again with the finished lanes' target time set to their current time (they hold
    still) until every lane has met its apsis: at most one call per lane."""
    import heyoka as hy

    bs = int(hy.recommended_simd_size())
    key = ("batch", tol, bs)
    if key not in _HY_CACHE:
        sys_, u = _heyoka_system()
        ev = hy.t_event_batch(u, direction=hy.event_direction.negative)
        _HY_CACHE[key] = hy.taylor_adaptive_batch(sys_, np.ones((5, bs)), tol=tol,
                                                  t_events=[ev], pars=np.ones((4, bs)))  # fmt: skip
    ta = _HY_CACHE[key]
    nb = -(-len(idx) // bs)
    pad = np.resize(idx, nb * bs)  # the last batch is filled with repeats
    lanes = [pad[b * bs : (b + 1) * bs] for b in range(nb)]
    Y = [np.ascontiguousarray(y0[ii].T) for ii in lanes]
    P = [np.ascontiguousarray(_pars(o["alpha"][ii])) for ii in lanes]
    T = [10.0 * o["T"][ii] for ii in lanes]
    psi = np.full(o["alpha"].size, NAN)

    def run() -> np.ndarray:
        for b in range(nb):
            ta.set_time(0.0)
            ta.state[:] = Y[b]
            ta.pars[:] = P[b]
            ta.reset_cooldowns()
            done = np.zeros(bs, bool)
            for _ in range(bs + 1):
                ta.propagate_until(np.where(done, ta.time, T[b]))
                now = ta.time
                for lane, res in enumerate(ta.propagate_res):
                    if done[lane]:
                        continue
                    if int(res[0]) == -1:
                        psi[lanes[b][lane]] = abs(ta.state[1, lane])
                        done[lane] = True
                    elif now[lane] >= T[b][lane]:
                        psi[lanes[b][lane]] = NAN
                        done[lane] = True
                if done.all():
                    break
        return psi

    return run


# ------------------------------------------------------------------------------------- timing
def best_time(fn: Callable[[], object], repeats: int) -> float:
    """Smallest wall time [s] of ``repeats`` calls."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def interleaved_best(fn: Callable[[], object], threads: list[int], repeats: int) -> dict:
    """Best wall time [s] per thread count, the thread counts alternating call by call (so a
    change of machine load hits all of them alike)."""
    best = dict.fromkeys(threads, math.inf)
    for nt in threads:
        numba.set_num_threads(nt)
        fn()
    for _ in range(repeats):
        for nt in threads:
            numba.set_num_threads(nt)
            t0 = time.perf_counter()
            fn()
            best[nt] = min(best[nt], time.perf_counter() - t0)
    numba.set_num_threads(threads[-1])
    return best


def rel_err(psi: np.ndarray, ref: np.ndarray, idx: np.ndarray | None = None) -> np.ndarray:
    e = np.abs(psi / ref - 1.0)
    e = np.where(np.isnan(e), np.inf, e)  # a failed orbit counts as an infinite error
    return e if idx is None else e[idx]


def match(make: Callable[[float], Callable], ladder, levels, ref, calib) -> dict[float, float]:
    """Loosest tolerance of ``ladder`` whose max error over ``calib`` is <= each level (NaN if
    none); walks the ladder from loose to tight and stops once the tightest level is met."""
    found: dict[float, float] = dict.fromkeys(levels, NAN)
    for tol in ladder:
        err = float(np.max(rel_err(make(tol)(), ref, calib)))
        for lev in levels:
            if math.isnan(found[lev]) and err <= lev:
                found[lev] = tol
        if all(not math.isnan(v) for v in found.values()):
            break
    return found


_PROBE = """
import json, sys, time
t0 = time.perf_counter()
import numpy as np
import engine
from engine.integrated import evaluate_integrated
t1 = time.perf_counter()
sc = engine.Scene()
a = np.full(64, 0.5); h = np.full(64, 1.0); lz = np.full(64, 0.5)
e = engine.minimum_energy(a, h, lz, sc) * 0.7
out = {"import": t1 - t0}
for m in ("rk45", "dop853", "symplectic"):
    t2 = time.perf_counter()
    evaluate_integrated(a, e, h, lz, sc, m, 1e-10)
    t3 = time.perf_counter()
    evaluate_integrated(a, e, h, lz, sc, m, 1e-10)
    out[m] = [t3 - t2, time.perf_counter() - t3]
print(json.dumps(out))
"""


def first_call(cache_dir: str | None) -> dict:
    """Import time and first/second call of evaluate_integrated per method in a fresh
    interpreter [s]."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env.pop("CONESURVEY_NO_CACHE", None)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True,
                         check=True, timeout=900)  # fmt: skip
    out = json.loads(res.stdout.strip().splitlines()[-1])
    out["process"] = time.perf_counter() - t0
    return out


# --------------------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", type=int, default=200, help="orbits (default %(default)s)")
    parser.add_argument("-r", "--repeats", type=int, default=5, help="best of, engine (5)")
    parser.add_argument(
        "--calib", type=int, default=0, help="orbits for tolerance matching (default: all)"
    )
    parser.add_argument("--no-compile", action="store_true", help="skip the compile probe")
    args = parser.parse_args(argv)
    import scipy

    try:
        import heyoka as hy

        hy_version = hy.__version__
    except ImportError:
        hy = None
        hy_version = "not installed"
    t_start = time.perf_counter()
    ncpu = os.cpu_count() or 1
    print(f"machine: {platform.platform()}, {platform.machine()}, os.cpu_count() = {ncpu}")
    print(f"python {platform.python_version()}, numba {numba.__version__}, numpy "
          f"{np.__version__}, scipy {scipy.__version__}, heyoka {hy_version}, conesurvey "
          f"{engine.__version__}")  # fmt: skip
    load0 = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"load average before the run (1, 5, 15 min): {load0}")
    if hy is None:
        print("heyoka not installed")

    n = args.n
    o = typical_orbits(n)
    ref = o["psi"]
    y0, scales = start_states(o)
    allidx = np.arange(n)
    calib = allidx[: min(args.calib, n)] if args.calib > 0 else allidx
    threads = [1, 2] if numba.config.NUMBA_NUM_THREADS >= 2 else [1]
    print(f"\n{n} typical bounded orbits (g = {G}, k = {K}), one half radial period each "
          f"(r_min -> r_max); median half period {np.median(o['T']) / 2:.2f} s")  # fmt: skip

    # ---- (a) the engine at fixed tolerances
    t0 = time.perf_counter()
    for m in METHODS:  # compile / load the half-period kernel per method
        EngineHalf(o, m, 1e-6)()
    t_setup = time.perf_counter() - t0
    ref_before = reference_speedup(threads, 3) if len(threads) > 1 else NAN
    rows = {}
    for m in METHODS:
        for rt in ENGINE_RTOLS:
            half = EngineHalf(o, m, rt)
            full = EngineFull(o, m, rt)
            psi_half = half().copy()
            psi_full = full()
            rec = {"err": rel_err(psi_half, ref), "steps": np.median(half.steps)}
            rec["same"] = int(np.sum(psi_half == psi_full))
            for name, fn in (("half", half), ("full", full)):
                for nt, t in interleaved_best(fn, threads, args.repeats).items():
                    rec[f"{name}{nt}"] = t
            rows[m, rt] = rec
    numba.set_num_threads(threads[-1])
    ref_after = reference_speedup(threads, 3) if len(threads) > 1 else NAN
    layer = numba.threading_layer()
    print(f"\n(a) engine, best of {args.repeats}; threading layer {layer}; half-period kernel "
          f"load/compile {t_setup:.1f} s\n    control: 2-thread speedup of a compute-only prange "
          f"loop {ref_before:.2f} before and {ref_after:.2f} after these timings (2.0: two free "
          "cores)")  # fmt: skip
    head = (f"{'method':10s} {'rtol':>7s} {'psi err med':>11s} {'max':>8s} {'steps':>5s} "
            f"{'half: orb/s 1T':>14s} {'2T':>9s} {'speedup':>7s} {'eff':>5s}   "
            f"{'API full period: orb/s 1T':>25s} {'2T':>9s} {'speedup':>7s}")  # fmt: skip
    print(head)
    print("-" * len(head))
    for (m, rt), r in rows.items():
        s_half = r["half1"] / r[f"half{threads[-1]}"]
        s_full = r["full1"] / r[f"full{threads[-1]}"]
        print(f"{m:10s} {rt:7.0e} {np.median(r['err']):11.1e} {np.max(r['err']):8.1e} "
              f"{int(r['steps']):5d} {n / r['half1']:14.3g} {n / r[f'half{threads[-1]}']:9.3g} "
              f"{s_half:7.2f} {s_half / threads[-1]:5.0%}   {n / r['full1']:25.3g} "
              f"{n / r[f'full{threads[-1]}']:9.3g} {s_full:7.2f}")  # fmt: skip
    same = min(r["same"] for r in rows.values())
    print(f"(the API's psi is bit-identical to the half-period kernel's on at least {same} of {n} "
          "orbits per row: same steps up to r_max)")  # fmt: skip

    # ---- (b) matched accuracy
    solvers: dict[str, Callable[[float, np.ndarray], Callable]] = {}
    for m in METHODS:
        solvers[f"engine {m}"] = lambda tol, idx, m=m: EngineHalf(o, m, max(tol, 1e-14))
    solvers["scipy RK45"] = lambda tol, idx: scipy_runner(o, y0, scales, "RK45", tol, idx)
    solvers["scipy DOP853"] = lambda tol, idx: scipy_runner(o, y0, scales, "DOP853", tol, idx)
    if hy is not None:
        solvers["heyoka scalar loop"] = lambda tol, idx: heyoka_loop_runner(o, y0, tol, idx)
        solvers["heyoka batch (SIMD)"] = lambda tol, idx: heyoka_batch_runner(o, y0, tol, idx)
        nw = threads[-1]
        solvers[f"heyoka ensemble ({nw} threads)"] = lambda tol, idx, nw=nw: heyoka_ensemble_runner(
            o, y0, tol, idx, nw
        )
    t0 = time.perf_counter()
    chosen: dict[str, dict[float, float]] = {}
    for name, make in solvers.items():
        floor = 1e-15 if name.startswith("heyoka") else 1e-13 if name.startswith("scipy") else 1e-14
        ladder = [t for t in LADDER if t >= floor]
        if name.startswith("engine"):  # cheap: calibrate on all orbits
            chosen[name] = match(lambda t, mk=make: mk(t, allidx), ladder, LEVELS, ref, allidx)
        else:
            chosen[name] = match(lambda t, mk=make: mk(t, calib), ladder, LEVELS, ref, calib)
    t_match = time.perf_counter() - t0
    numba.set_num_threads(1)
    results: dict[tuple[str, float], dict] = {}
    for lev in LEVELS:
        for name, make in solvers.items():
            tol = chosen[name][lev]
            if math.isnan(tol):
                continue
            run = make(tol, allidx)
            psi = run()
            rep = args.repeats if name.startswith("engine") or "batch" in name else 2
            rep = 1 if name.startswith("scipy") else rep
            if name.startswith("engine"):
                run()
            tbest = best_time(run, rep)
            results[name, lev] = {"tol": tol, "t": tbest, "err": rel_err(psi, ref)}
    numba.set_num_threads(threads[-1])
    cal = "all" if calib.size == n else f"{calib.size} (scipy, heyoka; engine: all)"
    print(f"\n(b) matched accuracy: each solver at the loosest decade tolerance whose max psi "
          f"error over {cal} orbits is <= the level;\n    timed on all {n} orbits, 1 thread "
          f"(heyoka ensemble: {threads[-1]}), best of {args.repeats} (engine, heyoka batch), 2 "
          f"(heyoka loop and ensemble), 1 (scipy); matching took {t_match:.0f} s.\n    heyoka "
          "ensemble copies the integrator for every orbit (ensemble_propagate_until), which "
          "dominates at this orbit size")  # fmt: skip
    head = (f"{'level':>7s} {'solver':28s} {'tol':>7s} {'psi err med':>11s} {'max':>8s} "
            f"{'orbits/s':>10s} {'us/orbit':>9s} {'best engine / this':>18s}")  # fmt: skip
    print(head)
    print("-" * len(head))
    for lev in LEVELS:
        eng = [results[k] for k in results if k[1] == lev and k[0].startswith("engine")]
        t_eng = min((r["t"] for r in eng), default=NAN)
        for name in solvers:
            r = results.get((name, lev))
            if r is None:
                print(f"{lev:7.0e} {name:28s} {'-':>7s}   not reached on the tolerance ladder")
                continue
            flag = "" if np.max(r["err"]) <= lev else " (max > level on all orbits)"
            print(f"{lev:7.0e} {name:28s} {r['tol']:7.0e} {np.median(r['err']):11.1e} "
                  f"{np.max(r['err']):8.1e} {n / r['t']:10.3g} {r['t'] / n * 1e6:9.1f} "
                  f"{r['t'] / t_eng:17.2f}x{flag}")  # fmt: skip
        print()

    # ---- (c) targets
    print("(c) targets (1 thread each; half period)")
    cands = [(m, rows[m, TARGET_RTOL]) for m in METHODS]
    good = [(m, r) for m, r in cands if np.max(r["err"]) <= TARGET_ERR]
    if good:
        m_best, r_best = min(good, key=lambda mr: mr[1]["half1"])
        note = f"max psi error {np.max(r_best['err']):.1e} <= {TARGET_ERR:g}"
    else:
        m_best, r_best = min(cands, key=lambda mr: np.max(mr[1]["err"]))
        note = (f"NO method reaches max psi error <= {TARGET_ERR:g} at rtol {TARGET_RTOL:g}; "
                f"the most accurate, {m_best}, has {np.max(r_best['err']):.1e}")  # fmt: skip
    bad = ", ".join(f"{m} {np.max(r['err']):.1e}" for m, r in cands if (m, r) not in good)
    print(f"    at rtol {TARGET_RTOL:g}: engine {m_best}, {n / r_best['half1']:.3g} orbits/s "
          f"({note}; over the limit: {bad or 'none'})")  # fmt: skip
    eng_lev = {k[0]: v for k, v in results.items() if k[1] == TARGET_ERR and "engine" in k[0]}
    best_lev = min(eng_lev, key=lambda k: eng_lev[k]["t"]) if eng_lev else None
    if best_lev is not None:
        rb = eng_lev[best_lev]
        print(f"    matched accuracy (max psi error <= {TARGET_ERR:g}): {best_lev} at rtol "
              f"{rb['tol']:.0e}, {n / rb['t']:.3g} orbits/s")  # fmt: skip
    peers = (("heyoka scalar loop", TARGET_VS_HEYOKA), ("scipy DOP853", TARGET_VS_SCIPY))
    for peer, target in peers:
        r = results.get((peer, TARGET_ERR))
        if r is None:
            why = "heyoka not installed" if hy is None and "heyoka" in peer else "not reached"
            print(f"    vs {peer}: no result at max psi error <= {TARGET_ERR:g} ({why})")
            continue
        ratio = r["t"] / r_best["half1"]
        ok = "meets" if ratio >= target and good else "MISSES"
        line = (f"    vs {peer} (tol {r['tol']:.0e}, max psi error {np.max(r['err']):.1e}): "
                f"rtol-{TARGET_RTOL:g} engine {ratio:.2f}x")  # fmt: skip
        if best_lev is not None:
            ratio2 = r["t"] / eng_lev[best_lev]["t"]
            ok2 = "meets" if ratio2 >= target else "MISSES"
            line += f" ({ok}), matched-accuracy engine {ratio2:.2f}x ({ok2})"
        print(f"{line}; target >= {target:g}x")
    if len(threads) > 1:
        for m in METHODS:
            r = rows[m, TARGET_RTOL]
            sp = r["half1"] / r["half2"]
            sf = r["full1"] / r["full2"]
            ok = "meets" if sp >= TARGET_SPEEDUP else "MISSES"
            print(f"    {m:10s} rtol {TARGET_RTOL:g}: 2-thread speedup {sp:.2f} half period "
                  f"(efficiency {sp / 2:.0%}), {sf:.2f} API full period   (target >= "
                  f"{TARGET_SPEEDUP:g}: {ok})")  # fmt: skip
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        print(f"    (control prange loop speedup {ref_before:.2f} / {ref_after:.2f}; "
              f"load average now {load}: with {ncpu} cores, a load above "
              f"{ncpu - 1} leaves the second thread less than a free core)")  # fmt: skip

    # ---- (d) compile time
    if not args.no_compile:
        with tempfile.TemporaryDirectory(prefix="numba-cold-") as tmp:
            cold = first_call(tmp)
        # the first warm run refreshes a stale cache (sources edited since it was written)
        warm = min(
            (first_call(None) for _ in range(3)), key=lambda d: sum(d[m][0] for m in METHODS)
        )
        print("\n(d) evaluate_integrated (64 orbits, rtol 1e-10) in a fresh interpreter [s]")
        print(f"{'cache':30s} {'import':>7s} " + " ".join(
            f"{m + ' 1st':>14s} {'2nd':>8s}" for m in METHODS) + f" {'process':>8s}")  # fmt: skip
        for label, d in (("cold (empty NUMBA_CACHE_DIR)", cold), ("warm (on-disk cache)", warm)):
            cells = " ".join(f"{d[m][0]:14.3f} {d[m][1]:8.5f}" for m in METHODS)
            print(f"{label:30s} {d['import']:7.2f} {cells} {d['process']:8.2f}")
        c = sum(cold[m][0] for m in METHODS)
        w = sum(warm[m][0] for m in METHODS)
        print(f"first calls, all three methods: compile {c:.1f} s, cache load {w:.2f} s "
              f"({c / max(w, 1e-9):.0f}x)")  # fmt: skip
        if w > 1.0:
            print("    (the warm runs compiled too: engine sources changed during the run, so the "
                  "cache was stale; rerun for the cached figure)")  # fmt: skip
    print(
        f"\nload average at the end (1, 5, 15 min): "
        f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}"
    )
    print(f"total benchmark time {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""What each effect costs, and what the generic stepper costs against a hand-written kernel.

The task: one radial period from r_min for N bounded orbits (integrated to r_max and doubled by
time symmetry; with rolling resistance, which breaks the symmetry, the whole period: that row
does twice the steps) (the survey kernel
``engine.integrated.integrate_points``: apsides located on the dense output, period, apsidal
angle, energy drift; for the Runge-Kutta methods it runs several orbits at once on the SIMD lanes,
``engine.kernels.lanes``). The baseline is a kernel written by hand for exactly the gravity-only
scene: a Dormand-Prince 5(4) loop, one orbit at a time, with the coefficients as literals, the
equations of motion inlined as scalar code, the same error norm, PI controller and event location.
It is compared with the generic scalar run kernel (``engine.kernels.orbit.integrate_points``, the
same one-orbit-at-a-time loop): both take the same accepted steps (checked), and the generic one
takes one more step per apsis to polish it (``rk_events.polish_apsis``: 1 per half period, ~2%
of rk45's steps at rtol 1e-10), so their ratio is the price of the tableau-driven, effect-flagged
code. The effects table times the batch users run.

Each configuration is timed side by side in one process, interleaved, best of ``--repeats`` (one
thread: CPU time of the calling thread, which runs the kernel; more: wall time).

    .venv/bin/python scripts/bench_effects.py [--points 2000] [--repeats 7] [--rtol 1e-10]
        [--threads 1]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from functools import partial
from pathlib import Path

import numba
import numpy as np
from numba import prange

from engine._jit import call_specialized, parallel_kernel
from engine.integrated import integrate_points, points
from engine.kernels.cone import P_COT, P_GC, P_SIN, set_alpha
from engine.kernels.cone_starts import initial_state as generic_initial_state
from engine.kernels.cone_starts import orbit_start, tolerance_scales
from engine.kernels.layouts import ATTITUDE, P_KK
from engine.kernels.model import RIM, ROLLING_RESISTANCE, SLIP_CHECK
from engine.kernels.orbit import integrate_points as scalar_points
from engine.kernels.protocol import EPS, LITERAL, brent_next, brent_start, brent_update
from engine.kernels.rk import ERR_FLOOR, MIN_FACTOR, SAFETY, initial_step
from engine.kernels.tableaux import RK_TABLEAUX
from engine.methods import METHODS
from engine.scene import Scene

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import first_calls, interleaved  # noqa: E402

RK45 = METHODS["rk45"].kernel_id
SCALAR = "generic scalar kernel, gravity"
_DP5 = RK_TABLEAUX[RK45]

# Dormand-Prince 5(4) as literals (Hairer's dopri5).
A21 = 1 / 5
A31, A32 = 3 / 40, 9 / 40
A41, A42, A43 = 44 / 45, -56 / 15, 32 / 9
A51, A52, A53, A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
A61, A62, A63, A64, A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
B1, B3, B4, B5, B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
E1, E3, E4, E5, E6, E7 = -71 / 57600, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40
# Shampine's dense output, rows 0, 2..6 of scipy's P (row 1 is zero).
P0 = (1.0, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432)
P2 = (0.0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799)
P3 = (0.0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072)
P4 = (0.0, 127303824393 / 49829197408, -318862633887 / 49829197408,
      701980252875 / 199316789632)  # fmt: skip
P5 = (0.0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844)
P6 = (0.0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423)
K1, K_REJ, KB, MAX_FACTOR = _DP5.controller()


@numba.njit(inline="always")
def _f(r, u, v, w, s, cot, kk, gc):
    """Equations of motion of the gravity-only scene (inlined into the loop)."""
    ir = 1.0 / r
    kap = cot * ir
    vir = v * ir
    return u, vir / s, v * vir + kk * kap * v * w - gc, -u * vir, -kap * u * v


@numba.njit(inline="always")
def _w(P, x):
    return x * (P[0] + x * (P[1] + x * (P[2] + x * P[3])))


@numba.njit
def _hand_one(p, energy, hh, Lz, rtol, max_steps):
    """One radial period, DP5 written out by hand: to r_max, doubled. Returns (T, psi, steps)."""
    ok, r1, r2, rc = orbit_start(p, energy, hh, Lz)
    if not ok:
        return math.nan, math.nan, 0
    y0 = generic_initial_state(p, 0, r1, energy, hh, Lz)
    y0[2] = 0.0
    sc = tolerance_scales(p, 0, y0, energy, hh, Lz, r1, r2, rc)
    s = p[P_SIN]
    cot = p[P_COT]
    kk = p[P_KK]
    gc = p[P_GC]
    a0 = rtol * sc[0]
    a1 = rtol * sc[1]
    a2 = rtol * sc[2]
    a3 = rtol * sc[3]
    a4 = rtol * sc[4]
    r, th, u, v, w = y0[0], y0[1], y0[2], y0[3], y0[4]
    k1r, k1t, k1u, k1v, k1w = _f(r, u, v, w, s, cot, kk, gc)
    K = np.empty((7, 5))
    K[0, 0] = k1r
    K[0, 1] = k1t
    K[0, 2] = k1u
    K[0, 3] = k1v
    K[0, 4] = k1w
    h = initial_step(RK45, 0, y0, K, p, rtol, rtol * sc, np.empty(5))
    t = 0.0
    g_aps = k1u  # u = 0 at the start: sign of udot
    psi = math.nan
    T = math.nan
    err_old = ERR_FLOOR
    rejected = False
    n = 0
    st = np.empty(8)
    n_try = 0
    while n_try < max_steps:
        n_try += 1
        # stages
        k2r, k2t, k2u, k2v, k2w = _f(r + h * (A21 * k1r), u + h * (A21 * k1u), v + h * (A21 * k1v),
                                     w + h * (A21 * k1w), s, cot, kk, gc)  # fmt: skip
        k3r, k3t, k3u, k3v, k3w = _f(
            r + h * (A31 * k1r + A32 * k2r), u + h * (A31 * k1u + A32 * k2u),
            v + h * (A31 * k1v + A32 * k2v), w + h * (A31 * k1w + A32 * k2w), s, cot, kk, gc,
        )  # fmt: skip
        k4r, k4t, k4u, k4v, k4w = _f(
            r + h * (A41 * k1r + A42 * k2r + A43 * k3r),
            u + h * (A41 * k1u + A42 * k2u + A43 * k3u),
            v + h * (A41 * k1v + A42 * k2v + A43 * k3v),
            w + h * (A41 * k1w + A42 * k2w + A43 * k3w), s, cot, kk, gc,
        )  # fmt: skip
        k5r, k5t, k5u, k5v, k5w = _f(
            r + h * (A51 * k1r + A52 * k2r + A53 * k3r + A54 * k4r),
            u + h * (A51 * k1u + A52 * k2u + A53 * k3u + A54 * k4u),
            v + h * (A51 * k1v + A52 * k2v + A53 * k3v + A54 * k4v),
            w + h * (A51 * k1w + A52 * k2w + A53 * k3w + A54 * k4w), s, cot, kk, gc,
        )  # fmt: skip
        k6r, k6t, k6u, k6v, k6w = _f(
            r + h * (A61 * k1r + A62 * k2r + A63 * k3r + A64 * k4r + A65 * k5r),
            u + h * (A61 * k1u + A62 * k2u + A63 * k3u + A64 * k4u + A65 * k5u),
            v + h * (A61 * k1v + A62 * k2v + A63 * k3v + A64 * k4v + A65 * k5v),
            w + h * (A61 * k1w + A62 * k2w + A63 * k3w + A64 * k4w + A65 * k5w), s, cot, kk, gc,
        )  # fmt: skip
        rn = r + h * (B1 * k1r + B3 * k3r + B4 * k4r + B5 * k5r + B6 * k6r)
        tn = th + h * (B1 * k1t + B3 * k3t + B4 * k4t + B5 * k5t + B6 * k6t)
        un = u + h * (B1 * k1u + B3 * k3u + B4 * k4u + B5 * k5u + B6 * k6u)
        vn = v + h * (B1 * k1v + B3 * k3v + B4 * k4v + B5 * k5v + B6 * k6v)
        wn = w + h * (B1 * k1w + B3 * k3w + B4 * k4w + B5 * k5w + B6 * k6w)
        k7r, k7t, k7u, k7v, k7w = _f(rn, un, vn, wn, s, cot, kk, gc)
        # error
        er = (E1 * k1r + E3 * k3r + E4 * k4r + E5 * k5r + E6 * k6r + E7 * k7r) / (
            a0 + rtol * max(abs(r), abs(rn))
        )
        et = (E1 * k1t + E3 * k3t + E4 * k4t + E5 * k5t + E6 * k6t + E7 * k7t) / (
            a1 + rtol * max(abs(th), abs(tn))
        )
        eu = (E1 * k1u + E3 * k3u + E4 * k4u + E5 * k5u + E6 * k6u + E7 * k7u) / (
            a2 + rtol * max(abs(u), abs(un))
        )
        ev = (E1 * k1v + E3 * k3v + E4 * k4v + E5 * k5v + E6 * k6v + E7 * k7v) / (
            a3 + rtol * max(abs(v), abs(vn))
        )
        ew = (E1 * k1w + E3 * k3w + E4 * k4w + E5 * k5w + E6 * k6w + E7 * k7w) / (
            a4 + rtol * max(abs(w), abs(wn)))  # fmt: skip
        err = abs(h) * math.sqrt((er * er + et * et + eu * eu + ev * ev + ew * ew) / 5.0)
        if not rn > 0.0:
            err = math.inf
        if not err <= 1.0:
            if math.isinf(err) or math.isnan(err):
                h *= MIN_FACTOR
            else:
                h *= max(MIN_FACTOR, SAFETY * err ** (-K_REJ))
            rejected = True
            continue
        if err == 0.0:
            fac = MAX_FACTOR
        else:
            fac = min(MAX_FACTOR, max(MIN_FACTOR, SAFETY * err ** (-K1) * err_old**KB))
        if rejected:
            fac = min(fac, 1.0)
        rejected = False
        err_old = max(err, ERR_FLOOR)
        n += 1
        if (g_aps > 0.0 and un <= 0.0) or (g_aps < 0.0 and un >= 0.0):
            # apsis on the dense output (u component), Brent
            brent_start(st, 0.0, 1.0, u, un)
            x = 1.0
            for _ in range(100):
                done, x = brent_next(st, 4.0 * EPS)
                if done:
                    break
                ux = u + h * (_w(P0, x) * k1u + _w(P2, x) * k3u + _w(P3, x) * k4u
                              + _w(P4, x) * k5u + _w(P5, x) * k6u + _w(P6, x) * k7u)  # fmt: skip
                brent_update(st, ux)
            # r_max: the period is twice the time to it (time symmetry), as the engine's
            # one-period map of a conservative scene takes it
            psi = abs(
                th
                + h
                * (
                    _w(P0, x) * k1t
                    + _w(P2, x) * k3t
                    + _w(P3, x) * k4t
                    + _w(P4, x) * k5t
                    + _w(P5, x) * k6t
                    + _w(P6, x) * k7t
                )
            )
            return 2.0 * (t + x * h), psi, n
        t += h
        r, th, u, v, w = rn, tn, un, vn, wn
        k1r, k1t, k1u, k1v, k1w = k7r, k7t, k7u, k7v, k7w
        h *= fac
    return T, psi, n


@parallel_kernel
def hand_points(alpha, energy, hh, Lz, params, rtol, max_steps, out_f, out_n):
    """The hand-written baseline over all points (prange)."""
    for i in prange(alpha.shape[0]):
        p = params.copy()
        set_alpha(p, alpha[i])
        T, psi, n = _hand_one(p, energy[i], hh[i], Lz[i], rtol, max_steps)
        out_f[0, i] = T
        out_f[1, i] = psi
        out_n[i] = n


def sample_points(n: int, seed: int = 1) -> tuple[np.ndarray, ...]:
    """Bounded orbits under gravity: energy between 1.05 and 4 times V_min above it."""
    import engine

    rng = np.random.default_rng(seed)
    alpha = rng.uniform(0.2, 1.3, n)
    h = rng.uniform(-3.0, 3.0, n)
    Lz = rng.uniform(0.2, 2.0, n) * rng.choice([-1.0, 1.0], n)
    vmin = engine.minimum_energy(alpha, h, Lz, Scene())
    energy = vmin + np.abs(vmin) * rng.uniform(0.05, 3.0, n)
    return alpha, energy, h, Lz


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--threads", type=int, default=1, help="numba threads (1: least noise)")
    ap.add_argument(
        "--tiny", action="store_true", help="a seconds-long smoke run (tests/test_scripts.py)"
    )
    args = ap.parse_args()
    if args.tiny:
        args.points, args.repeats = 40, 1
    numba.set_num_threads(args.threads)
    # One thread: the CPU time of the calling thread (it runs the kernel), robust to the other
    # work of a shared machine; more threads: wall time.
    clock = time.thread_time if args.threads == 1 else time.perf_counter
    alpha, energy, hh, Lz = sample_points(args.points)
    n = alpha.size
    max_steps = 1_000_000
    base = Scene()
    r2 = 1e6
    scenes = {
        "gravity only": (base, "rk45"),
        "+ rolling resistance": (Scene(c_rr=1e-4), "rk45"),
        "+ rim (never reached)": (Scene(rim=r2), "rk45"),
        "+ slip check (never slips)": (Scene(mu=1e6), "rk45"),
        "+ attitude": (Scene(attitude=True), "rk45"),
        "+ all four": (Scene(c_rr=1e-4, rim=r2, mu=1e6, attitude=True), "rk45"),
        "dop853, gravity only": (base, "dop853"),
        "symplectic, gravity only": (base, "symplectic"),
    }

    if args.tiny:  # a smoke run: the comparisons on two configurations (each compiles its own)
        # (the rk45 kernels tests/test_integrated.py and tests/kernels/test_lanes.py compile:
        # gravity only, and a rim and a slip check; on an empty cache the suite's run of this
        # script loads them instead of compiling kernels no test uses)
        scenes = {
            "gravity only": scenes["gravity only"],
            "+ rim, slip check (never)": (Scene(rim=r2, mu=1e6), "rk45"),
        }

    def run_generic(scene, method):
        out_f = np.empty((5, n))
        out_n = np.empty(n, np.int64)
        out_s = np.empty(n, np.int8)
        integrate_points(alpha, energy, hh, Lz, scene.params(), METHODS[method].kernel_id,
                         scene.effects_mask, args.rtol, max_steps, out_f, out_n, out_s)  # fmt: skip
        return out_f, out_n, out_s

    def run_scalar():
        out_f = np.empty((5, n))
        out_n = np.empty(n, np.int64)
        out_s = np.empty(n, np.int8)
        call = (points(alpha, energy, hh, Lz), base.params(), RK45, 0, args.rtol, max_steps,
                out_f, out_n, out_s)  # fmt: skip
        call_specialized(scalar_points, call, LITERAL)
        return out_f, out_n, out_s

    def run_hand():
        out_f = np.empty((2, n))
        out_n = np.empty(n, np.int64)
        hand_points(alpha, energy, hh, Lz, base.params(), args.rtol, max_steps, out_f, out_n)
        return out_f, out_n

    calls = {"hand-written DP5, gravity only": run_hand, SCALAR: run_scalar}
    calls.update({name: partial(run_generic, *sm) for name, sm in scenes.items()})
    first, runs = first_calls(calls)
    hand_f, hand_n = runs["hand-written DP5, gravity only"]
    scal_f, scal_n, scal_s = runs[SCALAR]
    gen_f, gen_n, gen_s = runs["gravity only"]
    assert (gen_s == 0).all() and (scal_s == 0).all(), "generic kernel failed on some points"
    assert np.array_equal(gen_f, scal_f, equal_nan=True), "batch != scalar"
    assert np.array_equal(gen_n, scal_n), "batch != scalar"
    same_steps = np.array_equal(scal_n, hand_n)
    dT = np.nanmax(np.abs(scal_f[0] / hand_f[0] - 1))
    best = {name: t for name, (t,) in interleaved(calls, args.repeats, (clock,)).items()}
    steps = gen_n.mean()
    print(f"{n} bounded orbits, one radial period each, rtol {args.rtol:g}, "
          f"{numba.get_num_threads()} numba thread(s), best of {args.repeats}")  # fmt: skip
    print(f"generic scalar vs hand-written: identical step counts: {same_steps}; "
          f"max |dT/T| = {dT:.1e}; mean accepted steps per orbit {steps:.1f}; the batch gives "
          "the scalar kernel's results bit for bit")  # fmt: skip
    hand = best["hand-written DP5, gravity only"]
    print(f"generic scalar run kernel / hand-written DP5 (gravity only, rk45): "
          f"{best[SCALAR] / hand:.3f}; the batch on the SIMD lanes / hand-written: "
          f"{best['gravity only'] / hand:.3f}\n")  # fmt: skip
    ref = best["gravity only"]
    steps_of = {"hand-written DP5, gravity only": hand_n.mean(), SCALAR: scal_n.mean()}
    steps_of.update({name: runs[name][1].mean() for name in scenes})
    print(f"{'configuration':30s} {'best [ms]':>9s} {'us/orbit':>8s} {'steps':>7s} "
          f"{'ns/step':>7s} {'vs gravity':>10s} {'vs hand':>7s} {'per step vs gravity':>19s} "
          f"{'first call [s]':>14s}")  # fmt: skip
    ref_step = ref / steps_of["gravity only"]
    for name in best:
        t = best[name]
        st = steps_of[name]
        print(f"{name:30s} {1e3 * t:9.2f} {1e6 * t / n:8.2f} {st:7.1f} {1e9 * t / n / st:7.1f} "
              f"{t / ref:10.3f} {t / hand:7.3f} {t / st / ref_step:19.3f} "
              f"{first[name]:14.2f}")  # fmt: skip
    _ = (ATTITUDE, RIM, ROLLING_RESISTANCE, SLIP_CHECK)


if __name__ == "__main__":
    main()

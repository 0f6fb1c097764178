"""Work-precision study: accuracy against cost of the integrator methods and the closed form.

    .venv/bin/python scripts/work_precision.py                 # full study (minutes on 2 cores)
    .venv/bin/python scripts/work_precision.py --quick         # reduced sets (< 1 min)
    .venv/bin/python scripts/work_precision.py --part peers --out docs/figures

Writes into ``--out`` (default: the working directory): ``work_precision.nc`` and
``work_precision.png`` (parts 1 and 2), ``work_precision_peers.nc`` and
``work_precision_peers.png`` (part 3). A first run compiles the kernels of every method
(minutes on a busy machine; announced on stderr); ``--tiny`` is then a seconds-long smoke run.

Part 1, work-precision. A fixed set of about 50 bounded orbits: typical random orbits under
gravity and in free fall, plus the hard cases (alpha = 1e-3 and pi/2 - 1e-3, L_z = 1e-7, energy
1e-10 |V_min| above V_min, free fall with eccentricity 0.999, |h| = 40 with both signs of h L_z,
M = 1e-3 and 1e3, k = 0 and 2/3), one ``engine.Scene`` per (M, g, k). For each integrator
method (rk45, dop853, symplectic) and rtol = 1e-3 ... 1e-13 (each decade) ``engine.evaluate``
gives the radial period, the apsidal angle, the precession rate, the accepted steps and the
energy drift of every orbit; their relative errors are taken against the closed form
(method "exact"). The closed form itself is checked against the mpmath oracle
(``tests/oracle.py``, 60 digits, with condition numbers) on a subset. Cost per orbit: wall time
(best of 3, 1 and 2 numba threads) of ``engine.evaluation.evaluate_flat`` (the path of
``engine.evaluate`` without the xarray assembly) over the whole set, and right-hand-side
evaluations (stages x steps, see the file's attributes).

Part 2, near the class boundaries. The integrator path does NOT classify by itself:
``engine.evaluate(method=...)`` takes the class from the closed form and integrates only the
points it calls bounded (or spills), and ``engine.integrated.evaluate_integrated`` starts each
orbit at r_min from the closed-form turning points and only checks afterwards that the run met
an apocentre and then a pericentre. This script therefore measures (a) the integrator gate
itself on a slice across the forbidden boundary (gravity, energy from V_min - |V_min| to
V_min + |V_min|): does ``evaluate_integrated`` return status ok exactly where the closed form
says bounded?, (b) a class decided by integration on a slice across the bounded/hyperbolic
boundary in free fall (energy from -|V_min| to +|V_min|, e^2 = 1 + energy/|V_min|): the orbit
is integrated from r_min with ``engine.simulate`` for a time budget of 1.5 closed-form radial
periods (of the orbit, or for an escape of its mirror image energy -> -energy) and called
bounded when it met an apocentre and came back to a pericentre, and (c) how the errors of
period and apsidal angle grow as the energy approaches the boundaries (e -> 1 in free fall,
energy -> V_min under gravity).

Part 3, the peers (``--part peers``): the same orbits for conesurvey's integrators, scipy's
``solve_ivp`` (DOP853 and RK45) and heyoka's Taylor integrator (a Python loop over the orbits,
as a user would call it; ``scripts/integrator_peers.py``, the integrator benchmark's task:
typical bounded orbits under gravity, r_min to r_max, the apsidal angle against the closed
form), at a ladder of tolerances: the largest apsidal-angle error against the CPU time per
orbit (one thread; conesurvey through ``engine.integrated.evaluate_integrated``, the path of
its maps). heyoka is optional: without it, its line is left out and the script says so.

Writes a netCDF file (dims method, rtol, orbit, threads and the slices' axes; CF-style
units/long_name; select a method with ``ds.sel({"method": "rk45"})``, since ``sel(method=...)``
is xarray's inexact-match keyword) and a log-log PNG (apsidal-angle error against time per
orbit and against RHS evaluations, with the closed form as a point; error growth towards the two
class boundaries), prints a table and a reading. mpmath and matplotlib are imported here
only (benchmark extras).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import textwrap
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np
import xarray as xr
from bench_common import spin
from figure_cli import TINY_HELP, add_out

import engine
from engine.evaluation import evaluate_flat
from engine.integrated import evaluate_integrated
from engine.kernels.geometry import BOUNDED, CIRCULAR, CLASS_NAMES, HYPERBOLIC
from engine.plan import map_plan

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("rk45", "dop853", "symplectic")
RTOLS_FULL = tuple(10.0**-j for j in range(3, 14))  # 1e-3 ... 1e-13
RTOLS_QUICK = (1e-3, 1e-6, 1e-9, 1e-12)
RTOLS_TINY = (1e-3, 1e-9)  # --tiny: every part of the study runs, on two tolerances, timed once
#: Right-hand-side (force) evaluations per step of each method.
STAGES = {"rk45": 6, "dop853": 12, "symplectic": 7}
EVAL_NOTE = (
    "rhs_evaluations = stages x (accepted + rejected steps); stages per step: rk45 6 "
    "(Dormand-Prince 5(4), 7 stages, first same as last), dop853 12 (Dormand-Prince 8(5,3), "
    "12 stages with first same as last), symplectic 7 (6th-order Yoshida composition of 7 "
    "time-transformed leapfrog substeps, one force evaluation V'(r) with the time-transform "
    "rate Omega(r) each). Accepted steps: the Dataset's n_steps; rejected steps: "
    "engine.simulate(periods=1) of the same orbit (n_rejected attribute; the symplectic method "
    "has a fixed step and rejects nothing). Not counted: the start-up evaluations (rk: f(y0) "
    "and one for the initial step), the 3 extra dense-output stages dop853 computes in each of "
    "the 2 steps that contain an apsis, and the partial steps the symplectic method re-takes "
    "to locate the 2 apsides (Brent, about 10 composed steps each)"
)
TIME_NOTE = (
    "wall time of engine.evaluation.evaluate_flat (engine.evaluate without the xarray assembly: "
    "closed-form classification, then the integrator batch kernel with numba prange over "
    "points) on the whole orbit set, one call per scene, repeated so that one timing lasts "
    ">= {target} s, best of {repeats}, divided by the number of orbits integrated; numba "
    "threads set with numba.set_num_threads"
)
FLOOR = 1e-17  # errors below this are drawn at it (exact zeros on a log axis)


# ---------------------------------------------------------------------------------- orbit set
def _scene(M: float, g: float, k: float) -> engine.Scene:
    return engine.Scene(M=M, g=g, k=k)


def _vmin(alpha, h, Lz, M, g, k) -> np.ndarray:
    return np.asarray(engine.minimum_energy(alpha, h, Lz, _scene(M, g, k)), float)


def orbit_set(n_gravity: int, n_free: int, seed: int = 20240611) -> dict[str, np.ndarray]:
    """The fixed orbit set: ``n_gravity`` + ``n_free`` typical random orbits and the hard cases.

    Typical under gravity (M = 1, g = 9.81, k = 0.4): alpha uniform in [10, 80] deg, h uniform
    in [-3, 3] m/s, L_z log-uniform in [0.05, 3] kg m2/s with random sign, energy offset
    (calE - V_min)/|V_min| log-uniform in [1e-4, 10]. Typical in free fall (g = 0): alpha as
    above, h uniform in [0.3, 3] m/s, L_z = -log-uniform [0.05, 3] (h L_z < 0, so bounded orbits
    exist), eccentricity uniform in [0.05, 0.9], calE = V_min (1 - e^2).
    """
    rng = np.random.default_rng(seed)
    rows: list[tuple] = []  # (name, kind, alpha, energy, h, Lz, M, g, k)

    def offset_row(name, kind, alpha, h, Lz, off, M=1.0, g=9.81, k=0.4):
        vmin = float(_vmin(alpha, h, Lz, M, g, k))
        rows.append((name, kind, alpha, vmin + off * abs(vmin), h, Lz, M, g, k))

    def ecc_row(name, kind, alpha, h, Lz, e, M=1.0, k=0.4):
        vmin = float(_vmin(alpha, h, Lz, M, 0.0, k))
        rows.append((name, kind, alpha, vmin * (1.0 - e * e), h, Lz, M, 0.0, k))

    i = 0
    while sum(r[1] == "typical" for r in rows) < n_gravity:
        alpha = math.radians(rng.uniform(10.0, 80.0))
        h = rng.uniform(-3.0, 3.0)
        Lz = math.exp(rng.uniform(math.log(0.05), math.log(3.0))) * rng.choice([-1.0, 1.0])
        off = math.exp(rng.uniform(math.log(1e-4), math.log(10.0)))
        offset_row(f"gravity_{i:02d}", "typical", alpha, h, Lz, off)
        i += 1
    for j in range(n_free):
        alpha = math.radians(rng.uniform(10.0, 80.0))
        h = rng.uniform(0.3, 3.0)
        Lz = -math.exp(rng.uniform(math.log(0.05), math.log(3.0)))
        ecc_row(f"free_fall_{j:02d}", "typical", alpha, h, Lz, rng.uniform(0.05, 0.9))
    hard = "hard"
    offset_row("alpha=1e-3", hard, 1e-3, 1.0, 0.5, 0.3)
    offset_row("alpha=pi/2-1e-3", hard, math.pi / 2 - 1e-3, 1.0, 0.5, 0.3)
    offset_row("Lz=1e-7", hard, 0.6, 1.0, 1e-7, 0.3)
    offset_row("energy=V_min+1e-10|V_min|", hard, 0.6, 1.0, 0.5, 1e-10)
    offset_row("energy=V_min+1e-10|V_min|, alpha=1e-3", hard, 1e-3, -1.0, 0.5, 1e-10)
    ecc_row("free fall e=0.999", hard, 0.6, 1.0, -0.5, 0.999)
    ecc_row("free fall e=0.999, h=-40", hard, 1.2, -40.0, 0.3, 0.999)
    offset_row("h=40, hLz>0", hard, 0.6, 40.0, 0.5, 0.3)
    offset_row("h=-40, hLz<0", hard, 0.6, -40.0, 0.5, 0.3)
    offset_row("M=1e-3", hard, 0.6, 1.0, 0.5e-3, 0.3, M=1e-3)
    offset_row("M=1e3", hard, 0.6, 1.0, 0.5e3, 0.3, M=1e3)
    offset_row("k=0 (point particle)", hard, 0.6, 1.0, 0.5, 0.3, k=0.0)
    offset_row("k=2/3 (shell)", hard, 0.6, 1.0, 0.5, 0.3, k=2.0 / 3.0)
    names = ("name", "kind", "alpha", "energy", "h", "Lz", "M", "g", "k")
    out = {n: np.array([r[j] for r in rows]) for j, n in enumerate(names)}
    for n in names[2:]:
        out[n] = out[n].astype(np.float64)
    return out


def scene_groups(orbits: dict[str, np.ndarray]) -> list[tuple[engine.Scene, np.ndarray]]:
    """(scene, indices) per distinct (M, g, k) of the orbit set."""
    keys = list(zip(orbits["M"], orbits["g"], orbits["k"], strict=True))
    groups = []
    for key in dict.fromkeys(keys):
        idx = np.array([i for i, kk in enumerate(keys) if kk == key])
        groups.append((_scene(*key), idx))
    return groups


def evaluate_set(orbits, groups, method: str, rtol: float = 1e-10) -> dict[str, np.ndarray]:
    """engine.evaluate on every scene group, gathered back into orbit order."""
    n = orbits["alpha"].size
    out: dict[str, np.ndarray] = {}
    for scene, idx in groups:
        ds = engine.evaluate(
            orbits["alpha"][idx],
            orbits["energy"][idx],
            orbits["h"][idx],
            orbits["Lz"][idx],
            scene,
            method=method,
            rtol=rtol,
        )
        for name, var in ds.data_vars.items():
            if name not in out:
                out[name] = np.zeros(n, var.dtype) if var.dtype.kind in "iu" else np.full(n, np.nan)
            out[name][idx] = var.values
    return out


def rejected_steps(orbits, method: str, rtol: float) -> tuple[np.ndarray, np.ndarray]:
    """(accepted, rejected) steps of one radial period per orbit from engine.simulate."""
    from engine.simulate import simulate  # (engine.simulate is shadowed by the submodule)

    n = orbits["alpha"].size
    acc = np.full(n, -1, np.int64)
    rej = np.full(n, -1, np.int64)
    for i in range(n):
        args = [orbits[k][i] for k in ("alpha", "energy", "h", "Lz")]
        scene = _scene(orbits["M"][i], orbits["g"][i], orbits["k"][i])
        try:
            ds = simulate(*args, scene, periods=1, method=method, rtol=rtol, dt_out=1e300)
        except (RuntimeError, ValueError):
            continue
        acc[i] = ds.attrs["n_steps"]
        rej[i] = ds.attrs["n_rejected"]
    return acc, rej


# ------------------------------------------------------------------------------------- timing
def best_time(fn: Callable[[], object], repeats: int) -> float:
    """Smallest wall time [s] of ``repeats`` calls of ``fn``."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def batch_timer(orbits, groups, method: str, rtol: float, tile: int) -> Callable[[], None]:
    """A call that evaluates the orbit set ``tile`` times over (one evaluate_flat per scene)."""
    batches = []
    for scene, idx in groups:
        arrs = [np.ascontiguousarray(np.tile(orbits[k][idx], tile)) for k in ("alpha", "energy")]
        arrs += [np.ascontiguousarray(np.tile(orbits[k][idx], tile)) for k in ("h", "Lz")]
        batches.append((arrs, scene))

    def run() -> None:
        for arrs, scene in batches:
            evaluate_flat(*arrs, map_plan(scene, method, rtol=rtol))

    return run


def time_per_orbit(orbits, groups, method, rtol, threads, repeats, target) -> dict[int, float]:
    """Best-of-``repeats`` wall time per orbit [s] for each thread count (the thread counts
    alternate call by call, so a change of machine load hits them alike)."""
    n = orbits["alpha"].size
    numba.set_num_threads(threads[-1])
    once = batch_timer(orbits, groups, method, rtol, 1)
    once()  # compile / load and warm the pool
    t1 = best_time(once, 2)
    tile = int(min(2000, max(1, math.ceil(target / max(t1, 1e-7)))))
    run = batch_timer(orbits, groups, method, rtol, tile) if tile > 1 else once
    best = dict.fromkeys(threads, math.inf)
    for _ in range(repeats):
        for nt in threads:
            numba.set_num_threads(nt)
            t0 = time.perf_counter()
            run()
            best[nt] = min(best[nt], time.perf_counter() - t0)
    numba.set_num_threads(threads[-1])
    return {nt: t / (n * tile) for nt, t in best.items()}


def reference_speedup(threads: list[int]) -> float:
    """Speedup of :func:`bench_common.spin` on the most threads (about 2 on two free cores)."""
    t = {}
    for nt in threads:
        numba.set_num_threads(nt)
        spin(64, 20_000)
        t[nt] = best_time(lambda: spin(64, 20_000), 3)
    numba.set_num_threads(threads[-1])
    return t[threads[0]] / t[threads[-1]]


def single_orbit_times(orbits, method, rtol, repeats) -> np.ndarray:
    """Wall time [s] of ``engine.integrated.evaluate_integrated`` on each orbit alone (1 thread,
    best of ``repeats``; includes the per-call overhead, some 10 us)."""
    numba.set_num_threads(1)
    n = orbits["alpha"].size
    out = np.full(n, np.nan)
    for i in range(n):
        args = [orbits[k][i : i + 1].copy() for k in ("alpha", "energy", "h", "Lz")]
        scene = _scene(orbits["M"][i], orbits["g"][i], orbits["k"][i])

        def run(args=args, scene=scene) -> None:
            evaluate_integrated(*args, scene, method, rtol)

        run()
        out[i] = best_time(run, repeats)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return out


# ------------------------------------------------------------------------------------- oracle
def oracle_errors(orbits, exact, subset: np.ndarray) -> dict[str, np.ndarray]:
    """Relative error of the closed form against the mpmath oracle on ``subset`` (NaN elsewhere),
    with the oracle's condition numbers."""
    sys.path.insert(0, str(ROOT / "tests"))
    from oracle import reference

    n = orbits["alpha"].size
    keys = {"period": "T_r", "apsidal_angle": "psi", "precession_rate": "precession_rate"}
    out = {f"{p}_{v}": np.full(n, np.nan) for v in keys for p in ("err", "cond")}
    out["oracle_seconds"] = np.full(n, np.nan)
    for i in subset:
        t0 = time.perf_counter()
        cls, vals, cond = reference(
            *(float(orbits[k][i]) for k in ("alpha", "energy", "h", "Lz", "M", "g", "k"))
        )
        out["oracle_seconds"][i] = time.perf_counter() - t0
        if cls not in ("bounded", "circular"):
            continue
        for var, key in keys.items():
            ref = vals[key]
            out[f"err_{var}"][i] = abs(exact[var][i] / ref - 1.0) if ref != 0 else np.nan
            out[f"cond_{var}"][i] = cond.get(key, np.nan)
    return out


# ------------------------------------------------------------------------- boundary slices
def gravity_slice(alphas, offsets, h=1.0, Lz=0.5, M=1.0, g=9.81, k=0.4):
    """Points (alpha, energy = V_min + offset |V_min|) across the forbidden boundary."""
    A, X = np.meshgrid(alphas, offsets, indexing="ij")
    vmin = _vmin(A, h, Lz, M, g, k)
    E = vmin + X * np.abs(vmin)
    return A, E, vmin


def free_fall_slice(alphas, xs, h=1.0, Lz=-0.5, M=1.0, k=0.4):
    """Points (alpha, energy = x |V_min|) across the bounded/hyperbolic boundary (g = 0)."""
    A, X = np.meshgrid(alphas, xs, indexing="ij")
    vmin = _vmin(A, h, Lz, M, 0.0, k)
    return A, X * np.abs(vmin), vmin


def gate_study(A, E, h, Lz, scene, methods, rtols, exact):
    """Status of evaluate_integrated on every slice point (no closed-form gating before it)
    and the relative errors of period and apsidal angle against the closed form."""
    shape = (len(methods), len(rtols), *A.shape)
    status = np.zeros(shape, np.int8)
    err_T = np.full(shape, np.nan)
    err_psi = np.full(shape, np.nan)
    a, e = A.reshape(-1), E.reshape(-1)
    hh, lz = np.full(a.size, h), np.full(a.size, Lz)
    for im, m in enumerate(methods):
        for ir, r in enumerate(rtols):
            res = evaluate_integrated(a, e, hh, lz, scene, m, r)
            status[im, ir] = res["status"].reshape(A.shape)
            with np.errstate(invalid="ignore", divide="ignore"):
                err_T[im, ir] = np.abs(res["period"].reshape(A.shape) / exact["period"] - 1.0)
                err_psi[im, ir] = np.abs(
                    res["apsidal_angle"].reshape(A.shape) / exact["apsidal_angle"] - 1.0
                )
    return status, err_T, err_psi


def integrated_class(alpha, energy, h, Lz, scene, method, rtol, budget) -> int:
    """Class decided by integration: BOUNDED if the orbit, started at r_min, meets an apocentre
    and then a pericentre within ``budget`` seconds; HYPERBOLIC if not; -1 if the run fails or
    cannot start."""
    from engine.simulate import simulate

    try:
        ds = simulate(
            alpha,
            energy,
            h,
            Lz,
            scene,
            t_end=budget,
            method=method,
            rtol=rtol,
            dt_out=budget,
            max_steps=200_000,
        )
    except (RuntimeError, ValueError):
        return -1
    kinds = list(ds.event_kind.values)
    for j in range(len(kinds) - 1):
        if kinds[j] == 1 and kinds[j + 1] == 0:
            return BOUNDED
    return HYPERBOLIC


def free_fall_study(A, E, h, Lz, scene, methods, rtols, exact, budget):
    """Integration-decided class on the free-fall slice, and period / apsidal-angle errors of
    engine.evaluate on its bounded points."""
    shape = (len(methods), len(rtols), *A.shape)
    cls = np.full(shape, -1, np.int8)
    status = np.zeros(shape, np.int8)
    err_T = np.full(shape, np.nan)
    err_psi = np.full(shape, np.nan)
    for im, m in enumerate(methods):
        for ir, r in enumerate(rtols):
            for idx in np.ndindex(A.shape):
                cls[(im, ir, *idx)] = integrated_class(
                    float(A[idx]), float(E[idx]), h, Lz, scene, m, r, float(budget[idx])
                )
            ds = engine.evaluate(A, E, h, Lz, scene, method=m, rtol=r)
            status[im, ir] = ds.status.values
            with np.errstate(invalid="ignore", divide="ignore"):
                err_T[im, ir] = np.abs(ds.period.values / exact["period"] - 1.0)
                err_psi[im, ir] = np.abs(ds.apsidal_angle.values / exact["apsidal_angle"] - 1.0)
    return cls, status, err_T, err_psi


# ------------------------------------------------------------------------------------- output
def attrs(units: str, long_name: str, **extra) -> dict:
    return {"units": units, "long_name": long_name, **extra}


def machine_info() -> dict[str, str]:
    import scipy

    load = ", ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return {
        "machine": f"{platform.platform()}, {platform.machine()}, cpu_count={os.cpu_count()}",
        "versions": (
            f"python {platform.python_version()}, numba {numba.__version__}, numpy "
            f"{np.__version__}, xarray {xr.__version__}, scipy {scipy.__version__}, "
            f"conesurvey {engine.__version__}"
        ),
        "load_average_at_start": load,
    }


def plot(ds: xr.Dataset, png: Path) -> None:
    """Four log-log panels: apsidal-angle error against time per orbit and against RHS
    evaluations (work-precision), and against the distance to the two class boundaries."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = {"rk45": "tab:blue", "dop853": "tab:orange", "symplectic": "tab:green"}
    fig, axes = plt.subplots(2, 2, figsize=(15, 13))
    (ax, ex), (gx, fx) = axes
    t1 = ds.time_per_orbit.sel(threads=1)
    for m in ds.method.values:
        sel = {"method": m}
        err = ds.rel_error_apsidal_angle.sel(sel)
        med = np.maximum(err.median("orbit").values, FLOOR)
        mx = np.maximum(err.max("orbit").values, FLOOR)
        c = colors.get(str(m))
        for axis, x in ((ax, t1.sel(sel).values),
                        (ex, ds.rhs_evaluations.sel(sel).median("orbit").values)):  # fmt: skip
            axis.loglog(x, med, "o-", color=c, label=f"{m}: median over orbits")
            axis.loglog(x, mx, "s--", color=c, mfc="none", label=f"{m}: max over orbits")
            for j in (0, ds.rtol.size - 1):
                axis.annotate(f"rtol {float(ds.rtol[j]):.0e}", (x[j], mx[j]), fontsize=7,
                              color=c, textcoords="offset points", xytext=(4, 4))  # fmt: skip
    te = float(ds.exact_time_per_orbit.sel(threads=1))
    em = ds.exact_rel_error_apsidal_angle_vs_oracle
    ax.loglog([te], [max(float(em.median()), FLOOR)], "*", ms=16, color="k",
              label="closed form (exact) vs mpmath oracle: median")  # fmt: skip
    ax.loglog([te], [max(float(em.max()), FLOOR)], "*", ms=24, mfc="none", color="k",
              label="closed form vs oracle: max")  # fmt: skip
    ax.set_xlabel("wall time per orbit [s] (1 thread; one radial period per orbit)")
    ax.set_title(f"(a) work-precision: {ds.orbit.size} bounded orbits incl. hard cases")
    ex.set_xlabel("right-hand-side evaluations per orbit [1] (median over orbits)")
    ex.set_title("(b) the same against RHS evaluations (independent of machine load)")
    for axis in (ax, ex):
        axis.set_ylabel("relative error of the apsidal angle [1]")
        axis.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, loc="center left")

    # error growth near the class boundaries, at three tolerances
    want = (1e-6, 1e-10, 1e-13)
    irs = sorted({int(np.argmin(np.abs(np.log(ds.rtol.values / w)))) for w in want})
    styles = ["-", "--", ":"]
    goff = ds.gr_offset.values
    keep = goff > float(ds.attrs.get("circular_tol", 1e-12))  # above the circular band
    xff = ds.ff_x.values
    kff = xff < 0
    for m in ds.method.values:
        c = colors.get(str(m))
        sel = {"method": m}
        for k, ir in enumerate(irs):
            rt = float(ds.rtol[ir])
            ls = styles[k % len(styles)]
            eg = ds.gr_rel_error_apsidal_angle.sel(sel).isel(rtol=ir).max("gr_alpha").values
            gx.loglog(goff[keep], np.maximum(eg[keep], FLOOR), ls, marker="o", ms=3, color=c,
                      label=f"{m}, rtol {rt:.0e}")  # fmt: skip
            ef = ds.ff_rel_error_apsidal_angle.sel(sel).isel(rtol=ir).max("ff_alpha").values
            fx.loglog(-xff[kff], np.maximum(ef[kff], FLOOR), ls, marker="^", ms=3, color=c,
                      label=f"{m}, rtol {rt:.0e}")  # fmt: skip
            failed = (ds.ff_status.sel(sel).isel(rtol=ir) != 0).any("ff_alpha").values & kff
            if failed.any():
                fx.loglog(-xff[failed], np.full(int(failed.sum()), 10.0**k),
                          "x", ms=7, color=c)  # fmt: skip
    gx.set_xlabel("energy above the potential minimum, (calE - V_min)/|V_min| [1]")
    gx.set_title("(c) gravity: calE -> V_min (forbidden boundary)")
    fx.set_xlabel("energy below the escape energy, -calE/|V_min| = 1 - e^2 [1] (free fall)")
    fx.set_title("(d) free fall: e -> 1 (hyperbolic boundary)\n"
                 "x at the top: integration failed (status != 0), one row per rtol")  # fmt: skip
    for axis in (gx, fx):
        axis.set_ylabel("relative error of the apsidal angle [1] (max over alpha)")
        axis.grid(True, which="major", alpha=0.3)
    fx.legend(*gx.get_legend_handles_labels(), fontsize=8, loc="center", ncol=3,
              bbox_to_anchor=(0.5, 0.6), title="colour: method; line style: rtol")  # fmt: skip
    fig.tight_layout()
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=110, bbox_inches="tight")
    plt.close(fig)


def q(x: np.ndarray, fn) -> float:
    """fn over the finite values of x (NaN if none)."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(fn(x)) if x.size else math.nan


# ------------------------------------------------------------------------------------ the runs
def run_integrators(orbits, groups, exact, rtols, threads, repeats, target) -> dict:
    """Part 1: every method x rtol on the orbit set."""
    n = orbits["alpha"].size
    shape = (len(METHODS), len(rtols), n)
    R = {k: np.full(shape, np.nan) for k in ("err_T", "err_psi", "err_prec", "drift", "t_single")}
    R["n_steps"] = np.zeros(shape, np.int64)
    R["n_rej"] = np.full(shape, -1, np.int64)
    R["status"] = np.zeros(shape, np.int8)
    R["tpo"] = np.full((len(METHODS), len(rtols), len(threads)), np.nan)
    for im, m in enumerate(METHODS):
        for ir, r in enumerate(rtols):
            res = evaluate_set(orbits, groups, m, r)
            R["err_T"][im, ir] = np.abs(res["period"] / exact["period"] - 1.0)
            R["err_psi"][im, ir] = np.abs(res["apsidal_angle"] / exact["apsidal_angle"] - 1.0)
            R["err_prec"][im, ir] = np.abs(res["precession_rate"] / exact["precession_rate"] - 1)
            R["drift"][im, ir] = res["energy_drift"]
            R["n_steps"][im, ir] = res["n_steps"]
            R["status"][im, ir] = res["status"]
            acc, rej = rejected_steps(orbits, m, r)
            R["n_rej"][im, ir] = np.where(acc == res["n_steps"], rej, -1)
            tt = time_per_orbit(orbits, groups, m, r, threads, repeats, target)
            R["tpo"][im, ir] = [tt[t] for t in threads]
            R["t_single"][im, ir] = single_orbit_times(orbits, m, r, repeats)
    steps = np.where(R["n_rej"] >= 0, R["n_steps"] + np.maximum(R["n_rej"], 0), R["n_steps"])
    R["rhs"] = steps * np.array([STAGES[m] for m in METHODS])[:, None, None]
    if len(threads) > 1:
        R["eff"] = R["tpo"][:, :, 0] / (threads[-1] * R["tpo"][:, :, -1])
    else:
        R["eff"] = np.full(R["tpo"].shape[:2], np.nan)
    return R


def run_boundaries(quick: bool, rtols) -> dict:
    """Part 2: the gravity slice (integrator gate) and the free-fall slice (class by
    integration), with the period / apsidal-angle errors on both."""
    if quick:
        g_alpha = np.array([0.3, 1.0])
        g_off = np.concatenate([-np.geomspace(1.0, 1e-14, 8), np.geomspace(1e-14, 1.0, 8)])
        f_alpha = np.array([0.4, 1.1])
        f_x = np.concatenate([-np.geomspace(0.9, 1e-10, 6), np.geomspace(1e-10, 1.0, 6)])
    else:
        g_alpha = np.array([0.1, 0.4, 0.8, 1.2, 1.5])
        g_off = np.concatenate([-np.geomspace(1.0, 1e-14, 15), np.geomspace(1e-14, 1.0, 29)])
        f_alpha = np.array([0.2, 0.6, 1.0, 1.4])
        f_x = np.concatenate([-np.geomspace(0.9, 1e-10, 21), np.geomspace(1e-10, 1.0, 11)])
    B = {"g_alpha": g_alpha, "g_off": g_off, "f_alpha": f_alpha, "f_x": f_x}
    B["g_h"], B["g_Lz"], B["f_h"], B["f_Lz"] = 1.0, 0.5, 1.0, -0.5
    gscene = _scene(1.0, 9.81, 0.4)
    GA, GE, _ = gravity_slice(g_alpha, g_off, B["g_h"], B["g_Lz"])
    gex = engine.evaluate(GA, GE, B["g_h"], B["g_Lz"], gscene)
    B["g_cls"] = gex.orbit_class.values
    g_exact = {"period": gex.period.values, "apsidal_angle": gex.apsidal_angle.values}
    B["g_status"], B["g_eT"], B["g_epsi"] = gate_study(
        GA, GE, B["g_h"], B["g_Lz"], gscene, METHODS, rtols, g_exact
    )
    fscene = _scene(1.0, 0.0, 0.4)
    FA, FE, _ = free_fall_slice(f_alpha, f_x, B["f_h"], B["f_Lz"])
    fex = engine.evaluate(FA, FE, B["f_h"], B["f_Lz"], fscene)
    f_cls = B["f_cls"] = fex.orbit_class.values
    f_exact = {"period": fex.period.values, "apsidal_angle": fex.apsidal_angle.values}
    mirror = engine.evaluate(FA, -np.abs(FE), B["f_h"], B["f_Lz"], fscene).period.values
    B["budget"] = 1.5 * np.where(f_cls == BOUNDED, fex.period.values, mirror)
    B["f_icls"], B["f_status"], B["f_eT"], B["f_epsi"] = free_fall_study(
        FA, FE, B["f_h"], B["f_Lz"], fscene, METHODS, rtols, f_exact, B["budget"]
    )
    # summary fractions (method, rtol)
    band = B["g_cls"] == CIRCULAR  # the circular band: a convention, left out
    mism = ((B["g_status"] == 0) != (B["g_cls"] == BOUNDED)) & ~band
    B["g_frac"] = mism.sum(axis=(2, 3)) / max(1, int((~band).sum()))
    icls = B["f_icls"]
    known = np.isin(f_cls, (BOUNDED, HYPERBOLIC))
    nk = max(1, int(known.sum()))
    B["f_frac"] = ((icls != f_cls) & known).sum(axis=(2, 3)) / nk
    B["f_b2h_mask"] = (f_cls == BOUNDED) & (icls == HYPERBOLIC)
    B["f_h2b_mask"] = (f_cls == HYPERBOLIC) & (icls == BOUNDED)
    B["f_fail_mask"] = known & (icls < 0)
    B["f_evfail_mask"] = (f_cls == BOUNDED) & (B["f_status"] != 0)
    for key in ("b2h", "h2b", "fail"):
        B[f"f_{key}"] = B[f"f_{key}_mask"].sum(axis=(2, 3)) / nk
    B["f_evfail"] = B["f_evfail_mask"].sum(axis=(2, 3)) / max(1, int((f_cls == BOUNDED).sum()))
    return B


# ------------------------------------------------------------------------------------ dataset
def build_dataset(orbits, rtols, threads, R, exact, tex, orc, B, meta) -> xr.Dataset:
    """Everything in one CF-style Dataset."""
    data: dict[str, tuple] = {}

    def add(name, dims, values, units, long_name, **extra):
        data[name] = (dims, values, attrs(units, long_name, **extra))

    D3 = ("method", "rtol", "orbit")
    MR = ("method", "rtol")
    GS = ("method", "rtol", "gr_alpha", "gr_offset")
    FS = ("method", "rtol", "ff_alpha", "ff_x")
    vs = "against the closed form"
    add("rel_error_apsidal_angle", D3, R["err_psi"], "1", f"relative error of psi {vs}")
    add("rel_error_period", D3, R["err_T"], "1", f"relative error of the radial period {vs}")
    add("rel_error_precession_rate", D3, R["err_prec"], "1",
        f"relative error of the precession rate {vs}")  # fmt: skip
    add(
        "energy_drift",
        D3,
        R["drift"],
        "1",
        "relative change of the total energy over one radial period (engine energy_drift)",
    )
    add("n_steps", D3, R["n_steps"], "1", "accepted steps over one radial period")
    add(
        "n_rejected",
        D3,
        R["n_rej"],
        "1",
        "rejected steps over one radial period (engine.simulate; -1: unavailable)",
    )
    add(
        "rhs_evaluations",
        D3,
        R["rhs"],
        "1",
        "right-hand-side (force) evaluations over one radial period",
        comment=EVAL_NOTE,
    )
    add("status", D3, R["status"], "1", "integrator status code (0 = ok)")
    add(
        "wall_time_single",
        D3,
        R["t_single"],
        "s",
        "wall time of evaluate_integrated on this orbit alone, 1 thread, best of "
        f"{meta['repeats']} (includes the per-call overhead)",
    )
    add(
        "time_per_orbit",
        (*MR, "threads"),
        R["tpo"],
        "s",
        "wall time per orbit over the whole orbit set",
        comment=meta["timing"],
    )
    add(
        "parallel_efficiency",
        MR,
        R["eff"],
        "1",
        "time(1 thread) / (threads x time(threads)) at the highest thread count",
    )
    add(
        "median_rel_error_apsidal_angle",
        MR,
        np.nanmedian(R["err_psi"], axis=2),
        "1",
        "median over orbits of the apsidal-angle relative error",
    )
    add(
        "max_rel_error_apsidal_angle",
        MR,
        np.nanmax(np.where(np.isnan(R["err_psi"]), np.inf, R["err_psi"]), axis=2),
        "1",
        "max over orbits of the apsidal-angle relative error (inf: a failed orbit)",
    )
    add("exact_period", "orbit", exact["period"], "s", "radial period, closed form")
    add(
        "exact_apsidal_angle",
        "orbit",
        exact["apsidal_angle"],
        "radian",
        "apsidal angle, closed form",
    )
    add(
        "exact_precession_rate",
        "orbit",
        exact["precession_rate"],
        "radian s-1",
        "precession rate, closed form",
    )
    add(
        "exact_time_per_orbit",
        "threads",
        [tex[t] for t in threads],
        "s",
        "wall time per orbit of the closed form (method exact)",
        comment=meta["timing"],
    )
    for var in ("period", "apsidal_angle", "precession_rate"):
        label = var.replace("_", " ")
        add(
            f"exact_rel_error_{var}_vs_oracle",
            "orbit",
            orc[f"err_{var}"],
            "1",
            f"relative error of the closed-form {label} against the mpmath oracle (60 digits); "
            "NaN: orbit not in the oracle subset",
        )
        add(
            f"oracle_cond_{var}",
            "orbit",
            orc[f"cond_{var}"],
            "1",
            f"relative condition number of the {label} (oracle)",
        )
    flags = {
        "flag_values": np.arange(len(CLASS_NAMES), dtype=np.int8),
        "flag_meanings": " ".join(CLASS_NAMES),
    }
    add(
        "gr_class_exact",
        ("gr_alpha", "gr_offset"),
        B["g_cls"],
        "1",
        "closed-form class on the gravity slice",
        **flags,
    )
    add(
        "gr_status",
        GS,
        B["g_status"],
        "1",
        "status of evaluate_integrated on the gravity slice (0 ok, 5 not bounded)",
    )
    add(
        "gr_rel_error_period",
        GS,
        B["g_eT"],
        "1",
        "relative error of the integrated radial period, gravity slice",
    )
    add(
        "gr_rel_error_apsidal_angle",
        GS,
        B["g_epsi"],
        "1",
        "relative error of the integrated apsidal angle, gravity slice",
    )
    add(
        "gr_gate_mismatch_fraction",
        MR,
        B["g_frac"],
        "1",
        "fraction of gravity-slice points (circular band left out) where evaluate_integrated's "
        "status ok differs from closed-form class bounded",
    )
    add(
        "ff_class_exact",
        ("ff_alpha", "ff_x"),
        B["f_cls"],
        "1",
        "closed-form class on the free-fall slice",
        **flags,
    )
    add(
        "ff_class_integrated",
        FS,
        B["f_icls"],
        "1",
        "class decided by integration from r_min within the time budget (1 bounded: met an "
        "apocentre then a pericentre; 3 hyperbolic: did not; -1 run failed)",
        flag_values=np.array([-1, 1, 3], np.int8),
        flag_meanings="failed bounded hyperbolic",
    )
    add(
        "ff_time_budget",
        ("ff_alpha", "ff_x"),
        B["budget"],
        "s",
        "integration time budget: 1.5 closed-form radial periods of the orbit (or of its "
        "mirror image calE -> -calE for an escape)",
    )
    add(
        "ff_misclassified_fraction",
        MR,
        B["f_frac"],
        "1",
        "fraction of free-fall slice points whose integration-decided class differs from the "
        "closed-form class (including failed runs)",
    )
    add(
        "ff_bounded_called_hyperbolic_fraction",
        MR,
        B["f_b2h"],
        "1",
        "fraction of free-fall slice points bounded in closed form that the integration did "
        "not bring back to r_min within the budget",
    )
    add(
        "ff_hyperbolic_called_bounded_fraction",
        MR,
        B["f_h2b"],
        "1",
        "fraction of free-fall slice points hyperbolic in closed form that the integration "
        "brought back to r_min",
    )
    add(
        "ff_failed_fraction",
        MR,
        B["f_fail"],
        "1",
        "fraction of free-fall slice points whose budget run failed (engine.simulate raised: "
        "step size underflow, non-finite state, step budget)",
    )
    add(
        "ff_status",
        FS,
        B["f_status"],
        "1",
        "status of engine.evaluate(method) on the free-fall slice (0 ok, 3 max steps, 4 step "
        "size below 16 eps t, 6 non-finite; 0 also where not integrated: off the bounded points)",
    )
    add(
        "ff_evaluate_failed_fraction",
        MR,
        B["f_evfail"],
        "1",
        "fraction of the bounded free-fall slice points where engine.evaluate(method) returned "
        "a nonzero status (period and apsidal angle NaN)",
    )
    add(
        "ff_rel_error_period",
        FS,
        B["f_eT"],
        "1",
        "relative error of the integrated radial period, free-fall slice",
    )
    add(
        "ff_rel_error_apsidal_angle",
        FS,
        B["f_epsi"],
        "1",
        "relative error of the integrated apsidal angle, free-fall slice",
    )
    o = orbits
    coords = {
        "method": ("method", np.array(METHODS), {"long_name": "integration method"}),
        "rtol": ("rtol", np.array(rtols), attrs("1", "relative tolerance")),
        "orbit": ("orbit", np.arange(o["alpha"].size), {"long_name": "orbit index"}),
        "orbit_name": ("orbit", o["name"].astype(str), {"long_name": "orbit label"}),
        "orbit_kind": ("orbit", o["kind"].astype(str), {"long_name": "typical or hard case"}),
        "alpha": ("orbit", o["alpha"], attrs("radian", "half-aperture of the cone")),
        "energy": ("orbit", o["energy"], attrs("J", "radial energy calE")),
        "h": ("orbit", o["h"], attrs("m s-1", "spin invariant")),
        "Lz": ("orbit", o["Lz"], attrs("kg m2 s-1", "axial angular momentum")),
        "M": ("orbit", o["M"], attrs("kg", "mass of the sphere")),
        "g": ("orbit", o["g"], attrs("m s-2", "gravity (0: free fall)")),
        "k": ("orbit", o["k"], attrs("1", "inertia factor I/(M a^2)")),
        "threads": ("threads", np.array(threads), attrs("1", "numba threads")),
        "gr_alpha": ("gr_alpha", B["g_alpha"], attrs("radian", "half-aperture, gravity slice")),
        "gr_offset": ("gr_offset", B["g_off"], attrs(
            "1", "energy offset (calE - V_min)/|V_min| on the gravity slice (h = "
            f"{B['g_h']} m s-1, Lz = {B['g_Lz']} kg m2 s-1, M = 1 kg, g = 9.81 m s-2, k = 0.4)")),
        "ff_alpha": ("ff_alpha", B["f_alpha"], attrs("radian", "half-aperture, free-fall slice")),
        "ff_x": ("ff_x", B["f_x"], attrs(
            "1", "calE/|V_min| = e^2 - 1 on the free-fall slice (h = "
            f"{B['f_h']} m s-1, Lz = {B['f_Lz']} kg m2 s-1, M = 1 kg, g = 0, k = 0.4)")),
    }  # fmt: skip
    ds = xr.Dataset(
        data,
        coords=coords,
        attrs={
            "title": "work-precision study of the conesurvey integrators",
            "Conventions": "CF-1.11",
            "source": f"conesurvey {engine.__version__}, scripts/work_precision.py",
            "history": time.strftime("%Y-%m-%dT%H:%M:%S") + " " + " ".join(sys.argv),
            "reference": "closed form (method exact); the closed form against tests/oracle.py",
            "rhs_evaluations_definition": EVAL_NOTE,
            "timing": meta["timing"],
            "circular_tol": 1e-12,
            "classification_note": CLASS_NOTE,
            "note_on_method_dim": 'select with ds.sel({"method": "rk45"}): sel(method=...) is '
            "xarray's inexact-match keyword",
            **{k: v for k, v in meta.items() if k not in ("timing", "repeats")},
        },
    )
    return ds


CLASS_NOTE = (
    "The integrator path does not classify by itself: engine.evaluate takes the class from the "
    "closed form and integrates only bounded (and spills) points; evaluate_integrated starts at "
    "the closed-form r_min and returns status 5 (not bounded) when the turning points are "
    "missing or the apsides do not come as apocentre then pericentre. gr_*: that gate across "
    "the forbidden boundary. ff_*: a class decided by integration (engine.simulate from r_min "
    "for a time budget) across the bounded/hyperbolic boundary in free fall."
)


# ------------------------------------------------------------------------------------- report
def report(orbits, rtols, threads, R, tex, orc, subset, B) -> None:
    """Print the table, the hard cases, the boundary study and the reading."""
    print(
        "\nerrors are relative, against the closed form; t/orbit = batch wall time / orbits "
        "(best of 3);\nsteps, rhs = median over orbits (rhs = stages x (accepted + rejected))"
    )
    head = (
        f"{'method':10s} {'rtol':>7s} {'psi med':>8s} {'psi max':>8s} {'T med':>8s} "
        f"{'prec max':>8s} {'drift max':>9s} {'steps':>6s} {'rhs':>7s} "
        f"{'t/orbit 1T':>10s} {'2T':>8s} {'eff':>5s} {'fail':>4s}"
    )
    print(head)
    print("-" * len(head))
    tpo = R["tpo"]
    for im, m in enumerate(METHODS):
        for ir, r in enumerate(rtols):
            e = {k: R[k][im, ir] for k in ("err_psi", "err_T", "err_prec", "drift")}
            print(
                f"{m:10s} {r:7.0e} {q(e['err_psi'], np.median):8.1e} "
                f"{q(e['err_psi'], np.max):8.1e} {q(e['err_T'], np.median):8.1e} "
                f"{q(e['err_prec'], np.max):8.1e} {q(e['drift'], np.max):9.1e} "
                f"{int(np.median(R['n_steps'][im, ir])):6d} {int(np.median(R['rhs'][im, ir])):7d} "
                f"{tpo[im, ir, 0]:10.2e} {tpo[im, ir, -1]:8.2e} {R['eff'][im, ir]:5.2f} "
                f"{int(np.sum(R['status'][im, ir] != 0)):4d}"
            )
    te = orc["err_apsidal_angle"]
    eff_ex = tex[1] / (threads[-1] * tex[threads[-1]])
    print(
        f"{'exact':10s} {'-':>7s} {q(te, np.median):8.1e} {q(te, np.max):8.1e} "
        f"{q(orc['err_period'], np.median):8.1e} {q(orc['err_precession_rate'], np.max):8.1e} "
        f"{'-':>9s} {'-':>6s} {'-':>7s} {tex[1]:10.2e} {tex[threads[-1]]:8.2e} {eff_ex:5.2f}"
        f"    -   (errors vs the mpmath oracle, {subset.size} orbits)"
    )
    ratios = []
    for var in ("apsidal_angle", "period", "precession_rate"):
        r = orc[f"err_{var}"] / (np.maximum(orc[f"cond_{var}"], 1.0) * 2.2e-16)
        ratios.append(f"{var} {q(r, np.max):.1f}")
    print(
        f"closed form vs oracle, max of error / (cond eps): {', '.join(ratios)} (the reference "
        f"data's test allows 50); oracle {q(orc['oracle_seconds'], np.sum):.0f} s for "
        f"{subset.size} orbits"
    )

    ir = int(np.argmin(np.abs(np.log(np.array(rtols) / 1e-10))))
    print(
        f"\nhard cases at rtol {rtols[ir]:.0e}: apsidal-angle error, wall time of the orbit alone"
    )
    for i in np.flatnonzero(orbits["kind"] == "hard"):
        cells = "  ".join(
            f"{m} {R['err_psi'][im, ir, i]:7.1e} {R['t_single'][im, ir, i] * 1e6:6.0f}us"
            for im, m in enumerate(METHODS)
        )
        print(f"  {str(orbits['name'][i]):38s} {cells}")

    print("\nnear the class boundaries. " + textwrap.fill(CLASS_NOTE, 98, subsequent_indent="  "))
    print("fractions of the slice points:")
    print(
        "  gate: gravity slice (forbidden | bounded; offsets 1e-14..1 either side, circular "
        "band left out):\n    evaluate_integrated status ok != closed-form bounded"
    )
    print("  ff: free-fall slice (bounded | hyperbolic; |calE|/|V_min| 1e-10..1): class from "
          "integration within 1.5 periods\n    != closed form; split b->h (bounded, not back in "
          "time), h->b (escape came back), fail (run failed);\n    eval: engine.evaluate "
          "status != 0 on the bounded points (period, psi NaN)")  # fmt: skip
    print(
        f"  {'method':10s} {'rtol':>7s} {'gate':>5s} {'ff':>5s} {'b->h':>5s} {'h->b':>5s} "
        f"{'fail':>5s} {'eval':>5s}  max psi error at distance d: gravity | free fall"
    )
    dists = (1e-2, 1e-6, 1e-10)
    for im, m in enumerate(METHODS):
        for ir, r in enumerate(rtols):
            cells = []
            for d in dists:
                jg = np.flatnonzero(np.isclose(B["g_off"], d, rtol=0.3))
                jf = np.flatnonzero(np.isclose(-B["f_x"], d, rtol=0.3))
                eg = q(B["g_epsi"][im, ir][:, jg], np.max) if jg.size else math.nan
                ef = q(B["f_epsi"][im, ir][:, jf], np.max) if jf.size else math.nan
                fails = int(np.sum(B["f_status"][im, ir][:, jf] != 0)) if jf.size else 0
                cells.append(
                    f"{d:.0e}: {eg:7.1e} | "
                    + (f"{ef:7.1e}" if not fails else f"{fails} fail".rjust(7))
                )
            print(
                f"  {m:10s} {r:7.0e} {B['g_frac'][im, ir]:5.2f} {B['f_frac'][im, ir]:5.2f} "
                f"{B['f_b2h'][im, ir]:5.2f} {B['f_h2b'][im, ir]:5.2f} "
                f"{B['f_fail'][im, ir]:5.2f} {B['f_evfail'][im, ir]:5.2f}  " + "  ".join(cells)
            )
    for label, key in (
        ("bounded -> hyperbolic", "f_b2h_mask"),
        ("hyperbolic -> bounded", "f_h2b_mask"),
        ("failed runs", "f_fail_mask"),
        ("engine.evaluate status != 0", "f_evfail_mask"),
    ):
        hit = B[key].any(axis=(0, 1, 2))
        if hit.any():
            xs = np.abs(B["f_x"][hit])
            print(f"  free fall, {label}: at |calE|/|V_min| from {xs.min():.0e} to {xs.max():.0e}")

    print(
        "\nreading: cheapest setting (1-thread time per orbit) whose apsidal-angle error is "
        "<= target,\n  over all orbits (max) and for the typical orbit (median):"
    )
    mx = np.nanmax(np.where(np.isnan(R["err_psi"]), np.inf, R["err_psi"]), axis=2)
    md = np.nanmedian(R["err_psi"], axis=2)

    def cheapest(err: np.ndarray, tgt: float) -> str:
        ok = np.argwhere(err <= tgt)
        if ok.size == 0:
            return "none (use the closed form)"
        a, b = ok[int(np.argmin([tpo[i, j, 0] for i, j in ok]))]
        return f"{METHODS[a]} rtol {rtols[b]:.0e} ({tpo[a, b, 0]:.1e} s)"

    for tgt in (1e-4, 1e-7, 1e-10, 1e-12, 1e-13):
        print(f"  <= {tgt:.0e}:  max: {cheapest(mx, tgt):36s} median: {cheapest(md, tgt)}")
    ir = int(np.argmin(np.abs(np.log(np.array(rtols) / 1e-10))))
    drift = ", ".join(
        f"{m} {q(R['drift'][im, ir], np.median):.0e} (max {q(R['drift'][im, ir], np.max):.0e})"
        for im, m in enumerate(METHODS)
    )
    print(f"  energy drift over one period at rtol {rtols[ir]:.0e}, median: {drift}")
    good = {}
    for im, m in enumerate(METHODS):
        ok = [r for ir, r in enumerate(rtols) if not B["f_evfail_mask"][im, ir].any()]
        good[m] = ", ".join(f"{r:.0e}" for r in ok) or "none"
    print(
        "  free fall e -> 1 (down to 1 - e^2 = 1e-10), rtols where no orbit failed: "
        + "; ".join(f"{m}: {good[m]}" for m in METHODS)
    )
    lo, hi = np.nanmin(tpo[:, :, 0]) / tex[1], np.nanmax(tpo[:, :, 0]) / tex[1]
    print(f"  closed form: max error {q(te, np.max):.1e} against the oracle at {tex[1]:.1e} "
          f"s/orbit, {lo:.0f}x to {hi:.0f}x cheaper than the integrator settings:\n  wherever it "
          "applies (conservative scene) use it; integrate only what it cannot do (rolling "
          "resistance, rim and slip events, trajectories).")  # fmt: skip


# ------------------------------------------------------------------------------ part 3: peers
PEER_TOLS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
PEER_COLOURS = {"rk45": "tab:blue", "dop853": "tab:orange", "symplectic": "tab:green",
                "scipy DOP853": "tab:red", "scipy RK45": "tab:purple",
                "heyoka (Taylor)": "tab:brown"}  # fmt: skip


def cpu_per_call(fn: Callable[[], object], repeats: int) -> float:
    """Smallest process CPU time [s] of ``repeats`` calls of ``fn`` (one thread runs them: the
    figure compares what one core spends, whatever else the machine runs)."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def peers_study(n: int, tols: tuple[float, ...], repeats: int) -> xr.Dataset:
    """Largest apsidal-angle error and CPU time per orbit of each solver at each tolerance,
    on ``n`` orbits of the integrator benchmark's task (module docstring, part 3)."""
    import integrator_peers as peers

    o = peers.typical_orbits(n)
    y0, scales = peers.start_states(o)
    scene = engine.Scene(M=peers.M, g=peers.G, k=peers.K)
    pts = [np.ascontiguousarray(o[k]) for k in ("alpha", "energy", "h", "Lz")]

    def ours(method: str, tol: float) -> Callable[[], np.ndarray]:
        return lambda: evaluate_integrated(*pts, scene, method, tol)["apsidal_angle"]

    solvers: dict[str, Callable[[float], Callable[[], np.ndarray]]] = {
        m: (lambda tol, m=m: ours(m, tol)) for m in METHODS
    }
    solvers["scipy DOP853"] = lambda tol: peers.scipy_runner(o, y0, tol * scales, "DOP853", tol)
    solvers["scipy RK45"] = lambda tol: peers.scipy_runner(o, y0, tol * scales, "RK45", tol)
    version = peers.heyoka_version()
    if version is None:
        print("heyoka not installed: its line is left out (pip install '.[bench]')")
    else:
        solvers["heyoka (Taylor)"] = lambda tol: peers.heyoka_loop_runner(o, y0, tol)
    names = list(solvers)
    err = np.full((len(names), len(tols)), np.nan)
    cpu = np.full((len(names), len(tols)), np.nan)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        for i, name in enumerate(names):
            for j, tol in enumerate(tols):
                run = solvers[name](tol)
                psi = np.asarray(run(), float).copy()  # compiles / builds, not timed
                err[i, j] = float(np.max(peers.rel_err(psi, o["psi"])))
                cpu[i, j] = cpu_per_call(run, repeats) / n
    finally:
        numba.set_num_threads(threads)
    dims = ("solver", "tol")
    return xr.Dataset(
        {
            "max_error_apsidal_angle": (dims, err, attrs("1", "largest relative error of the "
                                        "apsidal angle over the orbits, against the closed form")),
            "cpu_time_per_orbit": (dims, cpu, attrs("s", "process CPU time per orbit, one "
                                   f"thread, best of {repeats}")),
        },
        coords={"solver": ("solver", np.array(names, dtype=object)),
                "tol": ("tol", np.array(tols), attrs("1", "relative tolerance"))},
        attrs={
            "title": "conesurvey's integrators and their peers on the same orbits",
            "orbits": f"{n} typical bounded orbits of scripts/integrator_peers.py "
            "(M = 1 kg, g = 9.81 m/s2, k = 0.4), r_min to r_max",
            "heyoka": version or "not installed",
            "load_average": ", ".join(f"{x:.2f}" for x in os.getloadavg()),
        },
    )  # fmt: skip


def plot_peers(ds: xr.Dataset, png: Path) -> None:
    """Largest apsidal-angle error against CPU time per orbit, one line per solver."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5.5))
    for name in ds.solver.values:
        row = ds.sel(solver=name)
        t, e = row.cpu_time_per_orbit.values, np.maximum(row.max_error_apsidal_angle.values, FLOOR)
        ok = np.isfinite(e)
        style = "o-" if name in METHODS else "s--"
        ax.loglog(t[ok], e[ok], style, color=PEER_COLOURS.get(str(name)), label=str(name))
        for j in np.flatnonzero(ok)[[0, -1]] if ok.any() else []:
            ax.annotate(f"{float(ds.tol[j]):.0e}", (t[j], e[j]), fontsize=7,
                        textcoords="offset points", xytext=(4, 3))  # fmt: skip
    ax.set_xlabel("CPU time per orbit [s] (one thread)")
    ax.set_ylabel("largest relative error of the apsidal angle [1]")
    sub = textwrap.fill(f"{ds.attrs['orbits']}; load average {ds.attrs['load_average']}", 90)
    ax.set_title(f"{ds.attrs['title']}\n{sub}", fontsize=9)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def report_peers(ds: xr.Dataset) -> None:
    print(f"\n{ds.attrs['title']}: {ds.attrs['orbits']}")
    print(f"{'solver':18s} {'tol':>7s} {'max psi err':>11s} {'CPU/orbit':>10s}")
    for name in ds.solver.values:
        for j, tol in enumerate(ds.tol.values):
            row = ds.sel(solver=name).isel(tol=j)
            print(f"{str(name):18s} {tol:7.0e} {float(row.max_error_apsidal_angle):11.1e} "
                  f"{float(row.cpu_time_per_orbit):10.2e}")  # fmt: skip


def write(ds: xr.Dataset, path: Path) -> None:
    """``ds`` to ``path`` through a temporary file and a rename."""
    tmp = path.with_name(path.name + ".tmp")
    ds.to_netcdf(tmp)
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_out(parser)
    parser.add_argument("--quick", action="store_true", help="reduced sets (< 1 min)")
    parser.add_argument(
        "--part",
        choices=("all", "study", "peers"),
        default="all",
        help="parts 1 and 2 (study), part 3 (peers) or all (default)",
    )
    parser.add_argument("--tiny", action="store_true", help=TINY_HELP)
    args = parser.parse_args(argv)
    args.quick = args.quick or args.tiny
    args.out.mkdir(parents=True, exist_ok=True)
    if args.part in ("all", "study"):
        study(args)
    if args.part in ("all", "peers"):
        n, tols = (2, (1e-6,)) if args.tiny else (20, PEER_TOLS) if args.quick else (100, PEER_TOLS)
        ds = peers_study(n, tols, 1 if args.tiny else 3)
        nc, png = args.out / "work_precision_peers.nc", args.out / "work_precision_peers.png"
        write(ds, nc)
        plot_peers(ds, png)
        report_peers(ds)
        print(f"\nwrote {nc} and {png}")
    return 0


def study(args: argparse.Namespace) -> None:
    """Parts 1 and 2 (module docstring), written to ``--out``."""
    t_start = time.perf_counter()
    meta = machine_info()
    print(f"machine: {meta['machine']}")
    print(meta["versions"])
    print(f"load average at start (1, 5, 15 min): {meta['load_average_at_start']}")
    rtols = RTOLS_TINY if args.tiny else RTOLS_QUICK if args.quick else RTOLS_FULL
    repeats, target = (1 if args.tiny else 3), (0.005 if args.quick else 0.02)
    threads = [1, 2] if numba.config.NUMBA_NUM_THREADS >= 2 else [1]
    meta.update(repeats=repeats, timing=TIME_NOTE.format(target=target, repeats=repeats))
    meta["quick"] = int(args.quick)

    orbits = orbit_set(6, 2) if args.quick else orbit_set(30, 6)
    groups = scene_groups(orbits)
    exact = evaluate_set(orbits, groups, "exact")
    bad = np.flatnonzero(exact["orbit_class"] != BOUNDED)
    if bad.size:
        raise RuntimeError(f"orbits not bounded: {[str(orbits['name'][i]) for i in bad]}")
    hard = np.flatnonzero(orbits["kind"] == "hard")
    typical = np.flatnonzero(orbits["kind"] == "typical")
    print(f"\n{orbits['alpha'].size} bounded orbits ({hard.size} hard cases), {len(groups)} "
          f"scenes; {len(rtols)} tolerances; threads {threads}")  # fmt: skip

    ref0 = reference_speedup(threads) if len(threads) > 1 else math.nan
    R = run_integrators(orbits, groups, exact, rtols, threads, repeats, target)
    ref1 = reference_speedup(threads) if len(threads) > 1 else math.nan
    meta["threading_layer"] = numba.threading_layer()
    meta["control_speedup"] = (
        f"2-thread speedup of a compute-only prange loop: {ref0:.2f} before, {ref1:.2f} after "
        "the integrator timings (2.0 = two free cores)"
    )
    t1 = time.perf_counter()
    tex = time_per_orbit(orbits, groups, "exact", 1e-10, threads, repeats, target)
    if args.quick:
        subset = np.concatenate([typical[:1], hard[[3, 5]]])
    else:
        subset = np.concatenate([typical[:4], typical[-2:], hard])
    orc = oracle_errors(orbits, exact, subset)
    t2 = time.perf_counter()
    B = run_boundaries(args.quick, rtols)
    t3 = time.perf_counter()
    meta["load_average_at_end"] = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"threading layer {meta['threading_layer']}; integrators {t1 - t_start:.0f} s, closed "
          f"form and oracle {t2 - t1:.0f} s, boundary slices {t3 - t2:.0f} s; load average "
          f"now {meta['load_average_at_end']}")  # fmt: skip

    ds = build_dataset(orbits, rtols, threads, R, exact, tex, orc, B, meta)
    nc, png = args.out / "work_precision.nc", args.out / "work_precision.png"
    write(ds, nc)
    plot(ds, png)
    print(meta["control_speedup"])
    report(orbits, rtols, threads, R, tex, orc, subset, B)
    print(f"\nwrote {nc} and {png}; total {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    raise SystemExit(main())

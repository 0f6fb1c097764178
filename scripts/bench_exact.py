"""Throughput of the exact (closed-form) path against its numpy/scipy peer, side by side in one run.

    .venv/bin/python scripts/bench_exact.py                 # 1e6 points, 3 rounds (~2 minutes)
    .venv/bin/python scripts/bench_exact.py -n 200000 -r 5  # quicker
    .venv/bin/python scripts/bench_exact.py --doc           # also rewrite docs/performance.md
    .venv/bin/python scripts/bench_exact.py --threads 1,2,4,8,16  # also a table over thread counts

Prints, with the machine load before and after:

(a) the engine on random bounded points under gravity through ``engine.evaluate``'s flat path
    (``engine.evaluation.evaluate_flat``: class, turning points, r_circ, T_r, psi, precession
    rate and mu_required per point), on 1 and 2 numba threads;
(b) the engine on a survey grid through the grid path (``engine.evaluation.evaluate_block`` on
    the first block of ``surveys/large_1e8.toml``: what ``conesurvey run`` computes), 1 and 2
    threads, into new arrays and into buffers reused from call to call (``out=``, as a survey
    reuses them from block to block);
(c) the peer, on one core: numpy turning points (the trigonometric cubic formula) and T_r, psi
    from Carlson's R_F, R_D, R_J with ``scipy.special.elliprf/elliprd/elliprj``; and the same
    given the engine's turning points (Carlson only: the stricter peer);
(d) the compute-only control loop (``bench_common.spin``, as long as the engine's call) on 1
    and 2 threads in the same rounds: the 2-thread speedup the machine offers at the moment
    (2.0 on two free cores; other jobs' load takes from it), and the load average before and
    after those rounds;
(e) the goals: exact >= 4x the peer per core, 2 threads >= 1.8x one, serial share <= 3 % (the
    wall time outside the parallel regions at 1 thread, ``bench_common.serial_share``, of
    ``engine.evaluate``, ``evaluate_flat`` and ``evaluate_block``: the regions are the calls
    of ``engine.evaluation.run_queued``, the closed form's kernel and the check of
    ``evaluate``'s inputs); met or not;
(f) where the time goes: the lanes' stages, ns per point, measured (``profile_batch``);
(g) the exact-path table of docs/performance.md, in markdown (``--doc`` writes it there);
(h) first-call time of the kernels in a fresh interpreter: cold (empty cache) and warm;
(i) with ``--threads``: wall time and speedup of ``engine.evaluate`` (random points) and of
    the survey block at each thread count, the control loop beside them;
(j) with ``--first-touch``: what the first touch of new outputs costs the closed form on the
    random points (``engine.evaluation.orbit_batch``), 1 and 2 threads, minor page faults per
    call, side by side: the outputs as ``evaluate_flat`` allocates them (one [rows, n] table),
    the same without numpy's advice to use huge pages, one ``np.empty`` per row, one table
    whose rows start on 2 MiB boundaries (every page of it a transparent huge page where the
    system gives them), and reused; each on memory as the allocator has it after the previous
    call, and on memory just returned to the system (``malloc_trim(0)`` before the call: a
    first call, or a process whose heap shrank); and the writes alone (the same units from a
    shared counter, nothing computed): what the first touch costs 1 and 2 threads.

Per core means CPU time (``time.process_time``, best of the rounds): on a machine shared with
other jobs a process's wall time includes the time it waits for a core, its CPU time does not.
Wall times are printed too. scipy is a benchmark extra (``.venv/bin/pip install '.[bench]'`` in
the checkout).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np

import engine
from engine.evaluation import (
    block_variables,
    evaluate_block,
    evaluate_flat,
    orbit_batch,
    run_queued,
)
from engine.families import minimum_energy_flat
from engine.grid import Tiling
from engine.kernels.batch import STAGES, profile_batch
from engine.kernels.batch_rows import BATCH_ROWS, empty_outputs
from engine.kernels.geometry import BOUNDED, scene_params
from engine.kernels.lanes_step import fetch_add
from engine.plan import map_plan, plan_from_survey
from engine.surveyfile import load_survey

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import (  # noqa: E402
    MACHINE,
    fresh_interpreter,
    interleaved,
    load,
    serial_share,
    spin,
    verdict,
)
from readme_block import update_readme  # noqa: E402

#: Where ``--doc`` writes the table (between ``<!-- bench_exact: start/end -->``).
DOC = Path(__file__).resolve().parents[1] / "docs" / "performance.md"

M, G, K = 1.0, 9.81, 0.4
SCENE = engine.Scene(M=M, g=G, k=K)
TARGET_VS_PEER = 4.0
TARGET_SPEEDUP = 1.8
TARGET_SERIAL = 0.03
SURVEY = Path(__file__).resolve().parents[1] / "surveys" / "large_1e8.toml"


def random_bounded_points(n: int, seed: int = 20240601) -> dict[str, np.ndarray]:
    """n random bounded orbits under gravity, the issue's task: alpha [rad] uniform in
    [0.15, 1.45], L_z [kg m^2/s] uniform in [0.05, 2], h [m/s] uniform in [-2, 2], energy [J]
    uniform up to 3 C r_c above V_min.
    """
    rng = np.random.default_rng(seed)
    m = int(n * 1.05) + 16
    alpha = rng.uniform(0.15, 1.45, m)
    h = rng.uniform(-2.0, 2.0, m)
    Lz = rng.uniform(0.05, 2.0, m)
    vmin = engine.minimum_energy(alpha, h, Lz, SCENE)
    r_c = evaluate_flat(alpha, vmin, h, Lz, map_plan(SCENE))["r_circ"]
    C = M * G * np.cos(alpha) / (1.0 + K)
    energy = vmin + rng.uniform(0.0, 3.0, m) * C * r_c
    res = evaluate_flat(alpha, energy, h, Lz, map_plan(SCENE))
    keep = np.flatnonzero(res["orbit_class"] == BOUNDED)[:n]
    if keep.size < n:
        raise RuntimeError(f"only {keep.size} of {n} random points are bounded")
    pts = {"alpha": alpha, "energy": energy, "h": h, "Lz": Lz}
    out = {k: np.ascontiguousarray(v[keep]) for k, v in pts.items()}
    for key, var in (("r1", "r_min"), ("r2", "r_max"), ("T", "period"), ("psi", "apsidal_angle")):
        out[key] = np.ascontiguousarray(res[var][keep])
    return out


def _coefficients(alpha: np.ndarray, Lz: np.ndarray, h: np.ndarray):
    s = np.sin(alpha)
    c = np.cos(alpha)
    s2 = s * s
    kk = K / (1.0 + K)
    A = Lz * Lz / (2.0 * M * s2) * (1.0 + kk * (c * c) / s2)
    B = kk * h * Lz * c / s2
    C = M * G * c / (1.0 + K)
    return s2, A, B, C


def carlson_numpy(alpha, Lz, r1, r2, coef=None) -> tuple[np.ndarray, np.ndarray]:
    """(T_r [s], psi [rad]) from Carlson's forms with scipy.special, given r1 < r2 [m].

    r3 = -A/(C r1 r2); T_r = 2 sqrt(M/2C) [2 r1 R_F(0, r1-r3, r2-r3)
    + 2/3 (r2-r1)(r1-r3) R_D(0, r2-r3, r1-r3)]; psi = 2 K sqrt(M/2C) [R_F(0, 1-m, 1)
    + n/3 R_J(0, 1-m, 1, 1-n)] / (r2 sqrt(r2-r3)), m = (r2-r1)/(r2-r3), n = (r2-r1)/r2.
    """
    from scipy.special import elliprd, elliprf, elliprj

    s2, A, _, C = coef if coef is not None else _coefficients(alpha, Lz, np.zeros_like(Lz))
    r3 = -A / (C * r1 * r2)
    sc = np.sqrt(M / (2.0 * C))
    d21 = r2 - r1
    d13 = r1 - r3
    d23 = r2 - r3
    rf = elliprf(0.0, d13, d23)
    T = 2.0 * sc * (2.0 * r1 * rf + (2.0 / 3.0) * d21 * d13 * elliprd(0.0, d23, d13))
    m1 = d13 / d23  # 1 - m
    n = d21 / r2
    Kang = np.abs(Lz) / (M * s2)
    rj = elliprj(0.0, m1, 1.0, 1.0 - n)
    psi = 2.0 * Kang * sc * (elliprf(0.0, m1, 1.0) + n / 3.0 * rj) / (r2 * np.sqrt(d23))
    return T, psi


def peer(alpha, energy, h, Lz) -> tuple[np.ndarray, np.ndarray]:
    """The peer of the issue: turning points in numpy (the three real roots of
    C r^3 - calE r^2 + B r + A by the trigonometric formula), then :func:`carlson_numpy`."""
    coef = _coefficients(alpha, Lz, h)
    _, A, B, C = coef
    a2, a1, a0 = -energy / C, B / C, A / C
    t = a2 / 3.0
    p = a1 - a2 * t
    q = (2.0 * t * t - a1) * t + a0
    m = 2.0 * np.sqrt(-p / 3.0)
    th = np.arccos(np.clip(3.0 * q / (p * m), -1.0, 1.0)) / 3.0
    r2 = m * np.cos(th) - t
    r1 = m * np.cos(th - 2.0 * np.pi / 3.0) - t
    return carlson_numpy(alpha, Lz, r1, r2, coef)


def measure(fns: dict[str, Callable[[], object]], rounds: int) -> dict[str, tuple[float, float]]:
    """Best (wall, CPU) seconds of each call over interleaved rounds."""
    return interleaved(fns, rounds, (time.perf_counter, time.process_time))


def threaded(nt: int, fn: Callable[[], object]) -> Callable[[], object]:
    """``fn`` run on ``nt`` numba threads."""

    def call():
        numba.set_num_threads(nt)
        try:
            return fn()
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)

    return call


def survey_block() -> tuple[dict, tuple[slice, ...], int]:
    """The first block of surveys/large_1e8.toml: its spec, slices and number of points."""
    survey = load_survey(SURVEY)
    tiling = Tiling.for_grid(survey.shape)
    slices = tiling.slices(0)
    n = math.prod(
        len(range(*s.indices(size))) for s, size in zip(slices, survey.shape, strict=True)
    )
    return plan_from_survey(survey), slices, n


def profile(pts: dict[str, np.ndarray], rounds: int) -> list[tuple[str, float]]:
    """CPU ns per point of each stage of the lanes (random points, one thread)."""
    a, e, h, lz = pts["alpha"], pts["energy"], pts["h"], pts["Lz"]
    n = a.size
    cls, f = empty_outputs(n)
    fns, p = {}, scene_params(M, G, K)
    for upto in range(len(STAGES)):
        fns[STAGES[upto]] = lambda u=upto: profile_batch(a, e, h, lz, p, 1e-12, cls, f, u)
    for fn in fns.values():
        fn()
    best = measure(fns, max(rounds, 5))
    out, prev = [], 0.0
    for name in STAGES:
        t = best[name][1] / n * 1e9
        out.append((name, t - prev))
        prev = t
    return out


_PROBE = """
import json, math, time
t0 = time.perf_counter()
import numpy as np
import engine
from engine.evaluation import evaluate_flat
from engine.plan import map_plan
t1 = time.perf_counter()
a = np.full(64, 0.5); e = np.full(64, 10.0); h = np.full(64, 1.0); lz = np.full(64, 1.0)
evaluate_flat(a, e, h, lz, map_plan(engine.Scene()))
t2 = time.perf_counter()
evaluate_flat(a, e, h, lz, map_plan(engine.Scene()))
t3 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "first": t2 - t1, "second": t3 - t2}))
"""


def first_call(cache_dir: str | None) -> dict[str, float]:
    """Import and first/second ``evaluate_flat`` call times [s] in a fresh interpreter."""
    return fresh_interpreter(_PROBE, cache_dir)


def doc_table(n, n_grid, rounds, goals, ceiling, stages, peer_rate, serial, loads) -> str:
    """The exact-path table of docs/performance.md (from this run's numbers)."""
    lines = [
        f"Exact path (`.venv/bin/python scripts/bench_exact.py -n {n}`, "
        f"{time.strftime('%Y-%m-%d')}, "
        f"{MACHINE}, load average {loads}; per core = CPU time of one thread, best of "
        f"{rounds} interleaved rounds; {n:.0e} random bounded orbits of the issue's task, and "
        f"a {n_grid}-point block of `{SURVEY.name}`; peer: numpy turning points + scipy "
        "Carlson R_F/R_D/R_J):",
        "",
        "| goal | engine | peer | ratio | target | |",
        "|---|---|---|---|---|---|",
    ]
    for label, engine_rate, peer_r, ratio, target in goals:
        threads = peer_r is None
        extra = f" (a compute-only control loop: {ceiling:.2f})" if threads else ""
        peer_txt = "-" if threads else f"{peer_r:.3g} points/s"
        lines.append(
            f"| {label} | {engine_rate:.3g} points/s{extra} | {peer_txt} | {ratio:.2f} | "
            f">= {target:g} | {verdict(ratio, target).lower()} |"
        )
    for label, share in serial.items():
        met = "met" if share <= TARGET_SERIAL else "missed"
        lines.append(f"| {label}, serial share at 1 thread | {share:.2%} | - | - | "
                     f"<= {TARGET_SERIAL:.0%} | {met} |")  # fmt: skip
    where = ", ".join(f"{name} {t:.0f}" for name, t in stages)
    lines += [
        "",
        f"Where the time goes (ns per point, one thread, the lanes' stages): {where}; total "
        f"{sum(t for _, t in stages):.0f} (the peer: {1e9 / peer_rate:.0f}).",
    ]
    return "\n".join(lines)


def scaling(counts: str, a, e, h, lz, grid_path, rounds: int) -> str:
    """A markdown table: wall time and speedup over 1 thread of ``engine.evaluate`` on the
    random points, of the survey block and of the control loop, at each thread count of
    ``counts`` ("1,2,4"), in the same interleaved rounds."""
    most = numba.config.NUMBA_NUM_THREADS
    nts = sorted({1, *(int(x) for x in counts.split(",") if x.strip())} & set(range(1, most + 1)))
    fns = {}
    inner = control_inner(threaded(1, lambda: engine.evaluate(a, e, h, lz, SCENE)))
    for nt in nts:
        fns[f"evaluate {nt}"] = threaded(nt, lambda: engine.evaluate(a, e, h, lz, SCENE))
        fns[f"grid {nt}"] = threaded(nt, grid_path)
        fns[f"control {nt}"] = threaded(nt, lambda: spin(64, inner))
    for fn in fns.values():
        fn()
    before = load()
    best = measure(fns, rounds)
    lines = [
        f"{MACHINE}; load average {before} before, {load()} after; wall time, best of {rounds} "
        f"interleaved rounds (`.venv/bin/python scripts/bench_exact.py -n {a.size} --threads "
        f"{','.join(map(str, nts))}`); speedup over 1 thread:",
        "",
        "| threads | `evaluate` [s] | speedup | survey block [s] | speedup | control loop |",
        "|---|---|---|---|---|---|",
    ]
    for nt in nts:
        row = [f"| {nt} "]
        for key in ("evaluate", "grid"):
            t = best[f"{key} {nt}"][0]
            row.append(f"| {t:.3f} | {best[f'{key} 1'][0] / t:.2f} ")
        row.append(f"| {best['control 1'][0] / best[f'control {nt}'][0]:.2f} |")
        lines.append("".join(row))
    return "\n".join(lines)


_HUGE = 1 << 21  # a transparent huge page (x86-64)
_ROWS = ("r_min", "r_max", "r_circ", "period", "apsidal_angle", "precession_rate", "mu_required")


def _plain_rows(n: int) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """The outputs one ``np.empty`` per row."""
    unused = np.empty(0)
    return np.empty(n, np.int8), tuple(np.empty(n) if r in _ROWS else unused for r in BATCH_ROWS)


def _aligned_table(n: int) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """The outputs in one allocation, each row (and the class) starting on a 2 MiB boundary."""
    row = -(-8 * n // _HUGE) * _HUGE
    raw = np.empty((len(_ROWS) + 1) * row + _HUGE, np.uint8)  # numpy advises huge pages
    buf = raw[(-raw.ctypes.data) % _HUGE :]
    rows = iter(range(len(_ROWS)))
    f = tuple(buf[next(rows) * row :][: 8 * n].view(np.float64) if r in _ROWS else np.empty(0)
              for r in BATCH_ROWS)  # fmt: skip
    return buf[len(_ROWS) * row :][:n].view(np.int8), f


def _small_pages(n: int) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """The table as evaluate_flat allocates it, without numpy's advice to use huge pages."""
    from numpy._core.multiarray import _set_madvise_hugepage

    was = _set_madvise_hugepage(False)
    try:
        return empty_outputs(n, _ROWS)
    finally:
        _set_madvise_hugepage(was)


@numba.njit(nogil=True)
def _write_units(queue, units, cls, f):
    """The closed form's writes with nothing computed: units of 512 points taken from
    ``queue`` (as :func:`engine.kernels.workqueue.orbit_units_queued` takes them), each output
    of the unit written once."""
    while True:
        u = fetch_add(queue, 1)
        if u >= units:
            return
        lo, hi = u * 512, min(cls.size, u * 512 + 512)
        for i in range(lo, hi):
            cls[i] = 1
        for k in range(len(f)):
            row = f[k]
            for i in range(lo, hi if row.size else lo):
                row[i] = 1.0


def first_touch(a, e, h, lz, rounds: int) -> str:
    """(j): the closed form on the random points into outputs allocated four ways, 1 and 2
    threads, on the allocator's memory and on memory just returned to the system."""
    import ctypes
    import resource

    try:
        trim = ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        trim = None
    p, n = SCENE.params(), a.size
    kept = empty_outputs(n, _ROWS)
    allocs = {
        "one [rows, n] table (evaluate_flat)": lambda: empty_outputs(n, _ROWS),
        "the same, 4 kB pages (no huge-page advice)": lambda: _small_pages(n),
        "one np.empty per row": lambda: _plain_rows(n),
        "one table, rows on 2 MiB boundaries": lambda: _aligned_table(n),
        "reused (touched before)": lambda: kept,
    }
    fns, faults = {}, {}
    for label, alloc in allocs.items():
        for fresh in (False, True) if trim else (False,):
            for nt in (1, 2):

                def call(alloc=alloc, fresh=fresh):
                    if fresh:
                        trim(0)
                    orbit_batch(a, e, h, lz, p, 1e-12, *alloc())

                fns[(label, fresh, nt)] = threaded(nt, call)
    writes = "the writes alone, nothing computed (the table)"
    for fresh in (False, True) if trim else (False,):
        for nt in (1, 2):

            def call(fresh=fresh):
                if fresh:
                    trim(0)
                run_queued(_write_units, -(-n // 512), *empty_outputs(n, _ROWS))

            fns[(writes, fresh, nt)] = threaded(nt, call)
    inner = control_inner(fns[(next(iter(allocs)), False, 1)])
    fns["control 1"] = threaded(1, lambda: spin(64, inner))
    fns["control 2"] = threaded(2, lambda: spin(64, inner))
    for key, fn in fns.items():
        fn()
        before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        fn()
        faults[key] = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
    load_before = load()
    best = measure(fns, rounds)
    ceiling = best["control 1"][0] / best["control 2"][0]
    lines = [
        f"{MACHINE}; load average {load_before} before, {load()} after; {n} random bounded "
        f"points, the closed form (`orbit_batch`) into outputs allocated each way; best of "
        f"{rounds} interleaved rounds; minor page faults of one call at 1 thread; the control "
        f"loop got {ceiling:.2f} in the same rounds",
        "",
        "| outputs | memory | faults | 1 thread [ms] (CPU) | 2 threads [ms] (CPU) | 2 / 1 |",
        "|---|---|---|---|---|---|",
    ]
    for label in (*allocs, writes):
        for fresh in (False, True) if trim else (False,):
            (w1, c1), (w2, c2) = best[(label, fresh, 1)], best[(label, fresh, 2)]
            memory = "just returned to the system" if fresh else "the allocator's"
            nf = faults[(label, fresh, 1)]
            lines.append(
                f"| {label} | {memory} | {nf} | {w1 * 1e3:.1f} ({c1 * 1e3:.1f}) | "
                f"{w2 * 1e3:.1f} ({c2 * 1e3:.1f}) | {w1 / w2:.2f} |"
            )
    return "\n".join(lines)


def control_inner(fn: Callable[[], object]) -> int:
    """The inner length of ``bench_common.spin(64, inner)`` that takes as long at 1 thread as
    ``fn`` (one call of each, after a warm-up call of spin)."""
    numba.set_num_threads(1)
    try:
        spin(64, 1000)
        t0 = time.perf_counter()
        spin(64, 20_000)
        t_spin = time.perf_counter() - t0
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    t0 = time.perf_counter()
    fn()
    return max(1000, int(20_000 * (time.perf_counter() - t0) / t_spin))


def main(argv: list[str] | None = None) -> int:  # noqa: PLR0915 (a report, top to bottom)
    """Run the benchmark and print the report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", type=int, default=1_000_000, help="points (default %(default)s)")
    parser.add_argument("-r", "--rounds", type=int, default=3, help="interleaved rounds (3)")
    parser.add_argument("--no-compile", action="store_true", help="skip the compile-time probe")
    parser.add_argument("--doc", action="store_true", help="rewrite docs/performance.md's table")
    parser.add_argument("--threads", default="", help="thread counts for a scaling table, "
                        "comma-separated (e.g. 1,2,4,8,16; at most NUMBA_NUM_THREADS)")  # fmt: skip
    parser.add_argument("--first-touch", action="store_true",
                        help="also time the first touch of new outputs, (j)")  # fmt: skip
    parser.add_argument(
        "--tiny", action="store_true", help="a seconds-long smoke run (tests/test_scripts.py)"
    )
    args = parser.parse_args(argv)
    if args.tiny:
        args.n, args.rounds, args.no_compile, args.doc = 2000, 1, True, False
    import scipy

    t_start = time.perf_counter()
    ncpu = os.cpu_count() or 1
    print(f"machine: {MACHINE}, {platform.platform()}, os.cpu_count() = {ncpu}")
    print(
        f"python {platform.python_version()}, numba {numba.__version__}, numpy {np.__version__}, "
        f"scipy {scipy.__version__}, conesurvey {engine.__version__}"
    )
    print(f"load average before the run (1, 5, 15 min): {load()}")

    n = args.n
    pts = random_bounded_points(n)
    a, e, h, lz = pts["alpha"], pts["energy"], pts["h"], pts["Lz"]
    spec, slices, n_grid = survey_block()

    # Agreement first: the peers compute the same numbers; the grid path equals the flat one.
    T_peer, psi_peer = peer(a, e, h, lz)
    T_carl, psi_carl = carlson_numpy(a, lz, pts["r1"], pts["r2"])
    agree = {
        "peer": (np.max(np.abs(T_peer / pts["T"] - 1)), np.max(np.abs(psi_peer / pts["psi"] - 1))),
        "carlson": (
            np.max(np.abs(T_carl / pts["T"] - 1)),
            np.max(np.abs(psi_carl / pts["psi"] - 1)),
        ),
    }
    block = evaluate_block(spec, slices)
    sub = [np.asarray(ax)[s] for ax, s in zip(spec.axes, slices, strict=True)]
    A, E, H, L = (x.reshape(-1) for x in np.meshgrid(*sub, indexing="ij"))
    vmin = minimum_energy_flat(A, H, L, SCENE)  # the energy axis is relative to V_min
    flat = evaluate_flat(A, vmin + E * np.abs(vmin), H, L, map_plan(SCENE))
    same = all(
        np.array_equal(flat[k], block[k].reshape(-1), equal_nan=True) for k in flat if k in block
    )

    def api_path():
        engine.evaluate(a, e, h, lz, SCENE)

    def flat_path():
        evaluate_flat(a, e, h, lz, map_plan(SCENE))

    def grid_path():
        evaluate_block(spec, slices)

    buffers = {name: np.empty(block[name].shape, dt) for name, dt in block_variables(spec).items()}

    def grid_reused():
        evaluate_block(spec, slices, out=buffers)

    fns = {
        "flat 1": threaded(1, flat_path),
        "flat 2": threaded(2, flat_path),
        "api 1": threaded(1, api_path),
        "api 2": threaded(2, api_path),
        "grid 1": threaded(1, grid_path),
        "grid 2": threaded(2, grid_path),
        "reuse 1": threaded(1, grid_reused),
        "reuse 2": threaded(2, grid_reused),
        "peer": lambda: peer(a, e, h, lz),
        "carlson": lambda: carlson_numpy(a, lz, pts["r1"], pts["r2"]),
    }
    for fn in fns.values():  # compile, warm the thread pool
        fn()
    same = same and all(np.array_equal(buffers[k], block[k], equal_nan=True) for k in buffers)
    # The control loop lasts as long as the engine's call: a short one would find the second
    # core free more often on a loaded machine, and its best round would promise too much.
    inner = control_inner(threaded(1, flat_path))
    fns["ref 1"] = threaded(1, lambda: spin(64, inner))
    fns["ref 2"] = threaded(2, lambda: spin(64, inner))
    load_before = load()
    best = measure(fns, args.rounds)
    load_after = load()
    layer = numba.threading_layer()
    size = {"flat": n, "api": n, "grid": n_grid, "reuse": n_grid, "peer": n, "carlson": n}

    def rate(key: str, cpu: bool) -> float:
        return size[key.split()[0]] / best[key][1 if cpu else 0]

    print(
        f"\n{n} random bounded points (g = {G}, k = {K}) and a {n_grid}-point survey block "
        f"({SURVEY.name}, block 0); best of {args.rounds} interleaved rounds; threading layer "
        f"{layer}; load now {load()}"
    )
    print(
        "agreement: peer vs engine max |rel diff| T_r {:.1e}, psi {:.1e}; Carlson-only peer "
        "{:.1e}, {:.1e}; grid path (new arrays and reused buffers) == flat path bit for bit: "
        "{}".format(*agree["peer"], *agree["carlson"], same)
    )
    head = f"{'evaluation':58s} {'thr':>3s} {'wall pts/s':>11s} {'CPU pts/s':>11s}"
    print("\n" + head + "\n" + "-" * len(head))
    rows = (
        ("(a) engine, random points: evaluate_flat", "flat"),
        ("    the same through engine.evaluate (an xarray Dataset)", "api"),
        ("(b) engine, survey grid: evaluate_block", "grid"),
        ("    the same into reused buffers (evaluate_block(out=))", "reuse"),
    )
    for label, key in rows:
        for nt in (1, 2):
            k = f"{key} {nt}"
            print(f"{label:58s} {nt:3d} {rate(k, False):11.3g} {rate(k, True):11.3g}")
    print(f"{'(c) peer: numpy turning points + scipy Carlson':58s} {1:3d} "
          f"{rate('peer', False):11.3g} {rate('peer', True):11.3g}")  # fmt: skip
    print(f"{'    peer given the turning points (Carlson only)':58s} {1:3d} "
          f"{rate('carlson', False):11.3g} {rate('carlson', True):11.3g}")  # fmt: skip
    ceiling = best["ref 1"][0] / best["ref 2"][0]
    print(f"(d) compute-only control loop: 2-thread speedup available now {ceiling:.2f} "
          f"(2.0 on two free cores); load average {load_before} before these rounds, "
          f"{load_after} after")  # fmt: skip

    per_core = rate("flat 1", True) / rate("peer", True)
    per_core_strict = rate("flat 1", True) / rate("carlson", True)
    per_core_grid = rate("grid 1", True) / rate("peer", True)
    wall_1 = rate("flat 1", False) / rate("peer", False)
    sp_flat = best["flat 1"][0] / best["flat 2"][0]
    sp_api = best["api 1"][0] / best["api 2"][0]
    sp_grid = best["grid 1"][0] / best["grid 2"][0]
    sp_reuse = best["reuse 1"][0] / best["reuse 2"][0]
    print("\n(e) goals")
    print(f"exact (random points) / peer, per core (CPU): {per_core:.2f}x "
          f"(target >= {TARGET_VS_PEER:g}x: {verdict(per_core, TARGET_VS_PEER)}); "
          f"wall {wall_1:.2f}x; vs the Carlson-only peer {per_core_strict:.2f}x")  # fmt: skip
    print(f"survey grid / peer, per core (CPU): {per_core_grid:.2f}x")
    print(f"2 threads vs 1 (wall): random points {sp_flat:.2f} (engine.evaluate {sp_api:.2f}), "
          f"survey grid {sp_grid:.2f}, into reused buffers {sp_reuse:.2f} (target >= "
          f"{TARGET_SPEEDUP:g}: {verdict(min(sp_flat, sp_api, sp_grid), TARGET_SPEEDUP)}); "
          f"the control loop got {ceiling:.2f} at the same time, load {load_after}")  # fmt: skip
    print(f"share of the control loop's speedup reached (1.00: all the second core gave): "
          f"evaluate {sp_api / ceiling:.2f}, evaluate_flat {sp_flat / ceiling:.2f}, survey grid "
          f"{sp_grid / ceiling:.2f}, survey grid into reused buffers "
          f"{sp_reuse / ceiling:.2f}")  # fmt: skip

    region = (engine.evaluation, "run_queued")  # every parallel region of the exact path
    serial = {
        "exact path (`evaluate`)": serial_share(lambda: engine.evaluate(a, e, h, lz, SCENE),
                                                *region),
        "exact path (`evaluate_flat`)": serial_share(flat_path, *region),
        "exact survey grid (`evaluate_block`)": serial_share(grid_path, *region),
    }  # fmt: skip
    for label, share in serial.items():
        print(f"{label} serial share at 1 thread (wall time outside the parallel regions): "
              f"{share:.2%} (target <= {TARGET_SERIAL:.0%}: "
              f"{'met' if share <= TARGET_SERIAL else 'MISSED'})")  # fmt: skip

    stages = profile(pts, args.rounds)
    total = sum(t for _, t in stages)
    print("\n(f) where the time goes: lanes' stages on random points, one thread, CPU ns/point")
    for name, t in stages:
        print(f"    {name:22s} {t:7.1f}")
    print(f"    {'total':22s} {total:7.1f}   (the peer: {1e9 / rate('peer', True):.0f})")

    goals = (
        ("exact path (`evaluate_flat`) vs the peer, per core", rate("flat 1", True),
         rate("peer", True), per_core, TARGET_VS_PEER),
        ("exact survey grid (`evaluate_block`) vs the peer, per core", rate("grid 1", True),
         rate("peer", True), per_core_grid, TARGET_VS_PEER),
        ("exact path (`evaluate`, the Dataset), 2 threads vs 1 (wall)", rate("api 2", False),
         None, sp_api, TARGET_SPEEDUP),
        ("exact path (`evaluate_flat`), 2 threads vs 1 (wall)", rate("flat 2", False), None,
         sp_flat, TARGET_SPEEDUP),
        ("exact survey grid, 2 threads vs 1 (wall)", rate("grid 2", False), None, sp_grid,
         TARGET_SPEEDUP),
        ("exact survey grid into reused buffers (`out=`), 2 threads vs 1 (wall)",
         rate("reuse 2", False), None, sp_reuse, TARGET_SPEEDUP),
    )  # fmt: skip
    loads = f"{load_before} before the timed rounds, {load_after} after"
    md = doc_table(n, n_grid, args.rounds, goals, ceiling, stages, rate("peer", True), serial,
                   loads)  # fmt: skip
    print("\n(g) docs/performance.md table\n" + md)
    if args.doc:
        update_readme("bench_exact", md, DOC)
        print(f"\nwrote it into {DOC}")

    if not args.no_compile:
        with tempfile.TemporaryDirectory(prefix="conesurvey-cold-") as tmp:
            cold = first_call(tmp)
        warm = min((first_call(None) for _ in range(2)), key=lambda d: d["first"])
        print("\n(h) evaluate_flat in a fresh interpreter [s]")
        print(f"{'cache':34s} {'import':>8s} {'1st call':>9s} {'2nd call':>9s} {'process':>8s}")
        for label, d in (("cold (empty cache directory)", cold), ("warm (on-disk cache)", warm)):
            print(
                f"{label:34s} {d['import']:8.3f} {d['first']:9.3f} {d['second']:9.5f} "
                f"{d['process']:8.3f}"
            )
    if args.threads:
        print("\n(i) threads\n" + scaling(args.threads, a, e, h, lz, grid_path, args.rounds))
    if args.first_touch:
        print("\n(j) first touch of new outputs\n" + first_touch(a, e, h, lz, args.rounds))
    print(f"\nload average after the run: {load()}; total benchmark time "
          f"{time.perf_counter() - t_start:.1f} s")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

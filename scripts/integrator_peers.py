"""The integrator benchmark's task and its peers (imported by ``scripts/bench_integrators.py``).

The task of the performance goals (README "Performance"): typical bounded orbits, M = 1 kg,
g = 9.81 m/s2, k = 0.4, alpha uniform in [0.15, 1.45] rad, L_z in [0.05, 2] kg m2/s, h in
[-2, 2] m/s, radial energy up to 3 C r_c above V_min; each integrated for half a radial
period, from r_min (u = 0) to the next apsis r_max, giving the apsidal angle psi (the azimuth
swept) and the period (twice the time), compared with the closed form (``method="exact"``).

Peers, on the same equations of motion (docs/physics.md) from the same start with a terminal
event u = 0 (u decreasing): scipy.integrate.solve_ivp, and heyoka's Taylor integrator
(``taylor_adaptive`` in a Python loop over the orbits, as a user would call it; its ensemble
propagation over threads; ``taylor_adaptive_batch`` on the SIMD lanes). scipy and heyoka are
the ``bench`` extra, imported here only.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

import engine
from engine.kernels.cone import coefficients
from engine.kernels.cone_starts import initial_state, orbit_start, tolerance_scales
from engine.kernels.roots import circular_radius

M, G, K = 1.0, 9.81, 0.4
NAN = math.nan


def typical_orbits(n: int, seed: int = 20240612) -> dict[str, np.ndarray]:
    """n orbits of the task, with their closed-form half period and apsidal angle."""
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(0.15, 1.45, n)
    Lz = rng.uniform(0.05, 2.0, n)
    h = rng.uniform(-2.0, 2.0, n)
    scene = engine.Scene(M=M, g=G, k=K)
    vmin = engine.minimum_energy(alpha, h, Lz, scene)
    rise = np.array([3.0 * C * circular_radius(A, B, C)
                     for A, B, C in (coefficients(a, b, c, M, G, K)
                                     for a, b, c in zip(alpha, h, Lz, strict=True))])  # fmt: skip
    energy = vmin + rng.uniform(0.0, 1.0, n) * rise
    ex = engine.evaluate(alpha, energy, h, Lz, scene)
    if not np.all(ex.orbit_class.values == engine.CLASS_NAMES.index("bounded")):
        raise RuntimeError("the task's orbits must all be bounded")
    out = {"alpha": alpha, "energy": energy, "h": h, "Lz": Lz}
    out["T"] = ex.period.values.copy()
    out["psi"] = ex.apsidal_angle.values.copy()
    return out


def start_states(o: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(y0 [n, 5], atol scales [n, 5]): the engine's start at r_min (u = 0) and its
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


def rel_err(psi: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """|psi/ref - 1|, infinite where an orbit failed (NaN)."""
    e = np.abs(psi / ref - 1.0)
    return np.where(np.isnan(e), np.inf, e)


# ---------------------------------------------------------------------------------------- scipy
def scipy_runner(o, y0, atol, method: str, rtol: float) -> Callable[[], np.ndarray]:
    """solve_ivp over the orbits one after the other; ``atol`` a scalar or [n, 5]. Returns psi
    per orbit (NaN where no apsis was found)."""
    from scipy.integrate import solve_ivp

    kk = K / (1.0 + K)
    n = o["alpha"].size
    atol = np.broadcast_to(np.asarray(atol, float), (n, 5)) if np.ndim(atol) == 0 else atol

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

    funcs = [make(i) for i in range(n)]
    psi = np.full(n, NAN)

    def run() -> np.ndarray:
        for i in range(n):
            fun, apsis = funcs[i]
            sol = solve_ivp(fun, (0.0, 10.0 * o["T"][i]), y0[i], method=method, rtol=rtol,
                            atol=atol[i], events=apsis)  # fmt: skip
            ev = sol.y_events[0]
            psi[i] = abs(ev[0][1]) if len(ev) else NAN
        return psi

    return run


# --------------------------------------------------------------------------------------- heyoka
_HY_CACHE: dict[tuple, object] = {}


def heyoka_version() -> str | None:
    try:
        import heyoka
    except ImportError:
        return None
    return str(heyoka.__version__)


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


def heyoka_loop_runner(o, y0, tol: float) -> Callable[[], np.ndarray]:
    """The scalar integrator driven by a Python loop over the orbits."""
    ta = heyoka_scalar(tol)
    pars = _pars(o["alpha"]).T.copy()
    n = o["alpha"].size
    psi = np.full(n, NAN)
    t_max = 10.0 * o["T"]

    def run() -> np.ndarray:
        for i in range(n):
            ta.time = 0.0
            ta.state[:] = y0[i]
            ta.pars[:] = pars[i]
            ta.reset_cooldowns()
            res = ta.propagate_until(float(t_max[i]))
            psi[i] = abs(ta.state[1]) if int(res[0]) == -1 else NAN
        return psi

    return run


def heyoka_ensemble_runner(o, y0, tol: float, workers: int) -> Callable[[], np.ndarray]:
    """heyoka.ensemble_propagate_until (a thread pool of ``workers``) over the orbits."""
    import heyoka as hy

    ta = heyoka_scalar(tol)
    pars = _pars(o["alpha"]).T.copy()
    n = o["alpha"].size
    psi = np.full(n, NAN)
    t_max = float(10.0 * np.max(o["T"]))

    def gen(tc, i):
        tc.time = 0.0
        tc.state[:] = y0[i]
        tc.pars[:] = pars[i]
        tc.reset_cooldowns()
        return tc

    def run() -> np.ndarray:
        out = hy.ensemble_propagate_until(ta, t_max, n, gen, algorithm="thread",
                                          max_workers=workers)  # fmt: skip
        for i, res in enumerate(out):
            psi[i] = abs(res[0].state[1]) if int(res[1]) == -1 else NAN
        return psi

    return run


def heyoka_batch_runner(o, y0, tol: float) -> Callable[[], np.ndarray]:
    """taylor_adaptive_batch (SIMD lanes), ``recommended_simd_size`` orbits at a time. A
    terminal event in one lane stops the whole batch, so the batch is propagated again with the
    finished lanes' target time set to their current time (they hold still) until every lane
    has met its apsis: at most one call per lane."""
    import heyoka as hy

    bs = int(hy.recommended_simd_size())
    key = ("batch", tol, bs)
    if key not in _HY_CACHE:
        sys_, u = _heyoka_system()
        ev = hy.t_event_batch(u, direction=hy.event_direction.negative)
        _HY_CACHE[key] = hy.taylor_adaptive_batch(sys_, np.ones((5, bs)), tol=tol,
                                                  t_events=[ev], pars=np.ones((4, bs)))  # fmt: skip
    ta = _HY_CACHE[key]
    n = o["alpha"].size
    nb = -(-n // bs)
    pad = np.resize(np.arange(n), nb * bs)  # the last batch is filled with repeats
    lanes = [pad[b * bs : (b + 1) * bs] for b in range(nb)]
    Y = [np.ascontiguousarray(y0[ii].T) for ii in lanes]
    P = [np.ascontiguousarray(_pars(o["alpha"][ii])) for ii in lanes]
    T = [10.0 * o["T"][ii] for ii in lanes]
    psi = np.full(n, NAN)

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


def main(argv: list[str] | None = None) -> int:
    """Run each peer once on a few orbits of the task and print its apsidal-angle error
    against the closed form (heyoka when installed; otherwise say so)."""
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", type=int, default=20, help="orbits (default %(default)s)")
    parser.add_argument("--tol", type=float, default=1e-10, help="tolerance of every peer")
    parser.add_argument("--tiny", action="store_true", help="a seconds-long smoke run (2 orbits)")
    args = parser.parse_args(argv)
    n = 2 if args.tiny else args.n
    o = typical_orbits(n)
    y0, scales = start_states(o)
    runs = {"scipy DOP853": scipy_runner(o, y0, args.tol * scales, "DOP853", args.tol)}
    version = heyoka_version()
    if version is None:
        print("heyoka not installed: its peers are left out (pip install heyoka)")
    else:
        runs[f"heyoka {version} loop"] = heyoka_loop_runner(o, y0, args.tol)
    for name, run in runs.items():
        err = rel_err(np.asarray(run()), o["psi"])
        print(f"{name:24s} {n} orbits, tol {args.tol:g}: max |psi error| {np.max(err):.2e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

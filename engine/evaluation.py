"""Evaluating maps: the kernels over flat arrays of points, and over one block of a survey grid.

:func:`evaluate_flat` is what :func:`engine.evaluate` and every survey block call: the closed
form for every point, then (for an integrator method) one integrated radial period for the
points that have one. :func:`evaluate_block` evaluates one hyperslab of a 4-D survey grid, so
the in-memory survey, local streamed runs and dask workers compute the very same blocks.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING

import numba
import numpy as np

from .families import minimum_energy_flat
from .fates import fate_map
from .integrated import integrate_period
from .kernels.batch_rows import BATCH_ROWS, empty_outputs
from .kernels.geometry import BOUNDED, OUT_OF_RANGE, ideal_cone
from .kernels.protocol import NOT_BOUNDED
from .kernels.workqueue import CHECK_UNIT, checked_queued, orbit_units_queued, work_units
from .launch import invariants
from .precision import at, stored
from .schema import (
    DIMS,
    FATE_KINDS,
    INTEGRATED,
    REPLACED_BY_INTEGRATION,
    RESULTS,
    variable_dims,
)
from .surface_eval import surface_block

if TYPE_CHECKING:
    from .plan import MapPlan, RunPlan

__all__ = ["evaluate_flat", "evaluate_block", "block_variables", "bad_inputs"]


def evaluate_flat(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    plan: MapPlan,
    *,
    r_start: np.ndarray | None = None,
    release: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> dict[str, np.ndarray]:
    """Kernel call on equal-length 1-D float64 arrays (validated by the caller), for the map
    of ``plan`` (:func:`engine.plan.map_plan`; a survey's :class:`engine.plan.RunPlan` is one).

    Returns a dict of 1-D arrays: the plan's variables but ``V_min`` and a launch grid's
    invariants. Every map holds the closed form; what else depends on the plan's
    ``map_kind``: where rolling ends on a cone with a rim or a friction limit (closed form),
    one integrated radial period, or each orbit's fate (integrated up to the plan's horizon
    from ``r_start``, by default r_min; then the closed form describes the launch orbit on the
    ideal cone; ``release``: (u0, slip_u, slip_v) of launches that may slide,
    :func:`engine.fates.fates`).
    """
    a = np.ascontiguousarray(alpha, np.float64)
    e = np.ascontiguousarray(energy, np.float64)
    hh = np.ascontiguousarray(h, np.float64)
    lz = np.ascontiguousarray(Lz, np.float64)
    kind, scene = plan.map_kind, plan.scene
    wanted = set(plan.variables)  # the rows not wanted are not written (nor allocated)
    if kind in FATE_KINDS and r_start is None:
        wanted.add("r_min")  # where the fates start
    cls, f = empty_outputs(a.shape[0], wanted)
    p = scene.params()
    if kind in FATE_KINDS:  # the launch orbit on the ideal cone; the integration follows the scene
        p = ideal_cone(p)
    orbit_batch(a, e, hh, lz, p, plan.circular_tol, cls, f)
    out: dict[str, np.ndarray] = {"orbit_class": cls}
    for i, name in enumerate(BATCH_ROWS):
        if name in plan.variables:
            out[name] = f[i]
    if kind == "one period":
        out.update(_integrate_bounded(a, e, hh, lz, plan, cls))
    elif kind in FATE_KINDS:
        start = f[0] if r_start is None else np.ascontiguousarray(r_start, np.float64)
        out.update(fate_map(a, e, hh, lz, start, scene, plan.method, plan.rtol, plan.horizon,
                            classes=cls, release=release))  # fmt: skip
    return out


def _integrate_bounded(a, e, hh, lz, plan: MapPlan, cls) -> dict[str, np.ndarray]:
    """The one-period variables for every point: bounded points integrated; the others NaN,
    no steps and the status "not_bounded" (nothing to integrate over a period)."""
    n = a.shape[0]
    sel = np.flatnonzero(cls == BOUNDED)
    every = sel.size == n  # every point bounded: no copies in, the kernel's outputs out
    pts = (a, e, hh, lz) if every else (a[sel], e[sel], hh[sel], lz[sel])
    res = integrate_period(*pts, plan.scene, plan.method, plan.rtol)
    upd: dict[str, np.ndarray] = {}
    for name in (*REPLACED_BY_INTEGRATION, *INTEGRATED):
        dtype = np.dtype(RESULTS[name].dtype)
        if every and res[name].dtype == dtype:
            upd[name] = res[name]
            continue
        fill = NOT_BOUNDED if name == "status" else (np.nan if dtype.kind == "f" else 0)
        col = np.full(n, fill, dtype)
        col[sel] = res[name]
        upd[name] = col
    return upd


_POOL: dict[int, ThreadPoolExecutor] = {}
_NO_ENERGY = np.empty(0)


def run_queued(kernel, units: int, *args) -> None:
    """A parallel region: ``kernel(queue, units, *args)`` (a GIL-free kernel of
    :mod:`.kernels.workqueue` that takes units of work from the shared counter ``queue`` until
    ``units`` are taken) on ``numba.get_num_threads()`` threads, the calling thread one of
    them. Not a ``prange`` kernel: numba compiles a parallel kernel's whole call tree once more
    (~9 s on a cold cache); a thread pool costs nothing (the kernels release the GIL)."""
    nt = max(1, min(numba.get_num_threads(), units))
    queue = np.zeros(1, np.int64)
    if nt == 1:
        kernel(queue, units, *args)
        return
    if nt not in _POOL:
        _POOL[nt] = ThreadPoolExecutor(max_workers=nt - 1, thread_name_prefix="conesurvey-lanes")
    jobs = [_POOL[nt].submit(kernel, queue, units, *args) for _ in range(nt - 1)]
    kernel(queue, units, *args)
    for job in jobs:
        job.result()


def run_units(*args) -> None:
    """The parallel region of the closed form: :func:`.kernels.batch.orbit_units` over all its
    units of work (``args``: its arguments after the unit range), by :func:`run_queued`: each
    thread makes one call of :func:`.kernels.workqueue.orbit_units_queued`, which takes units
    from a shared counter one at a time (the finest even split, balanced while it runs). The
    outputs are first touched there, by the thread that computes them. The results do not
    depend on the number of threads."""
    alpha, energy, h, Lz, grid = args[:5]
    units = work_units(alpha.size, energy.size, h.size * Lz.size, grid)
    run_queued(orbit_units_queued, units, *args)


def bad_inputs(
    arrays: tuple[np.ndarray, ...], lo: tuple[float, ...], hi: tuple[float, ...]
) -> np.ndarray:
    """Whether each of k C-contiguous float64 arrays of n values (any shape) holds a value not
    strictly between ``lo[j]`` and ``hi[j]`` (NaN included): bool[k], checked in one pass on
    the threads (:func:`run_queued`, :func:`.kernels.workqueue.checked_queued`)."""
    k, n = len(arrays), arrays[0].size
    per = -(-n // CHECK_UNIT)
    bad = np.zeros((k, per), np.int8)
    if n:
        run_queued(checked_queued, k * per, tuple(a.reshape(-1) for a in arrays),
                   np.array(lo, np.float64), np.array(hi, np.float64), bad)  # fmt: skip
    return bad.any(axis=1)


def orbit_batch(alpha: np.ndarray, energy: np.ndarray, h: np.ndarray, Lz: np.ndarray,
                params: np.ndarray, circ_tol: float, out_cls: np.ndarray,
                out_f: tuple[np.ndarray, ...]) -> None:  # fmt: skip
    """:func:`.kernels.geometry.orbit_point` over 1-D float64 arrays, in parallel and in lanes,
    on the scene's parameter array ``params`` (``Scene.params()``): ``out_cls`` int8[n],
    ``out_f`` 10 float64 arrays (rows :data:`.kernels.batch_rows.BATCH_ROWS`), each [n], or [0]
    where the row is not wanted (:func:`.kernels.batch_rows.empty_outputs`)."""
    run_units(alpha, energy, h, Lz, False, False, params, float(circ_tol), out_cls, out_f,
              _NO_ENERGY)  # fmt: skip


def orbit_grid(alpha: np.ndarray, energy: np.ndarray, h: np.ndarray, Lz: np.ndarray,
               relative: bool, params: np.ndarray, circ_tol: float, out_cls: np.ndarray,
               out_f: tuple[np.ndarray, ...], out_energy: np.ndarray) -> None:  # fmt: skip
    """:func:`orbit_batch` over the grid alpha x energy x h x Lz (1-D float64 axes; outputs
    flat in that C order), each family computed once per (alpha, h, L_z) for a chunk of
    energies; ``relative``: the energy axis is an offset (:func:`.kernels.batch.orbit_units`),
    ``out_energy`` float64[n] receives the absolute energy (float64[0]: not wanted)."""
    run_units(alpha, energy, h, Lz, True, bool(relative), params, float(circ_tol), out_cls, out_f,
              out_energy)  # fmt: skip


def evaluate_block(
    plan: RunPlan, slices: tuple[slice, ...], *, out: dict[str, np.ndarray] | None = None
) -> dict[str, np.ndarray]:
    """Results on one hyperslab of the grid, each array shaped like the slab.

    ``plan``: the validated run plan (:class:`engine.plan.RunPlan`): its dims (one of
    :data:`engine.schema.GRID_DIMS`) and axes, scene, method, map kind, ``energy_relative``,
    ``circular_tol``, ``rtol`` and ``horizon`` (fate maps).
    With a relative energy axis the absolute energy is V_min + offset |V_min| from the slab's
    own V_min; where V has no minimum it is NaN and the point is classed forbidden
    (out_of_range where its numbers are, as :func:`evaluate_flat` says). On a grid of launch
    states the invariants of each launch are computed (:func:`engine.launch.invariants`) and
    returned too, and fates start at the launch. A closed-form map on (alpha, energy, h, L_z)
    runs the grid kernel, which computes what does not depend on the energy once per
    (alpha, h, L_z); its numbers equal :func:`evaluate_flat`'s on the same points bit for bit.
    On that grid r_circ and V_min, stored on (alpha, h, Lz), are in no block
    (:func:`family_values`).

    ``out``: arrays to write the results into, and return (the same dict), in place of new
    ones: one for each of :func:`block_variables`, C-contiguous, of the slab's shape and the
    plan's dtype (a ValueError names the variable that is not). The numbers equal a call
    without ``out`` bit for bit. A closed-form map on (alpha, energy, h, L_z) with float64
    results (the survey grid) is computed into them directly, allocating nothing per point
    (a survey reuses its buffers from block to block: no new pages to fault in); other maps
    are computed as without ``out``, then copied in.
    """
    dims = tuple(plan.dims)
    sub = [np.ascontiguousarray(ax[s], np.float64) for ax, s in zip(plan.axes, slices, strict=True)]
    shape = tuple(x.size for x in sub)
    names = block_variables(plan)
    if out is not None:
        _check_out(out, names, shape)
    if plan.surface is not None:
        res = surface_block(plan, sub)
    elif tuple(dims) == DIMS and plan.map_kind == "closed form":
        direct = out is not None and all(names[n] == np.float64 for n in names if n in BATCH_ROWS)
        res = _closed_form_grid(sub, plan, names, out if direct else None)
        if direct:
            return out
    else:
        res = _flat_block(sub, plan)
    if out is None:  # r_circ (fewer dims): family_values
        return {n: col.reshape(shape) for n, col in res.items() if variable_dims(n, dims) == dims}
    for name in names:  # the cast of a float32 plan: never to a float32 of another meaning
        stored(name, res[name].reshape(shape), out[name].dtype, out[name], at(dims, sub))
    return out


def block_variables(plan: RunPlan) -> dict[str, np.dtype]:
    """The arrays of a block of ``plan``'s grid (:func:`evaluate_block`): names and dtypes,
    the plan's variables but those stored on fewer dims (r_circ and V_min on
    (alpha, h, L_z): :func:`family_values`)."""
    dims = tuple(plan.dims)
    return {n: dt for n, dt in plan.variables.items() if variable_dims(n, dims) == dims}


def _check_out(out: dict[str, np.ndarray], names: dict[str, np.dtype], shape: tuple) -> None:
    """ValueError naming the first array of ``out`` that :func:`evaluate_block` cannot write."""
    unknown = sorted(set(out) - set(names))
    missing = [n for n in names if n not in out]
    if unknown or missing:
        raise ValueError(f"out: arrays for {', '.join(names)} are wanted; "
                         f"missing {missing or 'none'}, unknown {unknown or 'none'}")  # fmt: skip
    for name, dtype in names.items():
        a = out[name]
        if not isinstance(a, np.ndarray):
            raise ValueError(f"out[{name!r}] is a {type(a).__name__}, not a numpy array")
        if a.shape != shape:
            raise ValueError(f"out[{name!r}] has shape {a.shape}; the block's is {shape}")
        if a.dtype != dtype:
            raise ValueError(f"out[{name!r}] has dtype {a.dtype}; the plan's is {dtype}")
        if not (a.flags.c_contiguous and a.flags.writeable):
            raise ValueError(f"out[{name!r}] is not a writeable C-contiguous array")


def _closed_form_grid(sub: list[np.ndarray], plan: RunPlan, names, out=None):
    """The closed form on the grid of the axes ``sub`` (flat arrays in the grid's C order),
    for the block's variables ``names``: into new arrays, or the float64 arrays ``out``."""
    n = math.prod(x.size for x in sub)
    scene, relative = plan.scene, plan.energy_relative
    if out is None:
        cls, f = empty_outputs(n, names)
    else:
        cls = out["orbit_class"].reshape(-1)
        f = tuple(out[r].reshape(-1) if r in names else _NO_ENERGY for r in BATCH_ROWS)
    orbit_grid(*sub, relative, scene.params(), plan.circular_tol, cls, f, _NO_ENERGY)
    res: dict[str, np.ndarray] = {"orbit_class": cls}
    for i, name in enumerate(BATCH_ROWS):
        if name in names:
            res[name] = f[i]
    return res


def _flat_block(sub: list[np.ndarray], plan: RunPlan):
    """Any map on the grid of the axes ``sub``, through :func:`evaluate_flat` on its points."""
    scene, dims = plan.scene, plan.dims
    A, X1, X2, X3, *rel = (x.reshape(-1) for x in np.meshgrid(*sub, indexing="ij"))
    e_abs = None
    r_start = None
    release = None
    if dims != DIMS:  # launch states (with the release's u0, slip_u, slip_v on a sliding scene:
        # its axes, or numbers, 0 where not given)
        given = dict(zip(dims[4:], rel, strict=True))
        fixed = dict(plan.release)

        def column(name: str) -> np.ndarray:
            return given[name] if name in given else np.full(A.shape, fixed.get(name, 0.0))

        u0 = column("u0")
        slip_u = u0 + column("backspin") if "backspin" in {*given, *fixed} else column("slip_u")
        inv = invariants(A, X1, u0, X2, X3, scene)
        E, H, L, r_start = inv["energy"], inv["h"], inv["Lz"], X1
        release = (u0, slip_u, column("slip_v")) if "sliding" in scene.effects else None
    else:
        E, H, L = X1, X2, X3
        if plan.energy_relative:
            vmin = minimum_energy_flat(A, H, L, scene)
            e_abs = vmin + E * np.abs(vmin)
            E = e_abs
    res = evaluate_flat(A, E, H, L, plan, r_start=r_start, release=release)
    if e_abs is not None:
        undefined = np.isnan(e_abs)
        if undefined.any():
            cls = res["orbit_class"]
            cls[undefined & (cls != OUT_OF_RANGE)] = 0  # out_of_range stays, as evaluate says
            for name, col in res.items():
                if name != "r_circ" and col.dtype.kind == "f":
                    col[undefined] = np.nan
            if "fate" in res:
                res["fate"][undefined] = 0  # no orbit
    if r_start is not None:
        res.update(energy=E, h=H, Lz=L)
    return res

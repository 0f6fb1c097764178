"""What accuracy costs: each method that can serve a survey's scene, measured on a sample of
the survey's own grid at a ladder of tolerances (:func:`work_precision`,
``conesurvey accuracy``; docs/accuracy.md).

The sample is a sub-grid of the survey: on each axis about ``sample ** (1/4)`` distinct values
drawn at random (seeded: the same sample every time), the longest axes most. Each method
computes the survey's map on it, the survey's own way (:func:`engine.evaluation.evaluate_block`),
and is compared with a reference:

- on a scene the closed form describes whole (a one-period map for the integrators), the
  reference is the exact path itself: for each bounded orbit, the relative errors of the
  radial period and the apsidal angle, of the turning points (the apocentre and the next
  pericentre of one period, integrated by :func:`engine.simulate`, on :data:`TURNING_ORBITS`
  bounded orbits spread evenly over the sample; a one-period map stores the closed form's
  turning points) and the energy drift over the integration (the map's ``energy_drift``).
  The closed form's own error is the one it is tested to (docs/api.md, "Accuracy"):
  :data:`EXACT_ERROR`;
- on a scene with rolling resistance, a rim, a friction limit or sliding (fate maps), the
  reference is :data:`REFERENCE_METHOD` at :data:`REFERENCE_RTOL` (at the points where it ends
  in a fate, not ``no_orbit`` or ``failed``): the share of points whose fate differs and,
  where it agrees, the relative errors of ``fate_time``, ``fate_r`` and ``energy_lost``.

A setting's ``error`` is the largest of these over the sample; its cost is the wall time per
point of the map on this machine (numba's threads; timed on a sub-grid of the survey large
enough to take :data:`MIN_TIME` s, the best of ``repeats`` rounds that time every setting in
turn), and ``survey_seconds`` that time for the whole grid.
:func:`recommend` picks the fastest setting whose error meets a target.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Sequence
from typing import Any

import numba
import numpy as np
import xarray as xr

from .api import minimum_energy
from .checks import check_rtol
from .evaluation import evaluate_block
from .methods import METHODS
from .plan import RunPlan, grid_plan, map_plan
from .schema import FATE_KINDS, flag_table
from .simulate import simulate
from .surveydef import Survey
from .surveyfile import load_survey

__all__ = [
    "DEFAULT_RTOLS",
    "EXACT_ERROR",
    "SAMPLE_POINTS",
    "recommend",
    "sample_counts",
    "sample_grid",
    "work_precision",
]

#: Points of the sample (a sub-grid; the whole grid if smaller).
SAMPLE_POINTS = 256
#: The tolerances each integrator is measured at.
DEFAULT_RTOLS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
#: Bounded orbits whose turning points are integrated (one ``simulate`` call each, per setting;
#: spread evenly over the sample's bounded orbits).
TURNING_ORBITS = 24
#: The closed form's relative error as tested against 40-digit references (docs/api.md).
EXACT_ERROR = 1e-12
#: A fate map's reference: this method at this tolerance.
REFERENCE_METHOD, REFERENCE_RTOL = "dop853", 1e-13
#: Seconds a timing call should last (the sub-grid grows to that), and its largest size.
MIN_TIME, MAX_TIMING_POINTS = 0.2, 1 << 20
_PERIODIC = ("period", "apsidal_angle", "turning_point", "energy")
_FATE = ("fate_time", "fate_r", "energy_lost")


def _plan(survey: Any) -> RunPlan:
    if isinstance(survey, RunPlan):
        return survey
    if isinstance(survey, Survey):
        return survey.plan
    if isinstance(survey, str | os.PathLike):
        return load_survey(survey).plan
    raise ValueError(f"survey must be a survey file, a Survey or a RunPlan; got {survey!r}")


def sample_counts(plan: RunPlan, points: int) -> list[int]:
    """Values per axis of a sub-grid of about ``points`` points: two of each axis (its one if
    it has one), then each doubled in turn, the one with the most values per sampled value
    first."""
    counts = [min(2, a.size) for a in plan.axes]
    while math.prod(counts) < points:
        grow = [i for i, a in enumerate(plan.axes) if counts[i] < a.size]
        if not grow:
            break
        i = max(grow, key=lambda j: plan.axes[j].size / counts[j])
        counts[i] = min(2 * counts[i], plan.axes[i].size)
    return counts


def sample_grid(plan: RunPlan, points: int = SAMPLE_POINTS, seed: int = 0) -> RunPlan:
    """``plan`` on a sub-grid of about ``points`` points (at most twice as many; the whole grid
    if smaller), each axis's values drawn at random without repeats (``seed``: reproducible)."""
    rng = np.random.default_rng(seed)
    axes = []
    for a, n in zip(plan.axes, sample_counts(plan, points), strict=True):
        sub = a[np.sort(rng.choice(a.size, n, replace=False))]
        sub.setflags(write=False)
        axes.append(sub)
    return dataclasses.replace(plan, axes=tuple(axes))


def _even_grid(plan: RunPlan, points: int) -> RunPlan:
    axes = []
    for a, n in zip(plan.axes, sample_counts(plan, points), strict=True):
        sub = a[np.unique(np.linspace(0, a.size - 1, n).round().astype(np.int64))]
        sub.setflags(write=False)
        axes.append(sub)
    return dataclasses.replace(plan, axes=tuple(axes))


def _setting(plan: RunPlan, method: str, rtol: float) -> RunPlan:
    """``plan`` computed by ``method`` at ``rtol`` (its grid, scene, horizon kept)."""
    h = plan.horizon
    mp = map_plan(plan.scene, method, rtol=rtol, circular_tol=plan.circular_tol,
                  horizon_time=h.time if h else None,
                  horizon_revolutions=h.revolutions if h else None,
                  horizon_hint="give the survey a [horizon] (the integrators follow each "
                               "orbit to its fate)")  # fmt: skip
    return grid_plan(mp, plan.dims, plan.axes, energy_relative=plan.energy_relative)


def _code(name: str, meaning: str, kind: str) -> int:
    """The code of ``meaning`` in the flag variable ``name`` of a map of ``kind``."""
    return dict((m, c) for c, m in flag_table(name, kind))[meaning]


def _flat(plan: RunPlan) -> dict[str, np.ndarray]:
    """The map of ``plan`` over its whole (sample) grid, flattened."""
    out = evaluate_block(plan, tuple(slice(None) for _ in plan.dims))
    return {k: np.asarray(v).reshape(-1) for k, v in out.items()}


def _timing_grid(full: RunPlan, sample: int, took: float, min_time: float) -> RunPlan:
    """A sub-grid of the survey ``full`` (evenly spaced values) whose map takes about
    ``min_time`` s, from ``took`` s for ``sample`` points; at most the whole grid."""
    want = int(sample * min_time / max(took, 1e-6))
    return _even_grid(full, max(sample, min(full.size, MAX_TIMING_POINTS, want)))


def _seconds_per_point(grids: list[RunPlan], repeats: int) -> np.ndarray:
    """Wall time per point of each map of ``grids``: the best of ``repeats`` rounds, each
    round timing every map once in turn (a burst of load hits them alike)."""
    best = np.full(len(grids), np.inf)
    for _ in range(repeats):
        for s, g in enumerate(grids):
            t0 = time.perf_counter()
            evaluate_block(g, tuple(slice(None) for _ in g.dims))
            best[s] = min(best[s], time.perf_counter() - t0)
    return best / np.array([g.size for g in grids])


def _rel(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.abs(x - ref) / np.abs(ref)


def _invariants(plan: RunPlan, res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """alpha and (calE, h, Lz) of every sample point, flattened: a launch grid's invariants
    are variables of its map; a relative energy is V_min + energy |V_min|, as the run took it."""
    grids = np.meshgrid(*plan.axes, indexing="ij")
    at = {d: g.reshape(-1) for d, g in zip(plan.dims, grids, strict=True)}
    if plan.launch:
        return {"alpha": at["alpha"], "energy": res["energy"], "h": res["h"], "Lz": res["Lz"]}
    energy = at["energy"]
    if plan.energy_relative:
        vmin = minimum_energy(at["alpha"], at["h"], at["Lz"], plan.scene)
        energy = vmin + energy * np.abs(vmin)
    return {"alpha": at["alpha"], "energy": energy, "h": at["h"], "Lz": at["Lz"]}


def _turning_errors(o, idx, ref, method, rtol, scene) -> np.ndarray:
    """Relative error of the apocentre and the next pericentre (the larger) of one period by
    ``simulate``, for the orbits ``idx`` (NaN where the run failed)."""
    out = np.full(idx.size, np.nan)
    for j, i in enumerate(idx):
        try:
            tr = simulate(o["alpha"][i], o["energy"][i], o["h"][i], o["Lz"][i], scene,
                          periods=1, method=method, rtol=rtol, dt_out=1e300)  # fmt: skip
        except (ValueError, RuntimeError):
            continue
        r = tr.event_r.values
        if tr.attrs["status"] == 0 and r.size >= 2:
            out[j] = max(_rel(r[0], ref["r_max"][i]), _rel(r[1], ref["r_min"][i]))
    return out


def work_precision(
    survey: Any,
    *,
    methods: Sequence[str] | None = None,
    rtols: Sequence[float] = DEFAULT_RTOLS,
    sample: int = SAMPLE_POINTS,
    seed: int = 0,
    repeats: int = 3,
    min_time: float = MIN_TIME,
) -> xr.Dataset:
    """Accuracy against cost of each method that can serve ``survey``'s scene (module
    docstring), on a sample of its grid.

    ``survey``: a survey file's path, an :class:`engine.surveydef.Survey` or a
    :class:`engine.plan.RunPlan`. ``methods``: names of :data:`engine.METHODS` (default: every
    one that honours the scene); ``rtols``: the integrators' tolerances; ``sample``: points of
    the sample; ``seed``: which sample. Returns a Dataset over ``setting`` (coordinates
    ``method`` and ``rtol``, NaN for the closed form) and ``orbit`` (the sample points compared,
    with their alpha and invariants ``orbit_energy`` [J], ``orbit_h``, ``orbit_Lz``): per orbit
    the relative error of each quantity, per setting ``error`` (the largest),
    ``median_error``, ``failed`` (orbits whose integration failed), ``steps`` (median accepted
    steps), ``seconds_per_point`` and ``survey_seconds``. ValueError naming the argument for
    bad input."""
    plan = _plan(survey)
    scene = plan.scene
    for name, value, low in (("sample", sample, 1), ("repeats", repeats, 1), ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}; got {value!r}")
    if not (isinstance(min_time, int | float) and min_time >= 0.0):
        raise ValueError(f"min_time must be a number >= 0; got {min_time!r}")
    rtols = _checked_rtols(rtols)
    names = _checked_methods(methods, scene)
    small = sample_grid(plan, sample, seed)
    kind = _setting(small, REFERENCE_METHOD, REFERENCE_RTOL).map_kind
    fates = kind in FATE_KINDS
    if fates:  # the closed form draws another map (where rolling ends) on such a scene
        names = [n for n in names if METHODS[n].integrates]
        ref = _flat(_setting(small, REFERENCE_METHOD, REFERENCE_RTOL))
        failed_fate = _code("fate", "failed", kind)
        none = (_code("fate", "no_orbit", kind), failed_fate)
        keep = np.flatnonzero(~np.isin(ref["fate"], none))  # where the reference has a fate
    else:
        ref = _flat(_setting(small, "exact", REFERENCE_RTOL))
        keep = np.flatnonzero(ref["orbit_class"] == _code("orbit_class", "bounded", kind))
    if keep.size == 0:
        what = "an orbit with a fate" if fates else "a bounded orbit (what integrators follow)"
        raise ValueError(f"sample: none of its {small.size} points is {what}; a larger sample "
                         "or another seed may find some")  # fmt: skip
    o = {k: v[keep] for k, v in _invariants(small, ref).items()}
    ref = {k: v[keep] for k, v in ref.items()}
    quantities = _FATE if fates else _PERIODIC
    settings = [(n, math.nan) for n in names if not METHODS[n].integrates]
    settings += [(n, r) for n in names if METHODS[n].integrates for r in rtols]
    shape = (len(settings), keep.size)
    err = {q: np.full(shape, np.nan) for q in quantities}
    per = {k: np.full(len(settings), np.nan) for k in ("error", "median_error", "steps")}
    failed = np.zeros(len(settings), np.int64)
    differs = np.zeros(shape, np.int8)
    turning = np.unique(np.linspace(0, keep.size - 1, TURNING_ORBITS).round().astype(np.int64))
    grids = []
    for s, (name, rtol) in enumerate(settings):
        r = rtol if METHODS[name].integrates else REFERENCE_RTOL
        res = {k: v[keep] for k, v in _flat(_setting(small, name, r)).items()}
        t0 = time.perf_counter()  # again, its kernels loaded: how long the sample takes
        evaluate_block(_setting(small, name, r), tuple(slice(None) for _ in small.dims))
        took = time.perf_counter() - t0
        grids.append(_timing_grid(_setting(plan, name, r), small.size, took, min_time))
        if not METHODS[name].integrates:
            per["error"][s] = per["median_error"][s] = EXACT_ERROR
            continue
        ok = res["fate"] != failed_fate if fates else res["status"] == 0
        failed[s] = int(np.sum(~ok))
        per["steps"][s] = float(np.median(res["n_steps"]))
        if fates:
            differs[s] = res["fate"] != ref["fate"]
            same = ~differs[s].astype(bool)
            for q in quantities:
                if q in res:
                    err[q][s] = np.where(same, _rel(res[q], ref[q]), np.nan)
        else:
            err["period"][s] = _rel(res["period"], ref["period"])
            err["apsidal_angle"][s] = _rel(res["apsidal_angle"], ref["apsidal_angle"])
            err["energy"][s] = res["energy_drift"]
            err["turning_point"][s, turning] = _turning_errors(o, turning, ref, name, rtol, scene)
        worst = np.nanmax(np.stack([err[q][s] for q in quantities]), axis=0, initial=0.0)
        worst = np.where(ok & ~differs[s].astype(bool), worst, np.inf)
        per["error"][s] = float(np.max(worst, initial=0.0))
        per["median_error"][s] = float(np.median(worst))
    per["seconds_per_point"] = _seconds_per_point(grids, repeats)
    return _dataset(plan, small, settings, o, err, per, failed, differs if fates else None)


def _checked_rtols(rtols: Any) -> tuple[float, ...]:
    values = np.atleast_1d(np.asarray(rtols, dtype=object)).tolist()
    if not values:
        raise ValueError("rtols must hold at least one tolerance; got none")
    out = []
    for r in values:
        try:
            out.append(check_rtol(r, METHODS["dop853"]))  # an integrator's range
        except ValueError as exc:
            raise ValueError(f"rtols: {exc}") from None
    return tuple(sorted(set(out), reverse=True))


def _checked_methods(methods: Any, scene: Any) -> list[str]:
    able = [n for n, m in METHODS.items() if not m.refused_effects(scene)]
    if methods is None:
        return able
    names = [methods] if isinstance(methods, str) else list(methods)
    if not names:
        raise ValueError("methods must name at least one method; got none")
    for n in names:
        if n not in METHODS:
            raise ValueError(f"methods: {n!r} is not a method; one of {', '.join(METHODS)}")
        if n not in able:
            refused = METHODS[n].refused_effects(scene)
            why = "; ".join(f"{e}: {dict(METHODS[n].refuses)[e]}" for e in refused)
            raise ValueError(f"methods: {n!r} cannot serve this scene ({why}); methods that "
                             f"can: {', '.join(able)}")  # fmt: skip
    return [n for n in METHODS if n in names]


def _dataset(plan, small, settings, o, err, per, failed, differs) -> xr.Dataset:
    method = np.array([n for n, _ in settings], dtype=object)
    rtol = np.array([r for _, r in settings])
    data: dict[str, Any] = {
        f"{q}_error": (("setting", "orbit"), e, {"units": "1", "long_name": f"relative error "
                       f"of {q.replace('_', ' ')} against the reference"})
        for q, e in err.items()
    }  # fmt: skip
    if differs is not None:
        data["fate_differs"] = (
            ("setting", "orbit"),
            differs,
            {"long_name": "1 where the fate differs from the reference"},
        )
    data["error"] = (
        "setting",
        per["error"],
        {
            "units": "1",
            "long_name": "largest relative "
            "error over the sample (inf: an orbit failed or its fate differs)",
        },
    )
    data["median_error"] = ("setting", per["median_error"], {"units": "1"})
    data["steps"] = ("setting", per["steps"], {"long_name": "median accepted steps per orbit"})
    data["failed"] = ("setting", failed, {"long_name": "orbits whose integration failed"})
    data["seconds_per_point"] = ("setting", per["seconds_per_point"], {"units": "s"})
    data["survey_seconds"] = (
        "setting",
        per["seconds_per_point"] * plan.size,
        {"units": "s", "long_name": "projected time of the whole survey"},
    )
    for k in ("energy", "h", "Lz"):
        data[f"orbit_{k}"] = ("orbit", np.asarray(o[k], np.float64))
    coords = {"method": ("setting", method), "rtol": ("setting", rtol),
              "alpha": ("orbit", np.asarray(o["alpha"], np.float64))}  # fmt: skip
    fates = differs is not None
    attrs = {
        "title": f"work-precision of {plan.title}",
        "reference": f"{REFERENCE_METHOD} at rtol {REFERENCE_RTOL:g}" if fates else "closed form",
        "exact_error": f"{EXACT_ERROR:g}: the closed form's tested accuracy (docs/api.md)",
        "survey_points": plan.size,
        "sample_points": small.size,
        "sample_shape": " x ".join(
            f"{d} {a.size}" for d, a in zip(small.dims, small.axes, strict=True)
        ),
        "compared": int(err[next(iter(err))].shape[1]),
        "threads": numba.get_num_threads(),
        "load_average": ", ".join(f"{x:.2f}" for x in os.getloadavg()),
        "map_kind": "fate" if fates else "one period",
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)


def recommend(ds: xr.Dataset, target: float) -> dict[str, Any] | None:
    """The fastest setting of ``ds`` (:func:`work_precision`) whose ``error`` is at most
    ``target`` and where no orbit failed: method, rtol, error, seconds per point and for the
    whole survey; None if none meets it."""
    if isinstance(target, bool) or not isinstance(target, int | float) or not target > 0:
        raise ValueError(f"target must be a number > 0; got {target!r}")
    ok = np.flatnonzero((ds["error"].values <= target) & (ds["failed"].values == 0))
    if ok.size == 0:
        return None
    s = int(ok[np.argmin(ds["seconds_per_point"].values[ok])])
    row = ds.isel(setting=s)
    return {"method": str(row["method"].values), "rtol": float(row["rtol"]),
            "error": float(row["error"]), "seconds_per_point": float(row["seconds_per_point"]),
            "survey_seconds": float(row["survey_seconds"])}  # fmt: skip

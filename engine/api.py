"""High-level API: validate inputs, run the kernels over arrays, return xarray Datasets."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import xarray as xr

from .checks import (
    PlanError,
    check_named_surface,
    check_numbers,
    check_release,
    check_scene,
    check_values,
)
from .evaluation import bad_inputs, evaluate_block, evaluate_flat
from .families import family_values, minimum_energy_flat
from .grid import BLOCK_POINTS, Tiling
from .kernels.cone import radial_energy as _radial_energy
from .kernels.geometry import CIRCULAR_TOL
from .methods import DEFAULT_RTOL
from .plan import RunPlan, map_plan, survey_plan
from .scene import Scene
from .schema import (
    DIMS,
    axis_attrs,
    launch_dims,
    result_attrs,
    surface_dims,
    variable_attrs,
    variable_dims,
)
from .surfaces import Surface

__all__ = [
    "evaluate",
    "survey",
    "launch_survey",
    "minimum_energy",
    "radial_energy",
    "run_plan",
    "validate_inputs",
]


def validate_inputs(alpha, energy, h, Lz) -> None:
    """Raise ValueError naming the first offending argument (non-finite, alpha out of range)."""
    for name, value in (("alpha", alpha), ("energy", energy), ("h", h), ("Lz", Lz)):
        check_values(name, value)


def evaluate(
    alpha: Any,
    energy: Any,
    h: Any,
    Lz: Any,
    scene: Scene | None = None,
    method: str = "exact",
    *,
    circular_tol: float = CIRCULAR_TOL,
    rtol: float = DEFAULT_RTOL,
    horizon_time: float | None = None,
    horizon_revolutions: float | None = None,
) -> xr.Dataset:
    """Class and orbit geometry at points (alpha [rad], energy [J], h [m/s], Lz [kg m^2/s]).

    Inputs broadcast like numpy arrays (xarray DataArrays broadcast by dimension name). The
    result has the broadcast shape, dims ``dim_0, dim_1, ...`` (or the DataArrays' dims), the
    inputs as coordinates, and the variables ``orbit_class``, ``r_min``, ``r_max``, ``r_circ``,
    ``period``, ``apsidal_angle``, ``precession_rate``, ``mu_required``. ``energy`` is the
    radial energy calE (see :func:`engine.radial_energy`). NaN marks an undefined quantity.

    What else the map holds depends on the scene and the method (its ``map_kind`` attribute,
    docs/api.md "What a map means for each scene"): with a rim or a friction limit the closed form
    adds where rolling ends (``end_r``, ``end_time``, ``end_theta``); an integrator on the ideal
    cone integrates one radial period; an integrator on a scene with rolling resistance, a rim or
    a friction limit follows each orbit from r_min to its fate (``fate`` and the variables after
    it), up to ``horizon_time`` [s] and/or ``horizon_revolutions`` (one is required then).
    """
    plan = map_plan(scene, method, circular_tol=circular_tol, rtol=rtol,
                    horizon_time=horizon_time, horizon_revolutions=horizon_revolutions)  # fmt: skip
    inputs = {"alpha": alpha, "energy": energy, "h": h, "Lz": Lz}
    for name, value in inputs.items():
        check_numbers(name, value)
    if any(isinstance(v, xr.DataArray) for v in inputs.values()):
        das = xr.broadcast(
            *[xr.DataArray(v) if not isinstance(v, xr.DataArray) else v for v in inputs.values()]
        )
        dims = das[0].dims
        arrays = [np.asarray(d.transpose(*dims).values, np.float64) for d in das]
    else:
        arrays = [np.asarray(v, np.float64) for v in inputs.values()]
        dims = tuple(
            f"dim_{i}" for i in range(len(np.broadcast_shapes(*(a.shape for a in arrays))))
        )
    arrays = _checked_points(list(inputs), arrays)
    shape = arrays[0].shape
    flat = [np.ascontiguousarray(a).reshape(-1) for a in arrays]
    res = evaluate_flat(*flat, plan)
    kind = plan.map_kind
    order = [name for name in plan.variables if name in res]  # as in a file
    assert len(order) == len(res), (sorted(res), order)
    data_vars = {
        name: (dims, res[name].reshape(shape), variable_attrs(name, kind)) for name in order
    }
    coords = {}
    for (name, value), arr in zip(inputs.items(), arrays, strict=True):
        attrs = axis_attrs(name)
        if isinstance(value, xr.DataArray):
            # keep a DataArray input on its own dims (1-D inputs become index coordinates)
            coords[name] = (value.dims, np.asarray(value.values, np.float64), attrs)
        else:
            coords[name] = (dims, arr, attrs)
    return xr.Dataset(
        data_vars,
        coords=coords,
        attrs=result_attrs(
            plan.scene, plan.method.name, plan.circular_tol, plan.rtol, plan.horizon
        ),
    )


#: The open interval each input of :func:`evaluate` must lie in (as :func:`check_values`).
_BOUNDS = {"alpha": (0.0, np.pi / 2)}


def _checked_points(names: list[str], arrays: list[np.ndarray]) -> list[np.ndarray]:
    """The inputs, broadcast to one shape, each checked (:func:`check_values`: a PlanError
    names the first bad value of the first input that holds one). float64 inputs of one shape
    (C-contiguous, writable) are used as they are, checked in one pass on the threads
    (:func:`engine.evaluation.bad_inputs`): the result's coordinates wrap them, as xarray
    wraps the arrays it is given; others are broadcast and copied here (copies, not broadcast
    views: numba warns on those)."""
    shape = np.broadcast_shapes(*(a.shape for a in arrays))
    if all(a.shape == shape and a.flags.c_contiguous and a.flags.writeable for a in arrays):
        lo, hi = zip(*(_BOUNDS.get(n, (-np.inf, np.inf)) for n in names), strict=True)
        for name, arr, bad in zip(names, arrays, bad_inputs(tuple(arrays), lo, hi), strict=True):
            if bad:
                check_values(name, arr)  # raises, naming the first bad value
        return arrays
    copies = [np.array(np.broadcast_to(a, shape)) for a in arrays]
    validate_inputs(*copies)
    return copies


def minimum_energy(alpha: Any, h: Any, Lz: Any, scene: Scene | None = None) -> np.ndarray:
    """V_min [J] of the effective potential at (alpha, h, Lz); NaN where V has no minimum."""
    scene = check_scene(scene)
    for name, value in (("alpha", alpha), ("h", h), ("Lz", Lz)):
        check_numbers(name, value)
    views = np.broadcast_arrays(*[np.asarray(v, np.float64) for v in (alpha, h, Lz)])
    a, hh, lz = (np.array(x) for x in views)  # copies: numba warns on broadcast views
    validate_inputs(a, 0.0, hh, lz)
    flat = (np.ascontiguousarray(x).reshape(-1) for x in (a, hh, lz))
    return minimum_energy_flat(*flat, scene).reshape(a.shape)


def radial_energy(E: Any, h: Any, scene: Scene | None = None) -> Any:
    """Radial energy calE [J] = E/(1+k) - k M h^2 / (2(1+k)) from the total energy E [J]
    (numbers or arrays)."""
    s = check_scene(scene)
    return _radial_energy.py_func(E, h, s.M, s.k)


def survey(
    alpha: Any,
    energy: Any,
    h: Any,
    Lz: Any,
    scene: Scene | None = None,
    method: str = "exact",
    *,
    energy_relative: bool = False,
    circular_tol: float = CIRCULAR_TOL,
    rtol: float = DEFAULT_RTOL,
    horizon_time: float | None = None,
    horizon_revolutions: float | None = None,
    progress: Callable[[int, int], None] | None = None,
    block_points: int = BLOCK_POINTS,
    chunk_points: int | None = None,
) -> xr.Dataset:
    """Outer product of four 1-D axes -> Dataset with dims (alpha, energy, h, Lz).

    With ``energy_relative=True`` the energy axis holds offsets (energy - V_min)/|V_min| from
    each (alpha, h, Lz)'s potential minimum, and ``energy_absolute`` [J] is added; where V has
    no minimum (free fall with B >= 0, or L_z = 0) the energy is undefined and the point is
    classed forbidden (out_of_range where :func:`evaluate` says so at any energy).
    ``progress(done, total)`` is called after each block of
    about ``block_points`` points (``chunk_points`` is its former name, still accepted).
    Fate maps (see :func:`evaluate`) start each orbit at its r_min.
    """
    plan = survey_plan(
        DIMS, dict(alpha=alpha, energy=energy, h=h, Lz=Lz), scene, method,
        energy_relative=energy_relative, circular_tol=circular_tol, rtol=rtol,
        horizon_time=horizon_time, horizon_revolutions=horizon_revolutions,
        block_points=block_points if chunk_points is None else chunk_points,
    )  # fmt: skip
    return run_plan(plan, progress)


def launch_survey(
    alpha: Any = None,
    r0: Any = None,
    v0: Any = None,
    w0: Any = None,
    scene: Scene | None = None,
    method: str = "exact",
    *,
    circular_tol: float = CIRCULAR_TOL,
    rtol: float = DEFAULT_RTOL,
    horizon_time: float | None = None,
    horizon_revolutions: float | None = None,
    progress: Callable[[int, int], None] | None = None,
    block_points: int = BLOCK_POINTS,
    u0: Any = 0.0,
    slip_u: Any = 0.0,
    slip_v: Any = 0.0,
    backspin: Any = None,
    surface: Surface | None = None,
    rho0: Any = None,
    z0: Any = None,
    surface_axes: dict[str, Any] | None = None,
) -> xr.Dataset:
    """A map over launch states: the sphere released at distance ``r0`` [m] from its cone's
    vertex (along the generatrix) with radial speed 0, azimuthal speed ``v0`` [m/s] and spin
    ``w0`` = a omega_nu [m/s], on cones of half-aperture ``alpha``. Dims (alpha, r0, v0, w0);
    the invariants ``energy`` (calE), ``h`` and ``Lz`` of each launch are variables
    (:func:`engine.invariants`); fate maps start each orbit at its launch point.

    On a scene with kinetic friction (``Scene.mu_k``: a slip is a transition) a launch need not
    roll: ``u0`` is its radial speed [m/s] (outward > 0) and ``slip_u``, ``slip_v`` the slip
    velocity of the contact point [m/s] along the generatrix and the parallel (0, 0: rolling;
    thrown outward without spin: slip_u = u0; backspin makes slip_u larger). Each is a number
    or a 1-D axis: an axis is a dim after (alpha, r0, v0, w0), in the order u0, slip_u,
    slip_v; a number is no axis (the same for every launch: a scalar coordinate of the map
    where it is not 0), and the invariants are those of the rolling orbit through the launch
    point with its radial speed. ``backspin`` (instead of ``slip_u``) is the slip beyond the
    radial speed, slip_u = u0 + backspin at every launch (an axis between u0 and slip_v: a
    map of speed by backspin is not sheared). Without ``mu_k`` they must be 0 (a ValueError
    names the one that is not).

    On a ``surface`` of revolution (:mod:`engine.surfaces`: ``Bowl(0.5)``, ``Funnel(0.1,
    0.02)``, ...) a launch is the centre at distance ``rho0`` [m] from the axis (the cylinder:
    at height ``z0``) with speed ``v0`` along the parallel, spin ``w0`` and no speed along the
    meridian (a turning point); ``surface_axes`` sweeps the surface's parameters (name ->
    values). Dims (the swept parameters, rho0 or z0, v0, w0); the exact map is Routh's
    reduction (docs/physics.md "Any surface of revolution"), the integrators rk45 and dop853
    serve it too."""
    scene = check_scene(scene)
    if surface is not None or rho0 is not None or z0 is not None:
        return _surface_survey(
            surface, dict(alpha=alpha, r0=r0), dict(rho0=rho0, z0=z0, v0=v0, w0=w0),
            surface_axes or {}, scene, method, circular_tol=circular_tol, rtol=rtol,
            horizon_time=horizon_time, horizon_revolutions=horizon_revolutions,
            progress=progress, block_points=block_points,
        )  # fmt: skip
    release = {"u0": u0, "slip_u": slip_u, "slip_v": slip_v}
    if backspin is not None:
        if not (np.ndim(slip_u) == 0 and check_numbers("slip_u", slip_u) == 0.0):
            raise ValueError("give slip_u or backspin (slip_u - u0), not both")
        release = {"u0": u0, "backspin": backspin, "slip_v": slip_v}
    dims = launch_dims(scene, [n for n, v in release.items() if np.ndim(v) > 0])
    values = dict(alpha=alpha, r0=r0, v0=v0, w0=w0)
    fixed: dict[str, Any] = {}
    if "sliding" not in scene.effects:  # a scene on which every launch rolls (no mu_k)
        for name, value in release.items():
            check_release(name, check_numbers(name, value), scene)
    else:
        values.update({n: release[n] for n in dims[4:]})
        fixed = {n: v for n, v in release.items() if n not in dims}
    plan = survey_plan(
        dims, values, scene, method,
        circular_tol=circular_tol, rtol=rtol, horizon_time=horizon_time,
        horizon_revolutions=horizon_revolutions, block_points=block_points, release=fixed,
    )  # fmt: skip
    return run_plan(plan, progress)


def _surface_survey(surface, cone_args, launch, surface_axes, scene, method, *, progress,
                    **options) -> xr.Dataset:  # fmt: skip
    """:func:`launch_survey` on a surface of revolution (its arguments checked here)."""
    surface = check_named_surface(
        surface, cone_args, lambda s: "is the cone's launch; on a surface give rho0 (or z0), v0, w0"
    )
    unknown = sorted(set(surface_axes) - set(surface.parameters))
    if unknown:
        has = ", ".join(surface.parameters) or "none"
        raise PlanError("surface_axes", f"{surface.kind} has the parameters {has}",
                        ", ".join(unknown))  # fmt: skip
    other = "z0" if surface.position == "rho0" else "rho0"
    if launch[other] is not None:
        raise PlanError(other, f"the {surface.kind}'s launch position is {surface.position}",
                        launch[other])  # fmt: skip
    dims = surface_dims(surface, surface_axes)
    values = {**surface_axes, surface.position: launch[surface.position], "v0": launch["v0"],
              "w0": launch["w0"]}  # fmt: skip
    for name in dims:
        if values[name] is None:
            raise PlanError(name, "is needed: the launch's values (a number or a 1-D axis)")
    plan = survey_plan(dims, values, scene, method, surface=surface, **options)
    return run_plan(plan, progress)


def run_plan(plan: RunPlan, progress: Callable[[int, int], None] | None = None) -> xr.Dataset:
    """The survey of ``plan`` (:mod:`engine.plan`) in memory, block by block, as a Dataset
    with dims ``plan.dims``; ``progress(done, total)`` after each block."""
    shape = plan.shape
    tiling = Tiling.for_grid(shape, plan.output.block_points)
    results: dict[str, np.ndarray] = {}
    done = 0
    for slices in tiling:
        block = evaluate_block(plan, slices)
        for name, arr in block.items():
            if name not in results:
                results[name] = np.empty(shape, arr.dtype)
            results[name][slices] = arr
        done += arr.size
        if progress is not None:
            progress(done, tiling.size)
    dims, kind = plan.dims, plan.map_kind
    results.update(family_values(dims, dict(zip(dims, plan.axes, strict=True)), plan.scene, kind,
                                 plan.variables))  # r_circ, V_min on fewer dims  # fmt: skip
    order = [n for n in plan.variables if n in results] + [
        n for n in results if n not in plan.variables
    ]
    data_vars = {n: (variable_dims(n, dims), results[n], variable_attrs(n, kind)) for n in order}
    coords = {
        name: (name, np.array(arr), axis_attrs(name, plan.energy_relative))
        for name, arr in zip(dims, plan.axes, strict=True)
    }
    for name, value in plan.release:  # a release value given as a number: no axis
        if value != 0.0:
            coords[name] = ((), value, axis_attrs(name, plan.energy_relative))
    return xr.Dataset(data_vars, coords=coords, attrs=plan.attrs())

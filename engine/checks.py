"""The checks of a run's inputs: one function per input, whatever the entry point.

The API (:func:`engine.survey`, :func:`engine.launch_survey`, :func:`engine.evaluate`), a
survey file (:mod:`engine.surveyfile`, :mod:`engine.surveyaxes`) and ``conesurvey run`` call
the same function for each input, so a bad value gets the same problem text wherever it comes
from; :func:`engine.plan.survey_plan` calls them all, in a fixed order. A refusal is a
:class:`PlanError` (a ValueError) naming the field and the value: the API shows ``"rtol must
lie in ...; got 0.5"``, a survey file the key path (``"s.toml: rtol: must lie in ..., got
0.5"``), and the CLI exits 2 with nothing written.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from numbers import Integral, Real
from pathlib import Path
from typing import Any

import numpy as np

from .bounds import check_launch, launch_extremes
from .errortext import PlanError, real_value, suggest
from .grid import MAX_BLOCKS, Tiling, grid_too_large
from .horizon import Horizon
from .io.codecs import check_compression
from .io.formats import OutputFormat, format_for
from .methods import METHODS, MODEL_BY_NAME, RTOL_RANGE, Method, check_model
from .methods import check_method as _registry_check_method
from .scene import Scene
from .schema import AXES, FATE_KINDS, GRID_DIMS, is_surface_grid
from .surfaces import Surface

#: Inputs whose values must be > 0: the cone's launch radius (a state's r), a surface's
#: launch distance and its parameters.
POSITIVE_AXES = ("r0", "r", "rho0", "radius", "scale", "hole", "n")

__all__ = [
    "PlanError",
    "PRECISIONS",
    "axis_problem",
    "check_axes",
    "check_block_points",
    "check_circular_tol",
    "check_energy_relative",
    "check_horizon",
    "HORIZON_HINT",
    "check_launch",
    "check_launch_axes",
    "check_launch_values",
    "check_max_steps",
    "check_method",
    "check_number",
    "check_numbers",
    "check_positive",
    "check_release",
    "check_output",
    "check_precision",
    "check_rtol",
    "check_scene",
    "check_values",
]

#: ``precision``: how the float result variables are stored (the axes stay float64; the
#: integer ones, class, status and fate, are exact either way).
PRECISIONS = ("double", "single")
# --- one validating function per input ------------------------------------------------------


def check_scene(scene: Any, *, sliding: bool = False) -> Scene:
    """The scene (None: the default :class:`Scene`); every effect of a Scene has a survey map.
    ``sliding``: where a launch is followed through its modes (``engine.story``), which needs
    kinetic friction."""
    if scene is None:
        scene = Scene()
    if not isinstance(scene, Scene):
        raise PlanError("scene", "must be an engine.Scene", scene)
    if sliding and scene.mu_k is None:
        raise PlanError(
            "scene",
            "needs kinetic friction, Scene.mu_k: a launch's story follows it through its modes "
            "(sliding, rolling again); engine.simulate follows a rolling one",
        )
    return scene


def check_surface(surface: Any) -> Surface | None:
    """The surface of revolution (None: the cone of the alpha axis)."""
    if surface is not None and not isinstance(surface, Surface):
        raise PlanError("surface", "must be a surface of engine.surfaces (Bowl(0.5), ...)",
                        surface)  # fmt: skip
    return surface


def check_named_surface(surface: Any, cone: dict[str, Any], refusal: Callable) -> Surface:
    """The surface a launch names, checked; a field of ``cone`` given: ``refusal(surface)``."""
    if surface is None:
        raise PlanError("surface", "rho0 or z0 give a launch on a surface: name it "
                        "(surface=engine.surfaces.Bowl(0.5), ...)")  # fmt: skip
    surface = check_surface(surface)
    for name, value in cone.items():
        if value is not None:
            raise PlanError(name, refusal(surface), value)
    return surface


def check_surface_fits(surface: Surface, scene: Scene) -> None:
    """A measured profile with a trough too sharp for the ball (beyond its inner edge) is
    refused: no run passes it, and nothing there is a rolling ball's orbit."""
    trough = getattr(surface, "trough", None)
    where = trough(scene.a) if trough is not None else None
    if where is not None:
        raise PlanError("surface", f"a ball of radius a = {scene.a!r} m does not fit in the "
                        f"profile's trough at rho = {where:.6g} m (its radius of curvature "
                        "there is below a): smooth the profile or take a smaller ball",
                        whole=True)  # fmt: skip


def check_surface_method(method: Method, scene: Scene) -> None:
    """The method can serve a surface of revolution (the surface model's capabilities), with
    the scene's effects."""
    try:
        check_model(method, MODEL_BY_NAME["surface"], scene)
    except ValueError as exc:
        raise PlanError("method", str(exc), method.name, whole=True) from None


def check_method(name: Any, scene: Scene, *, integrator: bool = False) -> Method:
    """The registered method ``name`` if it honours every effect of ``scene`` (a misspelt
    name gets a did-you-mean, from every method whatever the entry point); ``integrator``:
    where only an integrator can do (a trajectory, a story, a fate map's kernels)."""
    if not isinstance(name, str):
        raise PlanError("method", "must be a string, one of " + ", ".join(METHODS), name)
    if name not in METHODS:
        hint = suggest(name, tuple(METHODS))  # "; did you mean 'rk45'?" or the list again
        close = f" ({hint[2:]})" if hint.startswith("; did you mean") else ""
        raise PlanError("method", "must be one of " + ", ".join(METHODS) + close, name)
    if integrator and not METHODS[name].integrates:
        able = ", ".join(m.name for m in METHODS.values() if m.integrates)
        raise PlanError("method", f"must be an integrator, one of {able}", name)
    try:
        return _registry_check_method(name, scene)
    except ValueError as exc:  # "method 'exact' cannot honour ..."
        raise PlanError("method", str(exc), whole=True) from None


def check_rtol(rtol: Any, method: Method) -> float:
    """A relative tolerance in (0, 1); for an integrator, in its range :data:`RTOL_RANGE`."""
    r = real_value("rtol", rtol)
    if not 0.0 < r < 1.0:
        raise PlanError("rtol", "must lie in the open interval (0, 1)", rtol)
    lo, hi = RTOL_RANGE
    if method.integrates and not lo <= r <= hi:
        raise PlanError("rtol", f"must lie in [{lo:g}, {hi:g}] for the integrator {method.name}",
                        rtol)  # fmt: skip
    return r


def check_circular_tol(circular_tol: Any) -> float:
    """The relative width of the circular class: finite and >= 0."""
    t = real_value("circular_tol", circular_tol)
    if not (t >= 0.0 and math.isfinite(t)):
        raise PlanError("circular_tol", "must be finite and >= 0", circular_tol)
    return t


#: How the API asks for a horizon (the ``hint`` of :func:`check_horizon`): its keywords.
HORIZON_HINT = "give horizon_time= [s] and/or horizon_revolutions="


def check_horizon(
    kind: str, time: Any, revolutions: Any, *, hint: str = HORIZON_HINT
) -> Horizon | None:
    """The horizon of a map of ``kind`` (:func:`engine.schema.map_kind`): required for a fate
    map; None for other maps (refused if given). ``hint``: how the entry point asks for one,
    in the names of its own keys (the API's keywords; a survey file's ``[horizon]`` table)."""
    given = Horizon(time, revolutions)  # each value's rule: Horizon's own
    if kind in FATE_KINDS and not given.given:
        raise PlanError(
            "horizon",
            "is required: a fate map follows each orbit to its first terminal event (spill, "
            f"slip, rest, vertex) or a horizon: {hint}",
        )
    if kind not in FATE_KINDS and given.given:
        raise PlanError(
            "horizon",
            "applies to fate maps only (an integrator on a scene with rolling resistance, a "
            f"rim or a friction limit); this is a {kind} map",
        )
    return given if given.given else None


def check_count(name: str, value: Any, *, least: int = 0) -> int:
    """A count: an integer >= ``least`` (not a boolean, not a float)."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, Integral) or value < least:
        what = "a positive integer" if least == 1 else f"an integer >= {least}"
        raise PlanError(name, f"must be {what}", value)
    return int(value)


def check_max_steps(value: Any) -> int:
    """A step budget: an integer >= 1 (not a boolean, not a float)."""
    return check_count("max_steps", value, least=1)


def check_positive(name: str, value: Any) -> float:
    """A duration or a spacing (``t_end``, ``dt_out``): a finite number > 0."""
    v = real_value(name, value)
    if not v > 0.0:
        raise PlanError(name, "must be > 0", value)
    if not math.isfinite(v):
        raise PlanError(name, "must be finite", value)
    return v


def check_release(name: str, value: Any, scene: Scene) -> None:
    """A launch's radial speed or slip velocity (``u0``, ``slip_u``, ``slip_v``: numbers or
    arrays, checked numbers): nonzero only on a scene with kinetic friction."""
    arr = np.asarray(value, np.float64)
    if scene.mu_k is None and np.any(arr != 0.0):
        raise PlanError(
            name,
            "must be 0 without Scene.mu_k: a launch with a radial speed or a slip velocity "
            "needs kinetic friction (the sliding model); without it every launch rolls from "
            "rest radially",
            float(arr[arr != 0.0].flat[0]),
        )


def check_energy_relative(value: Any) -> bool:
    """``value`` if it is True or False (``"no"`` is not false)."""
    if not isinstance(value, bool | np.bool_):
        raise PlanError("energy_relative", "must be True or False", value)
    return bool(value)


def check_block_points(value: Any, shape: tuple[int, ...] | None = None) -> int:
    """Points per block: an integer >= 1 (not a boolean, not a float) and, on a grid of
    ``shape``, no more than :data:`engine.grid.MAX_BLOCKS` blocks."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, Integral) or value < 1:
        raise PlanError("block_points", "must be a positive integer", value)
    if shape is not None:
        tiling = Tiling.for_grid(shape, int(value))
        if tiling.nblocks > MAX_BLOCKS:
            fewer = -(-tiling.size // MAX_BLOCKS)
            raise PlanError(
                "block_points",
                f"cuts the grid into {tiling.nblocks:,} blocks of {math.prod(tiling.block):,} "
                f"points: a run lists at most {MAX_BLOCKS:,}; give --block-points {fewer} or "
                "more",
                value,
            )
    return int(value)


def check_precision(value: Any) -> str:
    """How float results are stored: one of :data:`PRECISIONS`."""
    if not isinstance(value, str) or value not in PRECISIONS:
        raise PlanError("precision", "must be one of " + ", ".join(PRECISIONS), value)
    return value


def axis_problem(name: str, x: float) -> str:
    """What is wrong with the value ``x`` on the axis ``name`` ("" if nothing): every axis is
    finite, alpha lies in (0, pi/2), a launch radius r0 is > 0. The one check of an axis
    value, for the API's arrays and a survey file's values and ranges alike."""
    if not math.isfinite(x):
        return "must be finite"
    if name == "alpha" and not 0.0 < x < math.pi / 2:
        return "must lie in the open interval (0, pi/2) [radian]"
    if name in POSITIVE_AXES and not x > 0.0:
        return f"must be > 0 [{AXES[name].units if name in AXES else 'm'}]"
    return ""


def check_numbers(name: str, value: Any) -> np.ndarray:
    """``value`` as a float64 array if it holds real numbers. Booleans, text (even ``"0.5"``),
    complex numbers and dates are not numbers; a masked array with masked values is refused
    (the engine has no masks: fill or drop them first), one without is its data."""
    data = value.values if hasattr(value, "dims") and hasattr(value, "values") else value
    if np.ma.isMaskedArray(data):
        masked = int(np.ma.count_masked(data))
        if masked:
            raise PlanError(
                name,
                f"has {masked} masked value(s); the engine does not carry masks: fill "
                "them (numpy.ma.filled) or drop them (.compressed()) first",
            )
        data = np.ma.getdata(data)
    arr = np.asarray(data)
    kind = arr.dtype.kind
    if kind == "O":
        bad = [x for x in arr.flat if isinstance(x, bool | np.bool_) or not isinstance(x, Real)]
        if bad:
            raise PlanError(name, "must hold real numbers", bad[0])
    elif kind not in "iuf":
        what = {"b": "booleans", "U": "text", "S": "bytes", "c": "complex numbers"}
        first = arr.flat[0].item() if arr.size else arr
        raise PlanError(name, f"must hold real numbers, not {what.get(kind, arr.dtype.name)}",
                        first)  # fmt: skip
    return np.asarray(arr, np.float64)


def check_number(name: str, value: Any) -> float:
    """One number of a single run (``engine.simulate``'s alpha, energy, h, Lz): what
    :func:`check_numbers` and :func:`check_values` ask of an axis's values, and a scalar."""
    arr = check_numbers(name, value)
    if arr.ndim:
        raise PlanError(name, f"must be one number, not an array of shape {arr.shape}")
    check_values(name, arr)
    return float(arr)


def check_launch_values(values: dict[str, Any], scene: Scene) -> list[np.ndarray]:
    """The launch states of ``engine.story`` and ``launch_fates`` (``values``: field -> a
    number or an array; numpy broadcasting): each value checked as a launch axis's
    (:func:`check_values`), the release by :func:`check_release`, then the launch's numbers
    within the bounds of :func:`engine.bounds.check_launch`. Returns the float64 arrays."""
    arrays = []
    for name, value in values.items():
        arr = check_numbers(name, value)
        check_values(name, arr)
        if name in ("u0", "slip_u", "slip_v"):
            check_release(name, arr, scene)
        arrays.append(arr)
    try:
        np.broadcast_shapes(*(a.shape for a in arrays))
    except ValueError:
        shapes = ", ".join(f"{n} {a.shape}" for n, a in zip(values, arrays, strict=True))
        raise PlanError("launch", f"arrays do not broadcast together: {shapes}") from None
    check_launch(dict(zip(values, arrays, strict=True)), scene)
    return arrays


def check_launch_axes(dims: tuple[str, ...], axes: tuple[np.ndarray, ...], scene: Scene) -> None:
    """A launch grid's axes (each value checked already) within the bounds of
    :func:`engine.bounds.check_launch`, at the grid's corners; an invariant grid passes."""
    if "r0" in dims:
        check_launch(launch_extremes(dims, axes), scene)


def check_values(name: str, values: np.ndarray) -> None:
    """PlanError naming the first value of ``values`` (any shape) on the axis ``name`` that
    :func:`axis_problem` refuses (vectorised: an axis may hold 10^8 points)."""
    v = np.asarray(values, np.float64)
    bad = ~np.isfinite(v)
    if name == "alpha":
        bad |= ~((v > 0.0) & (v < math.pi / 2))
    elif name in POSITIVE_AXES:
        bad |= ~(v > 0.0)
    if bad.any():
        x = float(v[bad].flat[0])
        raise PlanError(name, axis_problem(name, x), x)


def check_axes(dims: tuple[str, ...], values: dict[str, Any]) -> tuple[np.ndarray, ...]:
    """The axes ``dims`` as read-only 1-D float64 arrays: each non-empty, every value passing
    :func:`axis_problem`, the grid not too large for a run."""
    if dims not in GRID_DIMS and not is_surface_grid(dims):
        raise PlanError("dims", f"must be one of {GRID_DIMS} or a surface's launch axes", dims)
    out = []
    for name in dims:
        arr = np.array(np.atleast_1d(check_numbers(name, values[name])), np.float64)
        if arr.ndim != 1 or arr.size == 0:
            raise PlanError(name, f"must be a non-empty 1-D sequence, not of shape {arr.shape}")
        check_values(name, arr)
        arr.setflags(write=False)
        out.append(arr)
    if why := grid_too_large({n: a.size for n, a in zip(dims, out, strict=True)}):
        raise PlanError("axes", f"span too many points: {why}")
    return tuple(out)


def check_output(
    path: str | os.PathLike[str] | None,
    compression: Any,
    complevel: Any,
    output_format: Any = None,
) -> tuple[Path | None, OutputFormat, str, int | None]:
    """The output: its path (None: in memory), its format's row (:mod:`engine.io.formats`:
    ``output_format`` by name, else the one of the path's name), the compression (None: the
    format's default) and its level."""
    p = None if path is None else Path(path)
    try:
        fmt = format_for(p, output_format)
    except ValueError as exc:
        raise PlanError("output_format", str(exc), output_format, whole=True) from None
    if compression is None:
        compression = fmt.default_compression
    try:
        check_compression(compression, complevel)
    except ValueError as exc:
        name = "complevel" if str(exc).startswith("complevel") else "compression"
        raise PlanError(name, str(exc), whole=True) from None
    try:
        fmt.check_compression(compression)
    except ValueError as exc:
        raise PlanError("compression", str(exc), compression, whole=True) from None
    return p, fmt, compression, complevel

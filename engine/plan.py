"""The run plan: a survey's inputs validated once and frozen, handed to whatever runs it.

A survey reaches the engine from the API (:func:`engine.survey`, :func:`engine.launch_survey`),
from a survey file (:mod:`engine.surveyfile`) or from ``conesurvey run``; each way builds one
:class:`RunPlan` (:func:`survey_plan`; a survey file's parser: :func:`map_plan` then
:func:`grid_plan`), which the evaluation (:func:`engine.evaluation.evaluate_block`), the
backends (:mod:`engine.backends`) and the runner (:mod:`engine.runner`) take, with its output
added by :func:`plan_with_output`. Every input is checked once, by its one function in
:mod:`engine.checks`.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from .checks import (
    HORIZON_HINT,
    PlanError,
    check_axes,
    check_block_points,
    check_circular_tol,
    check_energy_relative,
    check_horizon,
    check_launch_axes,
    check_method,
    check_numbers,
    check_output,
    check_precision,
    check_rtol,
    check_scene,
    check_surface,
    check_surface_fits,
    check_surface_method,
    check_values,
)
from .grid import BLOCK_POINTS
from .horizon import Horizon
from .io.codecs import DEFAULT_COMPRESSION
from .io.formats import OutputFormat, format_for
from .kernels.geometry import CIRCULAR_TOL
from .methods import DEFAULT_RTOL, Method
from .scene import Scene
from .schema import DIMS, MAP_KINDS, map_kind, result_variables, survey_attrs

#: The title of a survey's results when none is given (a survey file's default too).
DEFAULT_TITLE = "conesurvey survey"

if TYPE_CHECKING:
    from .surfaces import Surface

__all__ = [
    "MapPlan",
    "OutputPlan",
    "PlanError",
    "RunPlan",
    "grid_plan",
    "map_plan",
    "plan_from_survey",
    "plan_with_output",
    "survey_plan",
]


# --- the plan ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class OutputPlan:
    """Where and how the results are written: ``path`` (None: an in-memory Dataset), its
    ``format`` (the row of :mod:`engine.io.formats`), ``compression``/``complevel``,
    ``precision`` (float results as float64 or float32) and ``block_points`` (points per
    block). Pickled with its format's name (a dask worker finds the row in its registry)."""

    path: Path | None = None
    format: OutputFormat = field(default_factory=format_for)
    compression: str = DEFAULT_COMPRESSION
    complevel: int | None = None
    precision: str = "double"
    block_points: int = BLOCK_POINTS

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return _output_plan, (self.path, self.format.name, self.compression, self.complevel,
                              self.precision, self.block_points)  # fmt: skip


def _output_plan(path, format_name, *rest) -> OutputPlan:
    return OutputPlan(path, format_for(name=format_name), *rest)


@dataclass(frozen=True)
class MapPlan:
    """What a map computes at each point, validated once (:func:`map_plan`): the ``scene``,
    the resolved ``method`` (its registry row), the ``map_kind`` (:func:`engine.schema.map_kind`,
    asked here and nowhere else on a run's way), ``rtol``, ``circular_tol``, the ``horizon``
    (fate maps) and the result ``variables`` (names and dtypes, in file order). The evaluation
    (:func:`engine.evaluation.evaluate_flat`) takes it as it is, re-checking nothing."""

    scene: Scene
    method: Method
    map_kind: str
    rtol: float
    circular_tol: float
    horizon: Horizon | None
    variables: dict[str, np.dtype]
    #: The surface of revolution (:mod:`engine.surfaces`; None: the cone of the axes' alpha).
    surface: Surface | None = None


@dataclass(frozen=True, eq=False)
class RunPlan(MapPlan):
    """A validated survey run, built once (:func:`survey_plan`, :func:`plan_from_survey`) and
    read by the evaluation, the backends, the runner and the writers (:mod:`engine.io`): a
    :class:`MapPlan` over the axes ``dims``, with its output and, from a survey file, its
    ``title`` and ``source_text`` (the TOML text, stored with the results); picklable (a dask
    worker gets it whole)."""

    dims: tuple[str, ...] = DIMS
    axes: tuple[np.ndarray, ...] = ()
    #: (name, value) of each release value (:data:`engine.schema.RELEASE_AXES`) given as a number,
    #: not an axis, on a launch grid of a scene with kinetic friction (absent: 0).
    release: tuple[tuple[str, float], ...] = ()
    energy_relative: bool = False
    output: OutputPlan = field(default_factory=OutputPlan)
    title: str = DEFAULT_TITLE
    source_text: str = ""

    def axis(self, name: str) -> np.ndarray:
        return self.axes[self.dims.index(name)]

    @property
    def launch(self) -> bool:
        return self.dims != DIMS

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(a.size for a in self.axes)

    @property
    def size(self) -> int:
        return math.prod(self.shape)

    def attrs(self) -> dict[str, Any]:
        """The global attributes of its results (:func:`engine.schema.survey_attrs`)."""
        attrs = survey_attrs(self.scene, self.method.name, self.circular_tol, self.rtol,
                             self.energy_relative, self.horizon, self.launch)  # fmt: skip
        if self.surface is not None:
            attrs["map_kind"] = self.map_kind
            attrs["map_description"] = MAP_KINDS[self.map_kind]
            attrs.update(self.surface.as_attrs())
            attrs["surface_rim"] = self.surface.rim_means
            attrs["grid"] = (f"launches on the surface: the centre at {self.surface.position} "
                             "with speed v0 along the parallel, spin w0 and no speed along "
                             "the meridian")  # fmt: skip
        if self.output.precision == "single":
            attrs["precision"] = "single: float results stored as float32 (~7 digits)"
        return attrs

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, RunPlan):
            return NotImplemented
        same_axes = len(self.axes) == len(other.axes) and all(
            np.array_equal(a, b) for a, b in zip(self.axes, other.axes, strict=True)
        )
        rest = ("dims", "release", "scene", "method", "map_kind", "rtol", "circular_tol",
                "horizon", "energy_relative", "variables", "output", "title",
                "source_text", "surface")  # fmt: skip
        return same_axes and all(getattr(self, n) == getattr(other, n) for n in rest)

    __hash__ = None  # type: ignore[assignment]


def map_plan(
    scene: Any = None,
    method: Any = "exact",
    *,
    circular_tol: Any = CIRCULAR_TOL,
    rtol: Any = DEFAULT_RTOL,
    horizon_time: Any = None,
    horizon_revolutions: Any = None,
    horizon_hint: str = HORIZON_HINT,
    surface: Any = None,
) -> MapPlan:
    """The plan of a map at points (:func:`engine.evaluate`; a survey file's too): each input
    checked by its one function, in this order (the first problem is raised, a
    :class:`PlanError`). ``horizon_hint``: how the caller asks for a horizon
    (:func:`engine.checks.check_horizon`). ``surface``: a surface of revolution
    (:mod:`engine.surfaces`; None: the cone of the alpha axis)."""
    scene = check_scene(scene)
    surface = check_surface(surface)
    m = check_method(method, scene)
    if surface is not None:
        check_surface_method(m, scene)
        check_surface_fits(surface, scene)
    rtol = check_rtol(rtol, m)
    circular_tol = check_circular_tol(circular_tol)
    kind = map_kind(m.name, scene, surface)
    horizon = check_horizon(kind, horizon_time, horizon_revolutions, hint=horizon_hint)
    names = result_variables(m.name, scene, surface=surface)
    return MapPlan(scene, m, kind, rtol, circular_tol, horizon, names, surface)


def survey_plan(
    dims: tuple[str, ...],
    values: dict[str, Any],
    scene: Any = None,
    method: Any = "exact",
    *,
    energy_relative: Any = False,
    circular_tol: Any = CIRCULAR_TOL,
    rtol: Any = DEFAULT_RTOL,
    horizon_time: Any = None,
    horizon_revolutions: Any = None,
    block_points: Any = BLOCK_POINTS,
    precision: Any = "double",
    out: str | os.PathLike[str] | None = None,
    compression: Any = None,
    complevel: Any = None,
    output_format: Any = None,
    title: str = DEFAULT_TITLE,
    source_text: str = "",
    release: dict[str, Any] | None = None,
    surface: Any = None,
) -> RunPlan:
    """The plan of a survey over the axes ``dims`` (one of
    :data:`engine.schema.GRID_DIMS`; on a ``surface``, :func:`engine.schema.surface_dims`)
    holding ``values``: the map's inputs (:func:`map_plan`), then every other input checked by
    its one function, in this order (the first problem is raised, a :class:`PlanError`).
    ``release``: the release values given as numbers, not axes (a launch grid of a scene with
    kinetic friction), each checked as an axis value."""
    mp = map_plan(scene, method, circular_tol=circular_tol, rtol=rtol, horizon_time=horizon_time,
                  horizon_revolutions=horizon_revolutions, surface=surface)  # fmt: skip
    energy_relative = check_energy_relative(energy_relative)
    if energy_relative and tuple(dims) != DIMS:
        raise PlanError("energy_relative", "applies to an energy axis, not to launch states")
    precision = check_precision(precision)
    path, fmt, compression, complevel = check_output(out, compression, complevel, output_format)
    check_block_points(block_points)
    axes = check_axes(tuple(dims), values)
    fixed = tuple((name, _number(name, value)) for name, value in (release or {}).items())
    check_launch_axes(tuple(dims), axes, mp.scene)
    block_points = check_block_points(block_points, tuple(a.size for a in axes))
    output = OutputPlan(path, fmt, compression, complevel, precision, block_points)
    return grid_plan(mp, tuple(dims), axes, energy_relative=energy_relative, output=output,
                     title=title, source_text=source_text, release=fixed)  # fmt: skip


def _number(name: str, value: Any) -> float:
    """``value`` of the axis ``name`` given as one number, checked as an axis value is."""
    x = np.asarray(check_numbers(name, value), np.float64)
    check_values(name, x)
    return float(x)


def grid_plan(
    mp: MapPlan,
    dims: tuple[str, ...],
    axes: tuple[np.ndarray, ...],
    *,
    energy_relative: bool = False,
    output: OutputPlan | None = None,
    title: str = DEFAULT_TITLE,
    source_text: str = "",
    release: tuple[tuple[str, float], ...] = (),
) -> RunPlan:
    """The plan of the map ``mp`` over the axes ``dims`` holding ``axes`` (read-only float64
    arrays), written as ``output`` (None: in memory, float64), with the release values
    ``release`` that are numbers, not axes. It checks nothing: every input was checked where
    it was read (:func:`survey_plan` for the API; a survey file's parser,
    :mod:`engine.surveyfile`, with its key paths), each by its one function."""
    output = OutputPlan() if output is None else output
    names = result_variables(mp.method.name, mp.scene, energy_relative, dims != DIMS, mp.surface)
    if output.precision == "single":
        names = {n: np.dtype(np.float32) if dt.kind == "f" else dt for n, dt in names.items()}
    fields = {f.name: getattr(mp, f.name) for f in dataclasses.fields(MapPlan)}
    return RunPlan(**{**fields, "variables": names}, dims=dims, axes=axes, release=release,
                   energy_relative=energy_relative, output=output, title=title,
                   source_text=source_text)  # fmt: skip


def plan_with_output(
    plan: RunPlan,
    out: str | os.PathLike[str] | None = None,
    *,
    block_points: Any = None,
    compression: Any = None,
    complevel: Any = None,
    output_format: Any = None,
) -> RunPlan:
    """``plan`` written to ``out`` (None: in memory) in blocks of ``block_points`` (None:
    :data:`engine.grid.BLOCK_POINTS`): only these output inputs are checked, by their one
    functions; the rest of the plan was checked when it was built."""
    path, fmt, compression, complevel = check_output(out, compression, complevel, output_format)
    points = BLOCK_POINTS if block_points is None else block_points
    points = check_block_points(points, plan.shape)
    output = OutputPlan(path, fmt, compression, complevel, plan.output.precision, points)
    return dataclasses.replace(plan, output=output)


class Survey(Protocol):
    """What :func:`plan_from_survey` takes: a survey file's definition
    (:class:`engine.surveydef.Survey`), whose plan was checked when the file was read."""

    @property
    def plan(self) -> RunPlan: ...


def plan_from_survey(
    survey: Survey,
    out: str | os.PathLike[str] | None = None,
    *,
    block_points: Any = None,
    compression: Any = None,
    complevel: Any = None,
    output_format: Any = None,
) -> RunPlan:
    """The plan of a survey file's :class:`engine.surveyfile.Survey` written to ``out`` (or
    in memory): the survey's own plan (:attr:`engine.surveydef.Survey.plan`, checked once,
    when the file was read) with its output (:func:`plan_with_output`)."""
    return plan_with_output(survey.plan, out, block_points=block_points,
                            compression=compression, complevel=complevel,
                            output_format=output_format)  # fmt: skip

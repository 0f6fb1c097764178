"""Read and validate a survey definition: a TOML file naming the scene, the method and four axes.

A survey evaluates every point of the grid alpha x energy x h x Lz. Example::

    title = "Precession map under gravity"   # optional, a free-text title
    method = "exact"                         # optional: exact (default), rk45, dop853, symplectic
    rtol = 1e-10                             # optional, relative tolerance of the integrators
    circular_tol = 1e-12                     # optional, relative width of the circular class
    precision = "double"                     # optional: "single" stores float32 (docs/output.md)

    [scene]                                  # optional; any field of engine.Scene
    M = 1.0                                  # mass [kg]
    g = 9.81                                 # gravity [m s-2]; 0 = free fall
    a = 0.01                                 # sphere radius [m]
    k = 0.4                                  # inertia factor I/(M a^2)
    rim = 50.0                               # slant length of the rim [m]; absent = infinite cone

    [axes.alpha]                             # half-aperture [radian], each in (0, pi/2)
    values = [0.3, 0.6]

    [axes.energy]                            # radial energy [J]
    start = 1e-6
    stop = 10.0
    num = 50
    scale = "log"
    relative_to = "V_min"                    # values are (energy - V_min) / |V_min| [1]

    [axes.h]                                 # spin invariant [m s-1]
    values = [-2.0, 0.0, 2.0]

    [axes.Lz]                                # angular momentum about the axis [kg m2 s-1]
    start = 0.1
    stop = 1.0
    num = 10

Instead of the invariants (energy, h, Lz) a survey may span launch states: ``[axes.r0]`` (the
launch radius [m], > 0), ``[axes.v0]`` (speed along the parallel [m s-1]) and ``[axes.w0]``
(spin a omega_nu [m s-1]), the sphere released with radial speed 0; the invariants of each
launch are then stored as variables. A fate map (an integrator on a scene with rolling
resistance, a rim or a friction limit) needs a horizon::

    [horizon]
    time = 30.0                              # [s], and/or
    revolutions = 100                        # about the axis

Each of the four axes is required and is given either as ``values = [...]`` (a non-empty list
of distinct finite numbers, in the order they should appear) or as a range: ``start``, ``stop``
(both included) and ``num`` (a positive integer, at most ``MAX_AXIS_POINTS``; ``num = 1`` needs
``start == stop``, and the points must be distinct doubles), with ``scale = "linear"`` (the
default) or ``"log"`` (geometric; start, stop > 0); ``relative_to = "V_min"``: energy only.

Numbers are TOML integers or floats (booleans are not). Every problem is a :class:`SurveyError`
naming the file, the key path (``axes.alpha.values[1]``) and the value (did-you-mean for keys).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from .checks import PlanError, check_launch_axes, check_precision, check_release
from .errortext import toml_repr, toml_type
from .grid import grid_too_large
from .io.atomic import read_regular
from .kernels.geometry import CIRCULAR_TOL as DEFAULT_CIRCULAR_TOL
from .methods import DEFAULT_RTOL
from .plan import MapPlan, OutputPlan, grid_plan, map_plan
from .scene import Scene
from .schema import DIMS as AXES
from .schema import LAUNCH_DIMS, RELEASE_AXES, launch_dims, surface_dims
from .surfaces import Surface
from .surveyaxes import MAX_AXIS_POINTS, RELATIVE_TO, SCALES, AxisReader, frozen
from .surveydef import Survey
from .surveyhelp import HORIZON_KEYS, TOP_KEYS
from .surveysurface import read_surface

__all__ = [
    "AXES",
    "LAUNCH_DIMS",
    "MAX_AXIS_POINTS",
    "RELATIVE_TO",
    "SCALES",
    "Survey",
    "SurveyError",
    "load_survey",
    "parse_survey",
]

DEFAULT_METHOD = "exact"
#: Largest survey file read [bytes] (``values`` lists of ~10^5 numbers fit).
MAX_SURVEY_BYTES = 4 << 20

_TOP_KEYS = tuple(TOP_KEYS)  # the keys run --help lists (engine.surveyhelp), no other
_HORIZON_KEYS = tuple(HORIZON_KEYS)
#: Key paths of the plan's fields that a survey file spells otherwise.
_KEYS = {"horizon_time": "horizon.time", "horizon_revolutions": "horizon.revolutions"}
#: How a survey file asks for a horizon (:func:`engine.checks.check_horizon`'s ``hint``).
_HORIZON_HINT = "add a [horizon] table with time = SECONDS and/or revolutions = N"
_SCENE_FIELDS = tuple(f.name for f in dataclasses.fields(Scene) if not f.name.startswith("_"))


class SurveyError(ValueError):
    """A survey definition that cannot be run; the message names the key path and the value.

    Attributes
    ----------
    origin : where the text came from (a file name or ``"<string>"``).
    key : the key path of the problem (``"axes.alpha.values[1]"``), ``""`` for the whole file.
    problem : the message without origin and key.
    """

    def __init__(self, origin: str, key: str, problem: str) -> None:
        self.origin = origin
        self.key = key
        self.problem = problem
        where = f"{origin}: {key}" if key else origin
        super().__init__(f"{where}: {problem}")


def load_survey(path: str | os.PathLike[str]) -> Survey:
    """Read and validate the survey definition in the TOML file ``path``.

    Raises :class:`SurveyError` for an invalid definition (a file that is not UTF-8 text, or
    larger than ``MAX_SURVEY_BYTES``) and :class:`OSError` (e.g. ``FileNotFoundError``) when
    the file cannot be read; a FIFO, a device or a directory raises
    :class:`engine.io.atomic.NotRegularFile` (an OSError) without being read.
    """
    p = Path(path)
    try:
        data = read_regular(p, MAX_SURVEY_BYTES)
    except ValueError:
        raise SurveyError(
            str(p),
            "",
            f"larger than {MAX_SURVEY_BYTES >> 20} MiB: not a survey definition "
            "(give long axes as start, stop and num)",
        ) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SurveyError(
            str(p), "", f"not UTF-8 text ({exc.reason} at byte {exc.start})"
        ) from None
    return parse_survey(text, origin=str(p))


def parse_survey(text: str, *, origin: str = "<string>") -> Survey:
    """Parse and validate a survey definition given as TOML text.

    ``origin`` names the text's source in error messages. Raises :class:`SurveyError`.
    """
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SurveyError(origin, "", f"malformed TOML: {exc}") from None
    except RecursionError:  # tomllib recurses once per level of nested arrays/inline tables
        raise SurveyError(
            origin, "", "malformed TOML: arrays or tables nested too deeply"
        ) from None
    return _Reader(origin).survey(doc, text)


# --- validation -----------------------------------------------------------------------------


def _counts(axes: dict, dims: tuple[str, ...]) -> dict[str, int]:
    """Points per axis as the tables give them, without building any axis (an axis whose
    count is not yet known is left out: reading it reports the problem)."""
    out: dict[str, int] = {}
    for name in dims:
        table = axes.get(name)
        if not isinstance(table, dict):
            continue
        values, num = table.get("values"), table.get("num")
        if isinstance(values, list):
            out[name] = len(values)
        elif isinstance(num, int) and not isinstance(num, bool) and 1 <= num <= MAX_AXIS_POINTS:
            out[name] = num
    return out


class _Reader(AxisReader):
    """Validates a parsed TOML document, raising :class:`SurveyError` at the first problem."""

    def __init__(self, origin: str) -> None:
        self.origin = origin

    def fail(self, key: str, problem: str) -> SurveyError:
        return SurveyError(self.origin, key, problem)

    # -- sections --

    def survey(self, doc: dict, text: str) -> Survey:
        self.check_keys(doc, _TOP_KEYS, "")
        title = self.string(doc.get("title", "conesurvey survey"), "title")
        if "\0" in title:
            raise self.bad_value("title", title, "must not contain NUL (netCDF text ends there)")
        scene = self.scene(self.table(doc, "scene", "", required=False) or {})
        if "surface" in doc:
            return self.surface_survey(doc, text, title, scene)
        mp = self.map(doc, scene)
        axes = self.table(doc, "axes", "", required=True)
        launch = any(n in axes for n in (*LAUNCH_DIMS[1:], *RELEASE_AXES))
        if "backspin" in axes and "slip_u" in axes:
            raise self.fail("axes.backspin", "give slip_u or backspin (slip_u - u0), not both")
        dims = launch_dims(mp.scene, axes) if launch else AXES
        other = AXES if launch else (*LAUNCH_DIMS, *RELEASE_AXES)
        for name in axes:
            if name in other and name not in dims:
                raise self.fail(
                    f"axes.{name}",
                    "a survey spans invariants (alpha, energy, h, Lz) or launch states "
                    "(alpha, r0, v0, w0), not both",
                )
        release = [n for n in RELEASE_AXES if n in axes and n not in dims]  # a scene without mu_k
        self.check_keys(axes, (*dims, *release), "axes")
        for name in dims:
            if name not in axes and name not in RELEASE_AXES:
                sets = "alpha, energy, h, Lz (invariants) or alpha, r0, v0, w0 (launch states)"
                raise self.fail(f"axes.{name}", f"missing; give every axis of {sets}")
        if why := grid_too_large(_counts(axes, dims)):  # before any axis is built
            raise self.fail("axes", why)
        arrays: dict[str, Any] = {
            name: self.axis(axes, name) if name in axes else frozen(np.zeros(1)) for name in dims
        }
        for name in release:
            self.rolling_release(self.axis(axes, name), name)
        with self.checked("axes."):  # a launch grid's numbers within a run's range
            check_launch_axes(dims, tuple(arrays[name] for name in dims), mp.scene)
        energy_relative = "relative_to" in axes.get("energy", {})
        with self.checked():
            precision = check_precision(doc.get("precision", "double"))
        axes_read = tuple(arrays[name] for name in dims)
        plan = grid_plan(mp, dims, axes_read, energy_relative=energy_relative,
                         output=OutputPlan(precision=precision), title=title,
                         source_text=text)  # fmt: skip
        return Survey.from_plan(plan)

    def surface_survey(self, doc: dict, text: str, title: str, scene: Scene) -> Survey:
        """A survey over launches on the ``[surface]`` table's surface
        (:mod:`engine.surveysurface`)."""
        axes = self.table(doc, "axes", "", required=True)
        table = self.table(doc, "surface", "", required=True)
        surface, swept = read_surface(self, table, axes, self.origin)
        mp = self.map(doc, scene, surface)
        dims = surface_dims(surface, swept)
        self.check_keys(axes, dims, "axes")
        for name in dims:
            if name not in axes:
                raise self.fail(f"axes.{name}", f"missing; a launch on the {surface.kind} "
                                f"gives {', '.join(dims)}")  # fmt: skip
        if why := grid_too_large(_counts(axes, dims)):
            raise self.fail("axes", why)
        with self.checked():
            precision = check_precision(doc.get("precision", "double"))
        plan = grid_plan(mp, dims, tuple(self.axis(axes, name) for name in dims),
                         output=OutputPlan(precision=precision), title=title,
                         source_text=text)  # fmt: skip
        return Survey.from_plan(plan)

    def rolling_release(self, values: np.ndarray, name: str) -> None:
        """An axis of the release (u0, slip_u, slip_v) on a scene without kinetic friction:
        refused unless every value is 0 (every launch rolls from rest radially there)."""
        with self.checked("axes."):
            check_release(name, values, Scene())

    def map(self, doc: dict, scene: Scene, surface: Surface | None = None) -> MapPlan:
        """The map's inputs (method, rtol, circular_tol, ``[horizon]``) through the API's one
        set of checks (:func:`engine.plan.map_plan`), each value checked once, there; a
        missing horizon is asked for in the file's words (its ``[horizon]`` table)."""
        horizon = self.table(doc, "horizon", "", required=False) or {}
        self.check_keys(horizon, _HORIZON_KEYS, "horizon")
        with self.checked():
            return map_plan(scene, doc.get("method", DEFAULT_METHOD),
                            circular_tol=doc.get("circular_tol", DEFAULT_CIRCULAR_TOL),
                            rtol=doc.get("rtol", DEFAULT_RTOL),
                            horizon_time=horizon.get("time"),
                            horizon_revolutions=horizon.get("revolutions"),
                            horizon_hint=_HORIZON_HINT, surface=surface)  # fmt: skip

    @contextlib.contextmanager
    def checked(self, table: str = "") -> Iterator[None]:
        """A :class:`engine.checks.PlanError` as a SurveyError at the field's key path (in
        ``table``: "axes." for an axis)."""
        try:
            yield
        except PlanError as exc:
            key = table + _KEYS.get(exc.field, exc.field).replace("Scene.", "scene.")
            problem = exc.problem
            if exc.has_value:
                problem += f", got {toml_repr(exc.value)}"
            raise self.fail(key, problem) from None

    def scene(self, table: dict) -> Scene:
        self.check_keys(table, _SCENE_FIELDS, "scene")
        kwargs: dict[str, Any] = {}
        for field in dataclasses.fields(Scene):
            if field.name not in table:
                continue
            key = f"scene.{field.name}"
            value = table[field.name]
            if isinstance(field.default, bool):
                if not isinstance(value, bool):
                    raise self.fail(
                        key, f"must be true or false, got {toml_type(value)} {toml_repr(value)}"
                    )
                kwargs[field.name] = value
            else:
                kwargs[field.name] = self.number(value, key)
        try:
            scene = Scene(**kwargs)
        except ValueError as exc:
            m = re.search(r"Scene\.(\w+)", str(exc))
            name = m.group(1) if m else ""
            key = f"scene.{name}" if name else "scene"
            message = str(exc)
            if m:  # "Scene.M must be > 0, got -1.0" -> "must be > 0, got -1.0"
                message = message[m.end() :].strip()
            raise self.fail(key, message) from None
        return scene  # checked by its constructor; map_plan checks it is a Scene

"""Read and validate a survey definition: a TOML file naming the scene, the method and four axes.

A survey evaluates every point of the grid alpha x energy x h x Lz. Example::

    title = "Precession map under gravity"   # optional, a free-text title
    method = "exact"                         # optional: exact (default), rk45, dop853, symplectic
    rtol = 1e-10                             # optional, relative tolerance of the integrators
    circular_tol = 1e-12                     # optional, relative width of the circular class

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

Each of the four axes is required and is given either as ``values = [...]`` (a non-empty list
of distinct finite numbers, in the order they should appear) or as a range: ``start``, ``stop``
(both included) and ``num`` (a positive integer, at most ``MAX_AXIS_POINTS``; ``num = 1`` needs
``start == stop``, and the points must be distinct doubles), with
``scale = "linear"`` (the default) or ``"log"`` (geometric spacing; start and stop > 0).
``relative_to = "V_min"`` is allowed on the energy axis only.

Numbers may be written as TOML integers or floats; booleans are not numbers. Every problem is
reported as a :class:`SurveyError` naming the file, the key path (``axes.alpha.values[1]``) and
the offending value; unknown keys come with a did-you-mean suggestion.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .api import survey as api_survey
from .errortext import TomlChecker, toml_repr, toml_type
from .io.atomic import read_regular
from .kernels.geometry import CIRCULAR_TOL as DEFAULT_CIRCULAR_TOL
from .methods import DEFAULT_RTOL, METHODS, RTOL_RANGE, check_method, check_rtol
from .scene import Scene
from .schema import DIMS as AXES

if TYPE_CHECKING:
    import xarray as xr

__all__ = [
    "AXES",
    "Survey",
    "SurveyError",
    "load_survey",
    "parse_survey",
]

#: Accepted values of ``axes.energy.relative_to``.
RELATIVE_TO = ("V_min",)
SCALES = ("linear", "log")

DEFAULT_METHOD = "exact"
#: Largest ``num`` of a range axis (the axes are held in memory: 8 bytes a point).
MAX_AXIS_POINTS = 10**8
#: Largest survey file read [bytes] (``values`` lists of ~10^5 numbers fit).
MAX_SURVEY_BYTES = 4 << 20

_TOP_KEYS = ("title", "method", "rtol", "circular_tol", "scene", "axes")
_RANGE_KEYS = ("start", "stop", "num", "scale")
_AXIS_KEYS = ("values", *_RANGE_KEYS)
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


@dataclass(frozen=True, eq=False)
class Survey:
    """A validated survey definition.

    The axes are read-only 1-D float64 arrays: ``alpha`` [radian], ``energy`` [J] (or, when
    ``energy_relative``, the dimensionless offsets (energy - V_min)/|V_min|), ``h`` [m s-1] and
    ``Lz`` [kg m2 s-1]. ``source_text`` is the TOML text verbatim, stored with the results.
    """

    title: str
    method: str
    rtol: float
    circular_tol: float
    scene: Scene
    alpha: np.ndarray
    energy: np.ndarray
    h: np.ndarray
    Lz: np.ndarray
    energy_relative: bool
    source_text: str

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """Grid shape (alpha, energy, h, Lz)."""
        return (self.alpha.size, self.energy.size, self.h.size, self.Lz.size)

    @property
    def size(self) -> int:
        """Number of grid points."""
        return math.prod(self.shape)

    def to_toml_text(self) -> str:
        """The definition as TOML: the source text verbatim (comments included)."""
        return self.source_text

    def run(self, progress: Callable[[int, int], None] | None = None) -> xr.Dataset:
        """Evaluate the survey with :func:`engine.survey`; ``progress(done, total)`` per chunk."""
        return api_survey(
            self.alpha,
            self.energy,
            self.h,
            self.Lz,
            scene=self.scene,
            method=self.method,
            energy_relative=self.energy_relative,
            circular_tol=self.circular_tol,
            rtol=self.rtol,
            progress=progress,
        )


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


class _Reader(TomlChecker):
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
        method = self.choice(doc.get("method", DEFAULT_METHOD), "method", tuple(METHODS))
        rtol = self.number(doc.get("rtol", DEFAULT_RTOL), "rtol")
        if not 0.0 < rtol < 1.0:
            raise self.bad_value("rtol", doc["rtol"], "must lie in the open interval (0, 1)")
        circular_tol = self.number(doc.get("circular_tol", DEFAULT_CIRCULAR_TOL), "circular_tol")
        if circular_tol < 0.0:
            raise self.bad_value("circular_tol", doc["circular_tol"], "must be >= 0")
        scene = self.scene(self.table(doc, "scene", "", required=False) or {})
        self.method_for(method, scene, rtol, doc.get("rtol", DEFAULT_RTOL))
        axes = self.table(doc, "axes", "", required=True)
        self.check_keys(axes, AXES, "axes")
        for name in AXES:
            if name not in axes:
                raise self.fail(
                    f"axes.{name}", "missing; every axis of alpha, energy, h, Lz is required"
                )
        arrays = {name: self.axis(axes, name) for name in AXES}
        energy_relative = "relative_to" in axes["energy"]
        return Survey(
            title=title,
            method=method,
            rtol=rtol,
            circular_tol=circular_tol,
            scene=scene,
            energy_relative=energy_relative,
            source_text=text,
            **arrays,
        )

    def method_for(self, method: str, scene: Scene, rtol: float, raw_rtol: Any) -> None:
        """The checks ``run`` makes (engine.methods): the method honours the scene's effects,
        and an integrator's rtol lies in the registry's range."""
        try:
            integrates = check_method(method, scene).integrates
        except ValueError as exc:
            raise self.fail("method", str(exc)) from None
        if integrates:
            try:
                check_rtol(rtol)
            except ValueError:
                lo, hi = RTOL_RANGE
                raise self.bad_value(
                    "rtol", raw_rtol, f"must lie in [{lo:g}, {hi:g}] for the integrator {method}"
                ) from None

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
            return Scene(**kwargs)
        except ValueError as exc:
            m = re.search(r"Scene\.(\w+)", str(exc))
            name = m.group(1) if m else ""
            key = f"scene.{name}" if name else "scene"
            message = str(exc)
            if m:  # "Scene.M must be > 0, got -1.0" -> "must be > 0, got -1.0"
                message = message[m.end() :].strip()
            raise self.fail(key, message) from None

    def axis(self, axes: dict, name: str) -> np.ndarray:
        path = f"axes.{name}"
        table = self.table(axes, name, "axes", required=True)
        assert table is not None
        allowed = _AXIS_KEYS + (("relative_to",) if name == "energy" else ())
        for key in table:
            if key == "relative_to" and name != "energy":
                raise self.fail(f"{path}.relative_to", "only allowed on axes.energy")
        self.check_keys(table, allowed, path)
        if "relative_to" in table:
            self.choice(table["relative_to"], f"{path}.relative_to", RELATIVE_TO)

        range_keys = [k for k in _RANGE_KEYS if k in table]
        if "values" in table:
            if range_keys:
                raise self.fail(
                    f"{path}.{range_keys[0]}",
                    "give either values = [...] or start/stop/num, not both",
                )
            values = self.values(table["values"], f"{path}.values")
            if name == "alpha":
                for i, x in enumerate(values):
                    self.check_alpha(x, f"{path}.values[{i}]", table["values"][i])
            return values
        if not range_keys:
            raise self.fail(path, "give either values = [...] or start, stop and num")
        for key in ("start", "stop", "num"):
            if key not in table:
                raise self.fail(f"{path}.{key}", "missing (a range needs start, stop and num)")
        start = self.number(table["start"], f"{path}.start")
        stop = self.number(table["stop"], f"{path}.stop")
        num = table["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise self.bad_value(f"{path}.num", num, "must be a positive integer")
        if num > MAX_AXIS_POINTS:
            raise self.bad_value(f"{path}.num", num, f"must be <= {MAX_AXIS_POINTS:.0e} per axis")
        scale = self.choice(table.get("scale", "linear"), f"{path}.scale", SCALES)
        if name == "alpha":
            self.check_alpha(start, f"{path}.start", table["start"])
            self.check_alpha(stop, f"{path}.stop", table["stop"])
        if num == 1 and start != stop:
            raise self.bad_value(f"{path}.num", num, "must be > 1 when start != stop")
        if num > 1 and start == stop:
            raise self.bad_value(
                f"{path}.stop", table["stop"], "must differ from start when num > 1"
            )
        if scale == "log":
            for key, x in (("start", start), ("stop", stop)):
                if x <= 0.0:
                    raise self.bad_value(
                        f"{path}.{key}", table[key], 'must be > 0 with scale = "log"'
                    )
            with np.errstate(over="ignore"):  # 10**log10(stop) may round above DBL_MAX
                grid = np.geomspace(start, stop, num)
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                grid = np.linspace(start, stop, num)
            if not np.isfinite(grid).all():  # stop - start overflowed: halve, exactly
                grid = np.linspace(0.5 * start, 0.5 * stop, num) * 2.0
        grid[0], grid[-1] = start, stop  # exact end points (geomspace rounds them)
        steps = np.diff(grid)
        if not ((steps > 0.0).all() or (steps < 0.0).all()):
            raise self.bad_value(
                f"{path}.num",
                num,
                "is more points than there are distinct doubles between start and stop",
            )
        return _frozen(grid)

    def values(self, value: Any, key: str) -> np.ndarray:
        if not isinstance(value, list):
            raise self.fail(
                key, f"must be an array of numbers, got {toml_type(value)} {toml_repr(value)}"
            )
        if not value:
            raise self.fail(key, "must not be empty")
        out = np.array(
            [self.number(v, f"{key}[{i}]") for i, v in enumerate(value)], dtype=np.float64
        )
        seen: dict[float, int] = {}
        for i, x in enumerate(out.tolist()):
            if x in seen:
                raise self.bad_value(f"{key}[{i}]", value[i], f"duplicates {key}[{seen[x]}]")
            seen[x] = i
        return _frozen(out)

    def check_alpha(self, x: float, key: str, raw: Any) -> None:
        if not 0.0 < x < math.pi / 2:
            raise self.bad_value(key, raw, "alpha must lie in the open interval (0, pi/2) [radian]")


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    a.setflags(write=False)
    return a

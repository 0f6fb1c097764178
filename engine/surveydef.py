"""The validated survey definition (:class:`Survey`, what :func:`engine.surveyfile.load_survey`
returns): its grid (dims, shape), its run plan (built once, when the file was read), the
variables and global attributes of its results, and its evaluation in memory through the API."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .api import run_plan
from .fates import Horizon
from .plan import RunPlan, survey_plan
from .precision import stored
from .scene import Scene
from .schema import DIMS, LAUNCH_DIMS, RELEASE_AXES

if TYPE_CHECKING:
    import xarray as xr

    from .surfaces import Surface

__all__ = ["Survey"]


@dataclass(frozen=True, eq=False)
class Survey:
    """A validated survey definition.

    The axes are read-only 1-D float64 arrays: ``alpha`` [radian], ``energy`` [J] (or, when
    ``energy_relative``, the dimensionless offsets (energy - V_min)/|V_min|), ``h`` [m s-1] and
    ``Lz`` [kg m2 s-1]; or, over launch states, ``r0`` [m], ``v0`` and ``w0`` [m s-1] (and on
    a scene with kinetic friction ``u0``, ``slip_u`` and ``slip_v`` [m s-1], or ``backspin``
    = slip_u - u0 instead of ``slip_u``). ``source_text``
    is the TOML text verbatim, stored with the results.
    """

    title: str
    method: str
    rtol: float
    circular_tol: float
    scene: Scene
    alpha: np.ndarray | None
    energy: np.ndarray | None
    h: np.ndarray | None
    Lz: np.ndarray | None
    energy_relative: bool
    source_text: str
    r0: np.ndarray | None = None
    v0: np.ndarray | None = None
    w0: np.ndarray | None = None
    horizon: Horizon | None = None
    precision: str = "double"
    u0: np.ndarray | None = None
    slip_u: np.ndarray | None = None
    slip_v: np.ndarray | None = None
    backspin: np.ndarray | None = None
    #: A survey over launches on a surface of revolution: the surface, and its axes by name
    #: (``engine.schema.surface_dims``); alpha, energy, h, Lz are then None.
    surface: Surface | None = None
    surface_axes: dict[str, np.ndarray] | None = None
    # the plan the parser built, each value checked once (not copied by dataclasses.replace)
    _plan: RunPlan | None = field(default=None, init=False, repr=False, compare=False)

    @classmethod
    def from_plan(cls, plan: RunPlan) -> Survey:
        """The survey of a checked plan (a survey file's, :mod:`engine.surveyfile`), keeping
        it: reading its plan, variables or attributes, or running it, checks nothing again."""
        axes: dict[str, Any] = dict(zip(plan.dims, plan.axes, strict=True))
        if plan.surface is not None:
            axes = dict(alpha=None, energy=None, h=None, Lz=None, surface=plan.surface,
                        surface_axes=axes)  # fmt: skip
        elif plan.launch:
            axes.update(energy=None, h=None, Lz=None)
        survey = cls(title=plan.title, method=plan.method.name, rtol=plan.rtol,
                     circular_tol=plan.circular_tol, scene=plan.scene,
                     energy_relative=plan.energy_relative, source_text=plan.source_text,
                     horizon=plan.horizon, precision=plan.output.precision, **axes)  # fmt: skip
        object.__setattr__(survey, "_plan", plan)  # frozen: set once, here
        return survey

    @property
    def plan(self) -> RunPlan:
        """Its run plan, output in memory: the one its survey file's parser built (every value
        checked there, once, naming the file's keys) or, for a Survey made in Python
        (``dataclasses.replace``), the one the API's checks build
        (:func:`engine.plan.survey_plan`), kept for the next call."""
        if self._plan is None:
            horizon = self.horizon or Horizon()
            values = self.surface_axes or {d: getattr(self, d) for d in self.dims}
            plan = survey_plan(self.dims, values, self.scene,
                               self.method, energy_relative=self.energy_relative,
                               circular_tol=self.circular_tol, rtol=self.rtol,
                               horizon_time=horizon.time,
                               horizon_revolutions=horizon.revolutions,
                               precision=self.precision, title=self.title,
                               source_text=self.source_text, surface=self.surface)  # fmt: skip
            object.__setattr__(self, "_plan", plan)
        return self._plan

    @property
    def dims(self) -> tuple[str, ...]:
        """The survey's axes: (alpha, energy, h, Lz), or (alpha, r0, v0, w0) over launch
        states, then those of (u0, slip_u or backspin, slip_v) it has (a scene with kinetic
        friction: the release's radial speed and slip velocity, backspin = slip_u - u0; one
        without an axis is 0); on a surface, its launch axes."""
        if self.surface_axes is not None:
            return tuple(self.surface_axes)
        if not self.launch:
            return DIMS
        return (*LAUNCH_DIMS, *(n for n in RELEASE_AXES if getattr(self, n) is not None))

    @property
    def shape(self) -> tuple[int, ...]:
        """Grid shape, in the order of :attr:`dims`."""
        axes = self.surface_axes or {d: getattr(self, d) for d in self.dims}
        return tuple(axes[d].size for d in self.dims)

    @property
    def size(self) -> int:
        """Number of grid points."""
        return math.prod(self.shape)

    @property
    def launch(self) -> bool:
        """A survey over launch states (its dims are alpha, r0, v0, w0, or a surface's)."""
        return self.r0 is not None or self.surface_axes is not None

    def variables(self) -> dict[str, np.dtype]:
        """Names and dtypes of the result variables, in file order (its plan's: the float ones
        float32 with ``precision = "single"``)."""
        return self.plan.variables

    def attrs(self) -> dict[str, Any]:
        """The global attributes of its results (its plan's, :meth:`engine.plan.RunPlan.attrs`:
        :func:`engine.schema.survey_attrs`, and ``precision`` where it is single)."""
        return self.plan.attrs()

    def run(self, progress: Callable[[int, int], None] | None = None) -> xr.Dataset:
        """Evaluate the survey in memory (its plan, :attr:`plan`, run by
        :func:`engine.api.run_plan`); ``progress(done, total)`` per block."""
        plan = self.plan
        ds = run_plan(plan, progress)
        for name, dt in plan.variables.items():
            if name in ds and ds[name].dtype != dt:
                ds[name] = ds[name].copy(data=stored(name, ds[name].values, dt))
        return ds

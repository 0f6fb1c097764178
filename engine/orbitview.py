"""One orbit to draw (``conesurvey orbit``, ``ds.cone.orbit``, the report's sample orbits): an
(E, h, L_z) orbit, a launch (alpha, r0, v0, w0 and, on a scene with ``mu_k``, its radial speed
and slip or backspin), or the point of a survey nearest to the values asked, integrated by
:func:`engine.simulate` (from r_min, or from the launch point r0), with the closed form of the
same orbit on the ideal cone (its turning points, period and class) to draw it against.

No matplotlib here: :mod:`engine.orbitplot` draws an :class:`Orbit`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from .api import evaluate, minimum_energy
from .launch import invariants
from .mapspec import LookError
from .methods import get_method
from .scene import Scene
from .schema import DIMS, grid_dims
from .simulate import simulate
from .surveyfile import parse_survey

__all__ = [
    "DEFAULT_PERIODS",
    "DEFAULT_SAMPLES",
    "MAX_SAMPLES",
    "Orbit",
    "orbit",
    "orbit_at",
    "orbit_of_result",
    "scene_from_attrs",
]

#: Radial periods drawn of a bounded orbit when no duration is asked for.
DEFAULT_PERIODS = 6
#: Samples of the trajectory drawn (equally spaced in time), and the most that may be asked.
DEFAULT_SAMPLES = 1200
MAX_SAMPLES = 200_000
#: The method and tolerance of an orbit of a survey whose method is the closed form.
DRAW_METHOD, DRAW_RTOL = "dop853", 1e-10
#: An orbit without a radial period (escaping, spilling) is followed, when no duration is
#: asked for, for this many times r_min / v(r_min) (its time to cross a few r_min).
NO_PERIOD_SPANS = 4.0


@dataclass(frozen=True)
class Orbit:
    """A trajectory (``traj``: :func:`engine.simulate`'s Dataset) and the closed form of its
    orbit on the ideal cone: ``r_min``, ``r_max`` [m] (inf: it escapes), ``period`` [s] (NaN:
    none), ``orbit_class``; ``rim_r``: the radius [m] at which the centre spills (None: an
    infinite cone); ``label``: what was asked, in words."""

    traj: xr.Dataset
    alpha: float
    scene: Scene
    energy: float
    h: float
    Lz: float
    r_min: float
    r_max: float
    period: float
    orbit_class: str
    rim_r: float | None
    label: str

    @property
    def sliding(self) -> bool:
        """Whether the trajectory has modes (a scene with ``mu_k``)."""
        return "mode" in self.traj

    @property
    def has_attitude(self) -> bool:
        return "quat_w" in self.traj


def _ideal(scene: Scene) -> Scene:
    """The scene's cone without its losses: the closed form's reference (its rim and friction
    limit kept: they set the class)."""
    return Scene(M=scene.M, g=scene.g, a=scene.a, k=scene.k, rim=scene.rim, mu=scene.mu)


def orbit(
    alpha: float,
    energy: float | None = None,
    h: float | None = None,
    Lz: float | None = None,
    *,
    r0: float | None = None,
    v0: float | None = None,
    w0: float | None = None,
    u0: float = 0.0,
    slip_u: float | None = None,
    slip_v: float = 0.0,
    backspin: float | None = None,
    scene: Scene | None = None,
    method: str = DRAW_METHOD,
    rtol: float = DRAW_RTOL,
    t_end: float | None = None,
    periods: int | None = None,
    samples: int = DEFAULT_SAMPLES,
    attitude: bool = False,
) -> Orbit:
    """The :class:`Orbit` of the invariants (``energy``, ``h``, ``Lz``), started at r_min, or
    of the launch (``r0``, ``v0``, ``w0``; ``u0``, ``slip_u`` or ``backspin`` = slip_u - u0,
    ``slip_v`` on a scene with ``mu_k``), started at r0. ``t_end`` [s] or ``periods`` (radial
    periods) say how long; by default :data:`DEFAULT_PERIODS` periods of a bounded orbit on a
    scene without losses, else ``t_end`` that many closed-form periods (an orbit without one:
    :data:`NO_PERIOD_SPANS` times r_min / v(r_min)). ``attitude``: integrate the sphere's
    orientation too (for the spin mark of an animation; not on a sliding scene). ValueError
    (LookError) for what cannot be drawn."""
    scene = Scene() if scene is None else scene
    if attitude and scene.mu_k is None and not scene.attitude:
        scene = dataclasses.replace(scene, attitude=True)
    samples = int(samples)
    if not 2 <= samples <= MAX_SAMPLES:
        raise LookError(f"samples must be in 2..{MAX_SAMPLES:,}; got {samples}")
    launch = r0 is not None
    if launch:
        if energy is not None or h is not None or Lz is not None:
            raise LookError("give an orbit (energy, h, Lz) or a launch (r0, v0, w0), not both")
        if v0 is None or w0 is None:
            raise LookError("a launch needs r0, v0 and w0")
        if backspin is not None and slip_u is not None:
            raise LookError("give slip_u or backspin (slip_u - u0), not both")
        slip_u = u0 + backspin if backspin is not None else (slip_u or 0.0)
        inv = invariants(alpha, r0, u0, v0, w0, scene)
        h, Lz = float(inv["h"]), float(inv["Lz"])
        energy = float(inv["energy"]) - 0.5 * scene.M * u0 * u0  # as a launch map computes it
        label = f"launch alpha = {alpha:.4g}, r0 = {r0:.4g} m, v0 = {v0:.4g} m/s, w0 = {w0:.4g}"
        if scene.mu_k is not None:
            label += f", u0 = {u0:.4g}, slip ({slip_u:.4g}, {slip_v:.4g}) m/s"
    else:
        if energy is None or h is None or Lz is None:
            raise LookError("give an orbit (energy, h, Lz) or a launch (r0, v0, w0)")
        label = f"orbit alpha = {alpha:.4g}, energy = {energy:.6g} J, h = {h:.4g} m/s, "
        label += f"Lz = {Lz:.4g} kg m2/s"
        slip_u = 0.0
    ref = evaluate(alpha, energy, h, Lz, _ideal(scene))
    cls = str(ref.cone.names().item())
    r_min, r_max, period = (float(ref[n]) for n in ("r_min", "r_max", "period"))
    if not math.isfinite(r_min) or r_min <= 0:
        raise LookError(f"{label}: a {cls} orbit has no path to draw")
    lossless = not (set(scene.effects) - {"rim", "slip_check", "attitude"})
    if t_end is None and periods is None:
        if cls == "bounded" and lossless and scene.mu_k is None:
            periods = DEFAULT_PERIODS
        elif math.isfinite(period) and period > 0:
            t_end = DEFAULT_PERIODS * period
        else:
            v_min = abs(Lz) / (scene.M * r_min * math.sin(alpha))
            t_end = NO_PERIOD_SPANS * r_min / max(v_min, 1e-300)
    span = t_end if t_end is not None else float(periods) * 1.05 * period
    if not (math.isfinite(span) and span > 0):
        raise LookError(f"{label}: no duration to draw it over; give t_end")
    get_method(method)  # a name the registry knows (simulate checks the rest)
    try:
        traj = simulate(alpha, energy, h, Lz, scene, t_end=t_end, periods=periods,
                        method=method, rtol=rtol, dt_out=span / samples,
                        u0=u0 if scene.mu_k is not None else 0.0,
                        slip_u=slip_u if scene.mu_k is not None else 0.0,
                        slip_v=slip_v if scene.mu_k is not None else 0.0,
                        r0=r0)  # fmt: skip
    except ValueError as exc:
        raise LookError(f"{label}: {exc}") from None
    rim_r = None if scene.rim is None else scene.rim - scene.a / math.tan(alpha)
    return Orbit(traj, float(alpha), scene, float(energy), float(h), float(Lz), r_min, r_max,
                 period, cls, rim_r, label)  # fmt: skip


def scene_from_attrs(attrs: Mapping[str, Any]) -> Scene:
    """The scene of a result from its ``scene_*`` attributes (absent, or the string "none" of
    older files: not set)."""
    kw: dict[str, Any] = {}
    for f in dataclasses.fields(Scene):
        v = attrs.get(f"scene_{f.name}")
        if v is None or (isinstance(v, str) and v.strip().lower() == "none"):
            continue
        kw[f.name] = bool(int(v)) if isinstance(f.default, bool) else float(v)
    try:
        return Scene(**kw)
    except ValueError as exc:
        raise LookError(f"the result's scene: {exc}") from None


def orbit_at(
    dims: tuple[str, ...],
    axes: Mapping[str, np.ndarray],
    point: Mapping[str, float],
    *,
    scene: Scene,
    method: str,
    rtol: float,
    energy_relative: bool = False,
    horizon_time: float | None = None,
    **options: Any,
) -> tuple[Orbit, dict[str, float]]:
    """The orbit of the grid point of a survey (``dims``, ``axes``) nearest to ``point``
    (axis -> value; an axis not named: its middle value), drawn with the survey's scene and
    method (the closed form's orbits with :data:`DRAW_METHOD`), followed to ``horizon_time``
    where the survey has one. Returns the orbit and the grid point used."""
    unknown = sorted(set(point) - set(dims))
    if unknown:
        raise LookError(f"--at {unknown[0]}: no axis {unknown[0]!r}; axes: {', '.join(dims)}")
    at: dict[str, float] = {}
    for d in dims:
        values = np.asarray(axes[d], float)
        i = int(np.argmin(np.abs(values - point[d]))) if d in point else values.size // 2
        at[d] = float(values[i])
    if not get_method(method).integrates:
        method, rtol = DRAW_METHOD, DRAW_RTOL
    if horizon_time is not None and "t_end" not in options and "periods" not in options:
        options["t_end"] = float(horizon_time)
    common = dict(scene=scene, method=method, rtol=rtol, **options)
    if tuple(dims) == DIMS:
        energy = at["energy"]
        if energy_relative:
            vmin = float(minimum_energy(at["alpha"], at["h"], at["Lz"], scene))
            if not math.isfinite(vmin):
                raise LookError(f"no potential minimum at {at}: the relative energy is undefined")
            energy = vmin + energy * abs(vmin)
        return orbit(at["alpha"], energy, at["h"], at["Lz"], **common), at
    release = {k: at[k] for k in ("u0", "slip_u", "slip_v", "backspin") if k in at}
    return orbit(at["alpha"], r0=at["r0"], v0=at["v0"], w0=at["w0"], **release, **common), at


def orbit_of_result(
    ds: xr.Dataset, point: Mapping[str, float], **options: Any
) -> tuple[Orbit, dict[str, float]]:
    """The orbit of the grid point of the survey result ``ds`` nearest to ``point`` (see
    :func:`orbit_at`): the scene, method and horizon of its stored survey definition, or of
    its attributes (a Dataset of :func:`engine.survey` in memory)."""
    dims = grid_dims(ds.dims)
    axes = {d: np.asarray(ds[d].values, float) for d in dims}
    text = ds.attrs.get("survey_definition")
    if text:
        plan = parse_survey(str(text), origin="survey_definition").plan
        kw: dict[str, Any] = dict(
            scene=plan.scene,
            method=plan.method.name,
            rtol=plan.rtol,
            energy_relative=plan.energy_relative,
            horizon_time=plan.horizon.time if plan.horizon else None,
        )
    else:
        horizon = ds.attrs.get("horizon_time")
        kw = dict(scene=scene_from_attrs(ds.attrs), method=str(ds.attrs.get("method", "exact")),
                  rtol=float(ds.attrs.get("rtol", DRAW_RTOL)),
                  energy_relative=ds.attrs.get("energy_axis") == "relative to V_min",
                  horizon_time=None if isinstance(horizon, str) or horizon is None
                  else float(horizon))  # fmt: skip
    for key in ("method", "rtol"):
        if options.get(key) is not None:
            kw[key] = options.pop(key)
    return orbit_at(dims, axes, point, **kw, **options)

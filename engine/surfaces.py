"""The surfaces a ball can roll in: each the surface the ball touches, as a teacher measures it.

One row of :data:`SURFACES` per kind: its name (a survey file's ``[surface] kind``), its
parameters with their units (each can be a survey axis, as alpha is on the cone), what its rim
means, and how to make it. The engine derives the surface the centre moves on (offset by the
ball's radius along the normal: ``engine.kernels.meridian``); where the ball does not fit (a
concave radius of curvature below its radius) a run ends, and a surface the ball fits nowhere
is refused.

=================  ================================  ======================================
surface            the touching surface              its rim (``Scene.rim``)
=================  ================================  ======================================
Cone(alpha)        z = rho cot(alpha)                slant length from the vertex [m]
Bowl(radius)       a sphere of that radius, bottom   the edge's distance from the axis [m]
                   at z = 0 (a hemisphere at most)
Paraboloid(radius) z = rho^2 / (2 radius)            the edge's distance from the axis [m]
Funnel(scale,      z = -scale / rho, a hole of       the edge's distance from the axis [m]
hole)              radius ``hole`` at the bottom
PowerLaw(scale, n) z = scale rho^n                   the edge's distance from the axis [m]
Cylinder(radius)   the wall rho = radius             the edge's height [m]
Profile(rho, z)    a measured meridian z(rho),       the edge's distance from the axis [m]
                   fitted by a Chebyshev series
=================  ================================  ======================================

A launch is where the centre is and how it moves: its distance ``rho0`` from the axis (the
cylinder: its height ``z0``), its speed ``v0`` along the parallel, its spin ``w0`` = a omega .
nu (nu from the contact to the centre) and its speed ``u0`` along the meridian (0: a turning
point).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from .kernels import meridian

__all__ = [
    "Surface",
    "Cone",
    "Bowl",
    "Paraboloid",
    "Funnel",
    "PowerLaw",
    "Cylinder",
    "Profile",
    "SURFACES",
    "surface_from",
]


def _positive(owner: str, name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ValueError(f"{owner}.{name} must be a number; got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{owner}.{name} must be a finite number > 0; got {value!r}")
    return v


@dataclass(frozen=True)
class Surface:
    """A surface of revolution the ball rolls inside (module docstring): its kind's row."""

    #: The kind's name (``[surface] kind`` in a survey file).
    kind: ClassVar[str] = ""
    #: The kind's code in the kernels (:mod:`engine.kernels.meridian`).
    code: ClassVar[int] = -1
    #: Parameters -> units, in the order the kernels take them (shape1, shape2).
    parameters: ClassVar[dict[str, str]] = {}
    #: What ``Scene.rim`` measures on it.
    rim_means: ClassVar[str] = "the edge's distance from the axis [m]"
    #: The launch position's name: ``rho0`` (the centre's distance from the axis) or ``z0``.
    position: ClassVar[str] = "rho0"

    def __post_init__(self) -> None:
        owner = type(self).__name__
        for name in self.parameters:
            object.__setattr__(self, name, _positive(owner, name, getattr(self, name)))

    @property
    def shape(self) -> tuple[float, float]:
        """(shape1, shape2) as the kernels read them."""
        values = [float(getattr(self, name)) for name in self.parameters]
        return (values + [0.0, 0.0])[0], (values + [0.0, 0.0])[1]

    def with_shape(self, shape1: float, shape2: float) -> Surface:
        """The same kind with other shape values (a survey axis over a parameter)."""
        names = list(self.parameters)
        values = dict(zip(names, (shape1, shape2), strict=False))
        return type(self)(**values)

    def slots(self) -> dict[int, float]:
        """The kernels' surface slots (index -> value) other than the shape (the profile's
        coefficients)."""
        return {}

    def as_attrs(self) -> dict[str, float | str]:
        """The surface as netCDF attributes (typed, with the kind's name)."""
        out: dict[str, float | str] = {"surface_kind": self.kind}
        for name in self.parameters:
            out[f"surface_{name}"] = float(getattr(self, name))
        return out


@dataclass(frozen=True)
class Cone(Surface):
    """The cone of half-aperture ``alpha`` [rad] (the closed form's: exact and fastest)."""

    alpha: float = math.pi / 4
    kind: ClassVar[str] = "cone"
    code: ClassVar[int] = meridian.CONE
    parameters: ClassVar[dict[str, str]] = {"alpha": "radian"}
    rim_means: ClassVar[str] = "the slant length from the vertex [m]"

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.alpha < math.pi / 2:
            raise ValueError(f"Cone.alpha must lie in (0, pi/2); got {self.alpha!r}")


@dataclass(frozen=True)
class Bowl(Surface):
    """A spherical bowl of ``radius`` [m] (the touching sphere's), bottom at z = 0."""

    radius: float = 1.0
    kind: ClassVar[str] = "bowl"
    code: ClassVar[int] = meridian.BOWL
    parameters: ClassVar[dict[str, str]] = {"radius": "m"}


@dataclass(frozen=True)
class Paraboloid(Surface):
    """z = rho^2 / (2 ``radius``): ``radius`` [m] its radius of curvature at the bottom."""

    radius: float = 1.0
    kind: ClassVar[str] = "paraboloid"
    code: ClassVar[int] = meridian.PARABOLOID
    parameters: ClassVar[dict[str, str]] = {"radius": "m"}


@dataclass(frozen=True)
class Funnel(Surface):
    """The coin funnel ("gravity well") z = -``scale`` / rho [m^2 / m], with a hole of radius
    ``hole`` [m] at the bottom."""

    scale: float = 0.1
    hole: float = 0.02
    kind: ClassVar[str] = "funnel"
    code: ClassVar[int] = meridian.FUNNEL
    parameters: ClassVar[dict[str, str]] = {"scale": "m2", "hole": "m"}


@dataclass(frozen=True)
class PowerLaw(Surface):
    """z = ``scale`` rho^``n`` (scale in m^(1-n)); n < 2 is sharper than a paraboloid at the
    axis, where a ball stops fitting."""

    scale: float = 1.0
    n: float = 2.0
    kind: ClassVar[str] = "power_law"
    code: ClassVar[int] = meridian.POWER_LAW
    parameters: ClassVar[dict[str, str]] = {"scale": "m(1-n)", "n": "1"}


@dataclass(frozen=True)
class Cylinder(Surface):
    """A vertical wall of ``radius`` [m]; the ball rolls around inside it, its height
    oscillating."""

    radius: float = 1.0
    kind: ClassVar[str] = "cylinder"
    code: ClassVar[int] = meridian.CYLINDER
    parameters: ClassVar[dict[str, str]] = {"radius": "m"}
    rim_means: ClassVar[str] = "the edge's height [m]"
    position: ClassVar[str] = "z0"


#: Largest residual of a profile's fit, relative to its height range, that is accepted.
PROFILE_TOL = 1e-4


@dataclass(frozen=True)
class Profile(Surface):
    """A measured meridian: heights ``z`` [m] at distances ``rho`` [m] from the axis (at least
    4 points, rho increasing), fitted by a Chebyshev series of degree at most
    :data:`engine.kernels.meridian.PROFILE_TERMS` - 1 (least squares); refused where the fit
    misses a point by more than :data:`PROFILE_TOL` of the height range (not smooth enough for
    its curvature to mean anything). Its wall may fall as well as rise (a ring-shaped gutter);
    where it is too sharp for the ball, a survey refuses it (:meth:`trough`)."""

    rho: tuple[float, ...] = ()
    z: tuple[float, ...] = ()
    coefficients: tuple[float, ...] = field(default=(), repr=False, compare=False)
    kind: ClassVar[str] = "profile"
    code: ClassVar[int] = meridian.PROFILE
    parameters: ClassVar[dict[str, str]] = {}

    def __post_init__(self) -> None:
        rho = np.asarray(self.rho, dtype=float)
        z = np.asarray(self.z, dtype=float)
        if rho.ndim != 1 or rho.shape != z.shape or rho.size < 4:
            raise ValueError(
                "Profile needs rho and z of the same length, at least 4 points; got "
                f"{rho.size} and {z.size}"
            )
        if not (np.isfinite(rho).all() and np.isfinite(z).all()):
            raise ValueError("Profile.rho and Profile.z must be finite numbers")
        if rho[0] < 0.0 or np.any(np.diff(rho) <= 0.0):
            raise ValueError("Profile.rho must start at >= 0 and increase")
        lo, hi = float(rho[0]), float(rho[-1])
        x = (2.0 * rho - lo - hi) / (hi - lo)
        degree = min(meridian.PROFILE_TERMS - 1, rho.size - 1)
        series = np.polynomial.chebyshev.Chebyshev.fit(x, z, degree, domain=[-1.0, 1.0])
        span = max(float(np.ptp(z)), 1e-300)
        miss = float(np.max(np.abs(series(x) - z)))
        if miss > PROFILE_TOL * span:
            raise ValueError(
                f"Profile: no smooth meridian through the points (the best fit of degree "
                f"{degree} misses one by {miss:.3g} m, more than {PROFILE_TOL:g} of the height "
                "range): measure more points, or smooth them"
            )
        object.__setattr__(self, "rho", tuple(float(v) for v in rho))
        object.__setattr__(self, "z", tuple(float(v) for v in z))
        object.__setattr__(self, "coefficients", tuple(float(c) for c in series.coef))

    @property
    def shape(self) -> tuple[float, float]:
        return self.rho[0], self.rho[-1]

    def with_shape(self, shape1: float, shape2: float) -> Surface:
        return self

    def slots(self) -> dict[int, float]:
        return {meridian.P_CHEB + j: c for j, c in enumerate(self.coefficients)}

    def trough(self, a: float) -> float | None:
        """The distance from the axis [m] of the first place beyond the profile's inner edge
        where a ball of radius ``a`` does not fit (the meridian's concave radius of curvature
        below a), or None: a run cannot pass such a trough, and the exact map would integrate
        through the cusp of the centre's surface there."""
        lo, hi = self.shape
        series = np.polynomial.chebyshev.Chebyshev(self.coefficients)
        x = np.linspace(-1.0, 1.0, 4001)
        half = 0.5 * (hi - lo)
        d1 = series.deriv()(x) / half
        d2 = series.deriv(2)(x) / half**2
        fit = 1.0 - a * d2 / (1.0 + d1 * d1) ** 1.5
        ok = fit > 0.0
        if not ok.any():
            return lo
        first = int(np.argmax(ok))  # where it starts to fit (the inner end before it)
        later = np.flatnonzero(~ok[first:])
        if later.size == 0:
            return None
        return float(lo + half * (x[first + later[0]] + 1.0))

    def as_attrs(self) -> dict[str, float | str]:
        return {
            "surface_kind": self.kind,
            "surface_rho": np.asarray(self.rho),
            "surface_z": np.asarray(self.z),
        }


#: Every kind of surface, by name.
SURFACES: dict[str, type[Surface]] = {
    s.kind: s for s in (Cone, Bowl, Paraboloid, Funnel, PowerLaw, Cylinder, Profile)
}


def surface_from(kind: Any, **parameters: Any) -> Surface:
    """The surface of kind ``kind`` (a name of :data:`SURFACES`) with ``parameters``."""
    if kind not in SURFACES:
        raise ValueError(f"surface kind must be one of {', '.join(SURFACES)}; got {kind!r}")
    cls = SURFACES[kind]
    allowed = set(cls.parameters) | ({"rho", "z"} if cls is Profile else set())
    unknown = sorted(set(parameters) - allowed)
    if unknown:
        raise ValueError(
            f"surface {kind!r} takes {', '.join(sorted(allowed))}; got {', '.join(unknown)}"
        )
    return cls(**parameters)

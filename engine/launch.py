"""Launch states and invariants: where a ball is released and how fast it moves and spins, in
terms of the invariants (calE, h, L_z) the maps are made of, and back.

A physicist knows the release point and the spin, not calE. :func:`invariants` gives the
invariants of a state (r, u, v, w) on a cone of half-aperture alpha; :func:`launch_state` is
its inverse where it exists (the orbit reaches the radius r).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .checks import check_numbers, check_scene, check_values
from .kernels.cone import coefficients_sc, invariants_of, radial_energy
from .scene import Scene

__all__ = ["invariants", "launch_state"]


def _arrays(names: tuple[str, ...], values: tuple[Any, ...]) -> list[np.ndarray]:
    """The inputs as float64 arrays broadcast together, each checked as a map's axis is
    (:func:`engine.checks.check_numbers`, :func:`engine.checks.check_values`: numbers, finite,
    alpha in (0, pi/2), r > 0)."""
    out = []
    for name, value in zip(names, values, strict=True):
        arr = check_numbers(name, value)
        check_values(name, arr)
        out.append(arr)
    return [np.array(a) for a in np.broadcast_arrays(*out)]  # copies: numba warns on views


def invariants(
    alpha: Any, r: Any, u: Any, v: Any, w: Any, scene: Scene | None = None
) -> dict[str, np.ndarray]:
    """The invariants of the state (r [m], u = dr/dt, v = r sin(alpha) dtheta/dt, w = a omega_nu
    [m/s]) on a cone of half-aperture ``alpha`` [rad]: a dict of arrays (numpy broadcasting)
    ``E`` (total energy [J]), ``energy`` (radial energy calE [J], the maps' energy axis), ``h``
    [m/s] and ``Lz`` [kg m^2/s] (docs/physics.md "Invariants")."""
    s = check_scene(scene)
    a, rr, uu, vv, ww = _arrays(("alpha", "r", "u", "v", "w"), (alpha, r, u, v, w))
    E, Lz, h = invariants_of.py_func(rr, uu, vv, ww, np.sin(a), np.cos(a), s.M, s.g, s.k)
    return {"E": E, "energy": radial_energy.py_func(E, h, s.M, s.k), "h": h, "Lz": Lz}


def launch_state(
    alpha: Any,
    energy: Any,
    h: Any,
    Lz: Any,
    r: Any,
    scene: Scene | None = None,
    *,
    outward: bool = True,
) -> dict[str, np.ndarray]:
    """The state (u, v, w) [m/s] at radius ``r`` [m] of the orbit with invariants (calE [J],
    h [m/s], L_z [kg m^2/s]) on a cone of half-aperture ``alpha``: the inverse of
    :func:`invariants`. u >= 0 if ``outward``, else <= 0; NaN where the orbit does not reach r
    (calE < V(r)). Returns a dict of arrays ``u``, ``v``, ``w`` (numpy broadcasting)."""
    s = check_scene(scene)
    if not isinstance(outward, bool):
        raise ValueError(f"outward must be true or false; got {outward!r}")
    names = ("alpha", "energy", "h", "Lz", "r")
    a, e, hh, lz, rr = _arrays(names, (alpha, energy, h, Lz, r))
    sn, c = np.sin(a), np.cos(a)
    A, B, C = coefficients_sc.py_func(sn, c, hh, lz, s.M, s.g, s.k)
    ke = e - (A / (rr * rr) + B / rr + C * rr)
    with np.errstate(invalid="ignore"):
        u = np.where(ke >= 0.0, np.sqrt(np.maximum(2.0 * ke / s.M, 0.0)), np.nan)
    v = lz / (s.M * rr * sn)
    w = hh + lz * c / (s.M * rr * sn * sn)
    return {"u": u if outward else -u, "v": v, "w": w}

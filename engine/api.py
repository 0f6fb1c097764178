"""High-level API: validate inputs, run the kernels over arrays, return xarray Datasets."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import xarray as xr

from . import __version__
from .grid import BLOCK_POINTS, Tiling, evaluate_block
from .kernels.geometry import CIRCULAR_TOL, empty_outputs, minimum_energy_batch, orbit_batch
from .kernels.physics import CLASS_NAMES
from .scene import Scene

__all__ = ["evaluate", "survey", "evaluate_flat", "METHODS", "VARIABLES", "AXES"]

#: Methods accepted by :func:`evaluate` and :func:`survey`.
METHODS = ("exact", "rk45", "dop853", "symplectic")
#: Integrator methods (need ``engine.integrated``).
INTEGRATORS = METHODS[1:]

#: The four survey axes: name -> (units, long_name).
AXES: dict[str, tuple[str, str]] = {
    "alpha": ("radian", "half-aperture of the cone"),
    "energy": ("J", "radial energy calE = E/(1+k) - k M h^2/(2(1+k))"),
    "h": ("m s-1", "spin invariant h = w - L_z cos(alpha)/(M r sin^2 alpha)"),
    "Lz": ("kg m2 s-1", "axial angular momentum of the centre of mass"),
}

#: Result variables: name -> (units, long_name). ``orbit_class`` is int8 with CF flags.
VARIABLES: dict[str, tuple[str, str]] = {
    "r_min": ("m", "inner turning point (distance from the vertex of the centre's cone)"),
    "r_max": ("m", "outer turning point (+inf for escaping orbits)"),
    "r_circ": ("m", "radius of the circular orbit (minimum of the effective potential)"),
    "period": ("s", "radial period (time from r_max to the next r_max)"),
    "apsidal_angle": (
        "radian",
        "azimuth swept from r_min to r_max (to infinity for escaping orbits)",
    ),
    "precession_rate": ("radian s-1", "apsidal precession rate (2 psi - 2 pi) / T_r"),
    "mu_required": ("1", "smallest friction coefficient that keeps the sphere rolling"),
}
_FLOAT_ORDER = tuple(VARIABLES)  # rows of the kernel's float output

#: Extra variables of the integrator methods: name -> (units, long_name).
INTEGRATOR_VARIABLES: dict[str, tuple[str, str]] = {
    "n_steps": ("1", "accepted integrator steps over one radial period"),
    "energy_drift": (
        "1",
        "|E(T) - E(0)| / max(|E(0)|, kinetic energy at start) over one radial period",
    ),
    "status": ("1", "integrator status code (0 = ok)"),
}


def _check_method(method: str) -> str:
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")
    return method


def _check_array(
    name: str, values: np.ndarray, *, open_interval: tuple[float, float] | None = None
):
    bad = ~np.isfinite(values)
    if bad.any():
        raise ValueError(f"{name} must be finite; got {values[bad].flat[0]!r}")
    if open_interval is not None:
        lo, hi = open_interval
        out = (values <= lo) | (values >= hi)
        if out.any():
            raise ValueError(
                f"{name} must lie in the open interval ({lo:g}, {hi:.17g}); "
                f"got {values[out].flat[0]!r}"
            )


def validate_inputs(alpha, energy, h, Lz) -> None:
    """Raise ValueError naming the first offending argument (non-finite, alpha out of range)."""
    _check_array("alpha", np.asarray(alpha, float), open_interval=(0.0, math.pi / 2))
    _check_array("energy", np.asarray(energy, float))
    _check_array("h", np.asarray(h, float))
    _check_array("Lz", np.asarray(Lz, float))


def _check_tol(circular_tol: float) -> float:
    t = float(circular_tol)
    if not (t >= 0.0 and math.isfinite(t)):
        raise ValueError(f"circular_tol must be finite and >= 0; got {circular_tol!r}")
    return t


def evaluate_flat(
    alpha: np.ndarray,
    energy: np.ndarray,
    h: np.ndarray,
    Lz: np.ndarray,
    scene: Scene,
    method: str = "exact",
    *,
    circular_tol: float = CIRCULAR_TOL,
    rtol: float = 1e-10,
) -> dict[str, np.ndarray]:
    """Kernel call on equal-length 1-D float64 arrays (validated by the caller).

    Returns a dict of 1-D arrays: ``orbit_class`` (int8) and the float variables of
    :data:`VARIABLES`; integrator methods add :data:`INTEGRATOR_VARIABLES` and take period,
    apsidal angle and precession rate from the integration (bounded points only).
    """
    a = np.ascontiguousarray(alpha, np.float64)
    e = np.ascontiguousarray(energy, np.float64)
    hh = np.ascontiguousarray(h, np.float64)
    lz = np.ascontiguousarray(Lz, np.float64)
    cls, f = empty_outputs(a.shape[0])
    orbit_batch(a, e, hh, lz, scene.M, scene.g, scene.k, scene.rim_or_inf, circular_tol, cls, f)
    out: dict[str, np.ndarray] = {"orbit_class": cls}
    for i, name in enumerate(_FLOAT_ORDER):
        out[name] = f[i]
    if method != "exact":
        out.update(_integrate_bounded(a, e, hh, lz, scene, method, rtol, out))
    return out


def _integrate_bounded(a, e, hh, lz, scene, method, rtol, exact):
    """Replace period/psi/precession of bounded points by the integrator's values."""
    from .integrated import evaluate_integrated
    from .kernels.physics import BOUNDED, SPILLS

    n = a.shape[0]
    cls = exact["orbit_class"]
    sel = np.flatnonzero((cls == BOUNDED) | (cls == SPILLS))
    res = evaluate_integrated(a[sel], e[sel], hh[sel], lz[sel], scene, method, rtol)
    upd: dict[str, np.ndarray] = {}
    for name in ("period", "apsidal_angle", "precession_rate"):
        col = np.full(n, np.nan)
        col[sel] = res[name]
        upd[name] = col
    nsteps = np.zeros(n, np.int64)
    nsteps[sel] = res["n_steps"]
    drift = np.full(n, np.nan)
    drift[sel] = res["energy_drift"]
    status = np.zeros(n, np.int8)
    status[sel] = res["status"]
    upd.update(n_steps=nsteps, energy_drift=drift, status=status)
    if "energy_loss" in res:
        loss = np.full(n, np.nan)
        loss[sel] = res["energy_loss"]
        upd["energy_loss"] = loss
    return upd


def _class_attrs() -> dict[str, Any]:
    return {
        "long_name": "orbit class",
        "flag_values": np.arange(len(CLASS_NAMES), dtype=np.int8),
        "flag_meanings": " ".join(CLASS_NAMES),
    }


def _variable_attrs(name: str) -> dict[str, Any]:
    if name == "orbit_class":
        return _class_attrs()
    if name == "status":
        from .kernels.integrators import STATUS_FLAGS

        return {
            "long_name": "integrator status",
            "flag_values": np.arange(len(STATUS_FLAGS), dtype=np.int8),
            "flag_meanings": " ".join(STATUS_FLAGS),
        }
    if name == "energy_absolute":
        return {"units": "J", "long_name": "radial energy calE (absolute)"}
    if name == "energy_loss":
        return {"units": "J", "long_name": "total energy lost over the first radial period"}
    units, long_name = {**VARIABLES, **INTEGRATOR_VARIABLES}[name]
    return {"units": units, "long_name": long_name}


def _global_attrs(scene: Scene, method: str, circular_tol: float, rtol: float) -> dict[str, Any]:
    attrs: dict[str, Any] = {
        "source": f"conesurvey {__version__}",
        "method": method,
        "circular_tol": circular_tol,
    }
    if method != "exact":
        attrs["rtol"] = rtol
    attrs.update(scene.as_attrs())
    return attrs


def axis_attrs(name: str, energy_relative: bool = False) -> dict[str, str]:
    """``units`` and ``long_name`` of a survey axis (the energy axis may be relative)."""
    units, long_name = AXES[name]
    if name == "energy" and energy_relative:
        units = "1"
        long_name = "energy offset from the potential minimum, (calE - V_min)/|V_min|"
    return {"units": units, "long_name": long_name}


def survey_attrs(
    scene: Scene, method: str, circular_tol: float, rtol: float, energy_relative: bool
) -> dict[str, Any]:
    """Global attributes of a survey result (before the CF ones of :mod:`engine.output`)."""
    attrs = _global_attrs(scene, method, circular_tol, rtol)
    attrs["energy_axis"] = "relative to V_min" if energy_relative else "absolute"
    return attrs


def evaluate(
    alpha: Any,
    energy: Any,
    h: Any,
    Lz: Any,
    scene: Scene | None = None,
    method: str = "exact",
    *,
    circular_tol: float = CIRCULAR_TOL,
    rtol: float = 1e-10,
) -> xr.Dataset:
    """Class and orbit geometry at points (alpha [rad], energy [J], h [m/s], Lz [kg m^2/s]).

    Inputs broadcast like numpy arrays (xarray DataArrays broadcast by dimension name). The
    result has the broadcast shape, dims ``dim_0, dim_1, ...`` (or the DataArrays' dims), the
    inputs as coordinates, and the variables ``orbit_class``, ``r_min``, ``r_max``, ``r_circ``,
    ``period``, ``apsidal_angle``, ``precession_rate``, ``mu_required``. ``energy`` is the
    radial energy calE (see :func:`engine.radial_energy`). NaN marks an undefined quantity.
    """
    scene = Scene() if scene is None else scene
    _check_method(method)
    circular_tol = _check_tol(circular_tol)
    inputs = {"alpha": alpha, "energy": energy, "h": h, "Lz": Lz}
    if any(isinstance(v, xr.DataArray) for v in inputs.values()):
        das = xr.broadcast(
            *[xr.DataArray(v) if not isinstance(v, xr.DataArray) else v for v in inputs.values()]
        )
        dims = das[0].dims
        arrays = [np.asarray(d.transpose(*dims).values, np.float64) for d in das]
    else:
        arrays = list(np.broadcast_arrays(*[np.asarray(v, np.float64) for v in inputs.values()]))
        dims = tuple(f"dim_{i}" for i in range(arrays[0].ndim))
    validate_inputs(*arrays)
    shape = arrays[0].shape
    flat = [np.ascontiguousarray(a).reshape(-1) for a in arrays]
    res = evaluate_flat(*flat, scene, method, circular_tol=circular_tol, rtol=rtol)
    data_vars = {
        name: (dims, col.reshape(shape), _variable_attrs(name)) for name, col in res.items()
    }
    coords = {}
    for (name, value), arr in zip(inputs.items(), arrays, strict=True):
        attrs = {"units": AXES[name][0], "long_name": AXES[name][1]}
        if isinstance(value, xr.DataArray):
            # keep a DataArray input on its own dims (1-D inputs become index coordinates)
            coords[name] = (value.dims, np.asarray(value.values, np.float64), attrs)
        else:
            coords[name] = (dims, arr, attrs)
    return xr.Dataset(
        data_vars, coords=coords, attrs=_global_attrs(scene, method, circular_tol, rtol)
    )


def minimum_energy(alpha: Any, h: Any, Lz: Any, scene: Scene | None = None) -> np.ndarray:
    """V_min [J] of the effective potential at (alpha, h, Lz); NaN where V has no minimum."""
    scene = Scene() if scene is None else scene
    a, hh, lz = np.broadcast_arrays(*[np.asarray(v, np.float64) for v in (alpha, h, Lz)])
    validate_inputs(a, 0.0, hh, lz)
    out = np.empty(a.size)
    minimum_energy_batch(
        np.ascontiguousarray(a).reshape(-1),
        np.ascontiguousarray(hh).reshape(-1),
        np.ascontiguousarray(lz).reshape(-1),
        scene.M,
        scene.g,
        scene.k,
        out,
    )
    return out.reshape(a.shape)


def _axis(name: str, values: Any) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(values, np.float64))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"axis {name} must be a non-empty 1-D sequence; got shape {arr.shape}")
    return arr


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
    rtol: float = 1e-10,
    progress: Callable[[int, int], None] | None = None,
    chunk_points: int = BLOCK_POINTS,
) -> xr.Dataset:
    """Outer product of four 1-D axes -> Dataset with dims (alpha, energy, h, Lz).

    With ``energy_relative=True`` the energy axis holds offsets (energy - V_min)/|V_min| from
    each (alpha, h, Lz)'s potential minimum, and ``energy_absolute`` [J] is added; where V has
    no minimum (free fall with B >= 0, or L_z = 0) the energy is undefined and the point is
    classed forbidden. ``progress(done, total)`` is called after each block of
    about ``chunk_points`` points.
    """
    scene = Scene() if scene is None else scene
    _check_method(method)
    circular_tol = _check_tol(circular_tol)
    axes = {n: _axis(n, v) for n, v in (("alpha", alpha), ("energy", energy), ("h", h), ("Lz", Lz))}
    validate_inputs(axes["alpha"], axes["energy"], axes["h"], axes["Lz"])
    shape = tuple(a.size for a in axes.values())
    tiling = Tiling.for_grid(shape, chunk_points)
    spec = dict(
        axes,
        scene=scene,
        method=method,
        energy_relative=energy_relative,
        circular_tol=circular_tol,
        rtol=rtol,
    )
    results: dict[str, np.ndarray] = {}
    done = 0
    for slices in tiling:
        block = evaluate_block(spec, slices)
        for name, arr in block.items():
            if name not in results:
                results[name] = np.empty(shape, arr.dtype)
            results[name][slices] = arr
        done += arr.size
        if progress is not None:
            progress(done, tiling.size)
    dims = tuple(axes)
    data_vars = {name: (dims, col, _variable_attrs(name)) for name, col in results.items()}
    coords = {}
    for name, arr in axes.items():
        coords[name] = (name, arr, axis_attrs(name, energy_relative))
    attrs = survey_attrs(scene, method, circular_tol, rtol, energy_relative)
    return xr.Dataset(data_vars, coords=coords, attrs=attrs)

"""``ds.cone``: an xarray Dataset accessor for the results of :func:`engine.evaluate` and
:func:`engine.survey` (xarray ``doc/internals/extending-xarray.rst``: an accessor, not a subclass).

Class names always come from the ``flag_meanings`` attribute of ``orbit_class`` (CF flags), so
the helpers work on a Dataset read back from netCDF as well as on a fresh one::

    ds = engine.survey(...)
    ds.cone.class_fractions()                 # fraction of points per class
    ds.cone.where_class("bounded")            # other points masked with NaN
    ds.cone.precession_per_revolution()       # 2 psi - 2 pi [degree]
    ds.cone.energy_absolute()                 # V_min + energy |V_min| (relative energy axis)
    ds.cone.names("fate")                     # flag codes as names (orbit_class, fate, ...)
    ds.cone.class_map(x="Lz", y="energy", alpha=0.5, h=0.0)
    print(ds.cone.summary())
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Iterable, Sequence
from typing import Any

import numpy as np
import xarray as xr

from .mapspec import LookError
from .orbitplot import orbit_figure, write_animation
from .orbitview import orbit_of_result
from .plot import CLASS_COLORS, draw_map, legend_handles, matplotlib_parts, style_for
from .schema import variable_attrs

__all__ = ["ConeAccessor", "CLASS_COLORS", "DERIVED", "with_derived"]

#: Classes whose apsidal angle is a half radial period (so 2 psi - 2 pi is a precession).
_PRECESSING = ("bounded", "circular", "spills")

_UNIT_ALIASES = {
    "degree": "degree",
    "degrees": "degree",
    "deg": "degree",
    "radian": "radian",
    "radians": "radian",
    "rad": "radian",
}


#: Variables computed from a result's own (``conesurvey plot`` draws them as stored ones), by
#: name: what they are.
DERIVED: dict[str, str] = {
    "precession_per_revolution": "apsidal precession per radial period, 2 psi - 2 pi [degree]",
    "energy_absolute": "radial energy calE [J] of a survey whose energy axis is relative",
}


def with_derived(ds: xr.Dataset, name: str) -> xr.Dataset:
    """``ds`` with the derived variable ``name`` (:data:`DERIVED`) added, computed by its
    ``ds.cone`` method; ``ds`` itself if it holds ``name`` or ``name`` is not derived.
    LookError if ``ds`` lacks what it is computed from."""
    if name in ds.data_vars or name not in DERIVED:
        return ds
    try:
        da = getattr(ds.cone, name)()
    except ValueError as exc:
        raise LookError(f"{name} cannot be computed from this result: {exc}") from None
    return ds.assign({name: da})


@xr.register_dataset_accessor("cone")
class ConeAccessor:
    """Helpers for a conesurvey result Dataset (needs ``orbit_class`` with CF flag attributes)."""

    def __init__(self, ds: xr.Dataset) -> None:
        self._ds = ds

    # -- class bookkeeping -------------------------------------------------------------------

    @property
    def class_names(self) -> tuple[str, ...]:
        """Class names in flag order, from ``orbit_class.attrs["flag_meanings"]``."""
        attrs = self._class_var().attrs
        if "flag_meanings" not in attrs:
            raise ValueError(
                "orbit_class has no 'flag_meanings' attribute: not a conesurvey result"
            )
        return tuple(str(attrs["flag_meanings"]).split())

    @property
    def class_codes(self) -> dict[str, int]:
        """Class name -> integer code (``flag_values``, or 0, 1, ... when they are absent)."""
        names = self.class_names
        values = self._class_var().attrs.get("flag_values", np.arange(len(names)))
        values = np.atleast_1d(np.asarray(values)).tolist()
        if len(values) != len(names):
            raise ValueError(
                f"orbit_class has {len(values)} flag_values but {len(names)} flag_meanings"
            )
        return {n: int(v) for n, v in zip(names, values, strict=True)}

    def _class_var(self) -> xr.DataArray:
        if "orbit_class" not in self._ds:
            raise ValueError("the Dataset has no 'orbit_class' variable: not a conesurvey result")
        return self._ds["orbit_class"]

    def _codes_of(self, classes: Iterable[str | int]) -> list[int]:
        codes = self.class_codes
        out = []
        for c in classes:
            if isinstance(c, str):
                if c not in codes:
                    raise ValueError(f"unknown class {c!r}; known: {', '.join(codes)}")
                out.append(codes[c])
            elif int(c) in codes.values():
                out.append(int(c))
            else:
                raise ValueError(f"unknown class code {c!r}; known: {sorted(codes.values())}")
        return out

    def class_mask(self, *classes: str | int) -> xr.DataArray:
        """Boolean DataArray: True where ``orbit_class`` is one of ``classes`` (names or codes)."""
        if not classes:
            raise ValueError("give at least one class name, e.g. 'bounded'")
        return self._class_var().isin(self._codes_of(classes))

    def names(self, variable: str = "orbit_class") -> xr.DataArray:
        """The values of a flag variable (``orbit_class``, ``fate``, ``status``, ``event_kind``:
        CF ``flag_values``/``flag_meanings``) as their names, same dims and coordinates; a
        masked (NaN) value becomes ``""``."""
        table = self._flags(variable)
        da = self._ds[variable]
        codes = np.asarray(da.values, float)
        out = np.full(codes.shape, "", dtype=f"<U{max(map(len, table.values()), default=1)}")
        for code, name in table.items():
            out[codes == code] = name
        return xr.DataArray(out, dims=da.dims, coords=da.coords, name=f"{variable}_name")

    def flag_counts(self, variable: str = "orbit_class") -> dict[str, int]:
        """How many points have each flag of ``variable``, in flag order (zeros included)."""
        codes = np.asarray(self._ds[variable].values, float)
        return {name: int((codes == code).sum()) for code, name in self._flags(variable).items()}

    def _flags(self, variable: str) -> dict[int, str]:
        if variable not in self._ds:
            raise ValueError(f"the Dataset has no {variable!r} variable")
        attrs = self._ds[variable].attrs
        if "flag_meanings" not in attrs:
            raise ValueError(f"{variable} has no 'flag_meanings' attribute: not a flag variable")
        names = str(attrs["flag_meanings"]).split()
        values = np.atleast_1d(np.asarray(attrs.get("flag_values", np.arange(len(names)))))
        return {int(v): n for v, n in zip(values.tolist(), names, strict=True)}

    # -- selections and reductions -----------------------------------------------------------

    def where_class(self, *classes: str | int, drop: bool = False) -> xr.Dataset:
        """The Dataset with every point not of ``classes`` masked with NaN.

        ``orbit_class`` becomes float (NaN where masked); its flag attributes are kept. With
        ``drop=True`` coordinate labels whose points are all masked are removed.
        """
        mask = self.class_mask(*classes)
        out = self._ds.where(mask, drop=drop)
        for name, var in self._ds.data_vars.items():
            if name in out:
                out[name].attrs = dict(var.attrs)
        out.attrs = dict(self._ds.attrs)
        return out

    def class_counts(
        self,
        variable: str | None = None,
        dim: str | Sequence[Hashable] | None = None,
    ) -> xr.DataArray:
        """Number of points per flag of ``variable`` (default ``orbit_class``; ``fate``,
        ``status``, any CF flag variable), dim ``class_name`` in flag order, summed over ``dim``
        (default: all). An axis given first (``class_counts("alpha")``) is taken as ``dim``."""
        variable, dim = self._flag_and_dim(variable, dim)
        da = self._ds[variable]
        dims = _reduce_dims(da, dim)
        table = self._flags(variable)
        counts = [(da == code).sum(dim=dims) for code in table]
        names = list(table.values())
        out = xr.concat(counts, dim=xr.DataArray(names, dims="class_name", name="class_name"))
        out.name = "class_count"
        what = "orbit class" if variable == "orbit_class" else f"flag of {variable}"
        out.attrs = {"long_name": f"number of points per {what}", "units": "1"}
        return out

    def class_fractions(
        self,
        variable: str | None = None,
        dim: str | Sequence[Hashable] | None = None,
    ) -> xr.DataArray:
        """Fraction of points with each flag of ``variable`` (default ``orbit_class``; e.g.
        ``class_fractions("fate", dim="v0")``), dim ``class_name``, over ``dim`` (default:
        all). An axis given first is taken as ``dim``.

        Points whose value is NaN (masked by :meth:`where_class`) are not counted, so the
        fractions along ``class_name`` sum to 1 wherever any point is left.
        """
        variable, dim = self._flag_and_dim(variable, dim)
        da = self._ds[variable]
        dims = _reduce_dims(da, dim)
        counts = self.class_counts(variable, dim)
        total = da.notnull().sum(dim=dims)
        out = counts / total
        out.name = "class_fraction"
        what = "orbit class" if variable == "orbit_class" else f"flag of {variable}"
        out.attrs = {"long_name": f"fraction of points per {what}", "units": "1"}
        return out

    def _flag_and_dim(self, variable: Any, dim: Any) -> tuple[str, Any]:
        """(flag variable, dim) of a call of :meth:`class_counts` or :meth:`class_fractions`:
        the first argument may be an axis (the older ``class_counts(dim)``)."""
        if variable is None:
            variable = "orbit_class"
        elif not isinstance(variable, str) or (
            variable not in self._ds.data_vars and variable in self._ds.dims
        ):
            if dim is not None:
                raise ValueError(f"{variable!r} is not a flag variable of the Dataset")
            variable, dim = "orbit_class", variable
        if variable == "orbit_class":
            _ = self.class_names  # raises for a Dataset that is not a conesurvey result
        self._flags(variable)  # raises for one that is not a flag variable
        return variable, dim

    def precession_per_revolution(self, units: str = "degree") -> xr.DataArray:
        """Apsidal precession per radial period, 2 psi - 2 pi, in ``units`` ("degree", "radian").

        Defined for bounded, circular and spilling orbits; NaN elsewhere (for a hyperbolic
        escape ``apsidal_angle`` is a sweep, not a half period). Positive: the apsides advance
        with the orbital motion.
        """
        key = _UNIT_ALIASES.get(units.lower()) if isinstance(units, str) else None
        if key is None:
            raise ValueError(f"units must be 'degree' or 'radian'; got {units!r}")
        if "apsidal_angle" not in self._ds:
            raise ValueError("the Dataset has no 'apsidal_angle' variable")
        present = [c for c in _PRECESSING if c in self.class_codes]
        psi = self._ds["apsidal_angle"].where(self.class_mask(*present))
        out = 2.0 * psi - 2.0 * math.pi
        if key == "degree":
            out = out * (180.0 / math.pi)
        out.name = "precession_per_revolution"
        out.attrs = {
            "units": key,
            "long_name": "apsidal precession per radial period, 2 psi - 2 pi",
        }
        return out

    def energy_absolute(self) -> xr.DataArray:
        """The radial energy calE [J] of every point of a survey whose energy axis is relative
        to V_min: V_min + energy |V_min| in float64, on (alpha, energy, h, Lz); NaN where V has
        no minimum. The numbers the run used (and that files stored as ``energy_absolute``
        before V_min was stored on (alpha, h, Lz)), bit for bit."""
        ds = self._ds
        if "V_min" not in ds or "energy" not in ds.dims:
            raise ValueError(
                "the Dataset has no 'V_min': its energy axis is not relative to V_min (the "
                "energy axis is then the absolute energy itself)"
            )
        vmin = ds["V_min"].astype(np.float64)
        out = vmin + ds["energy"].astype(np.float64) * abs(vmin)
        out = out.transpose(*[d for d in ("alpha", "energy", "h", "Lz") if d in out.dims], ...)
        out.name = "energy_absolute"
        out.attrs = variable_attrs("energy_absolute")
        return out

    # -- presentation ------------------------------------------------------------------------

    def class_map(
        self,
        x: str = "Lz",
        y: str = "energy",
        ax: Any = None,
        legend: bool = True,
        **sel: Any,
    ) -> Any:
        """Plot a 2-D map of ``orbit_class`` over coordinates ``x`` and ``y``; return the Axes.

        ``sel`` picks one value of every other dimension (nearest label), e.g.
        ``alpha=0.5, h=0.0``. The legend lists the classes present, named from flag_meanings.
        Drawn by :func:`engine.plot.draw_map` (as ``conesurvey plot`` draws); matplotlib is
        imported when this is called, not at module import.
        """
        cls = self._class_var()
        _ = self.class_names  # raises for a Dataset without flag_meanings
        index_sel = {k: v for k, v in sel.items() if k in cls.dims and k in cls.indexes}
        pos_sel = {k: v for k, v in sel.items() if k in cls.dims and k not in cls.indexes}
        unknown = set(sel) - set(index_sel) - set(pos_sel)
        if unknown:
            raise ValueError(f"cannot select on {sorted(unknown)}: not dimensions of orbit_class")
        if index_sel:
            cls = cls.sel(index_sel, method="nearest")
        if pos_sel:
            cls = cls.isel(pos_sel)
        cls = cls.squeeze(drop=False)
        if cls.ndim != 2:
            raise ValueError(
                f"class_map needs a 2-D selection; orbit_class has dims {cls.dims} after "
                f"selecting {sel}: pick one value of the other dims with keyword arguments"
            )
        for name in (x, y):
            if name not in cls.coords:
                raise ValueError(f"{name!r} is not a coordinate of orbit_class")
        try:
            matplotlib_parts()
        except LookError as exc:
            raise ImportError(str(exc)) from None
        if ax is None:
            import matplotlib.pyplot as plt  # pyplot: the figure shows in notebooks

            _, ax = plt.subplots(figsize=(6, 4.5))
        style = style_for(cls.values, cls.attrs, "orbit_class")
        _, seen = draw_map(ax, cls, x, y, style)
        fixed = ", ".join(f"{k} = {_fmt(cls.coords[k].values)}" for k in sel if k in cls.coords)
        if fixed:
            ax.set_title(f"orbit class ({fixed})", fontsize="medium")
        if legend:
            handles = legend_handles(style, np.asarray(cls.values, float), seen)
            ax.legend(handles=handles, title="orbit class", loc="best", fontsize="small")
        return ax

    def orbit(self, animate: str | None = None, **kwargs: Any) -> Any:
        """The picture of the orbit of the grid point nearest ``kwargs`` (axis=value; the
        other axes at their middle values), as ``conesurvey orbit RESULT --at ...`` draws it
        (:mod:`engine.orbitplot`); other ``kwargs`` (t_end, periods, samples, method, rtol)
        go to :func:`engine.orbitview.orbit`. ``animate="orbit.gif"`` writes the animation
        too. Returns the matplotlib Figure; the orbit is ``fig.orbit``."""
        point = {k: float(v) for k, v in kwargs.items() if k in self._ds.dims}
        options = {k: v for k, v in kwargs.items() if k not in point}
        o, _ = orbit_of_result(self._ds, point, attitude=animate is not None, **options)
        fig = orbit_figure(o)
        fig.orbit = o
        if animate is not None:
            write_animation(o, animate, overwrite=True)
        return fig

    def summary(self) -> str:
        """A few lines: dims, scene, class counts and ranges of the main observables."""
        ds = self._ds
        cls = self._class_var()
        dims = ", ".join(f"{d}: {n}" for d, n in ds.sizes.items()) or "scalar"
        scene = ", ".join(
            f"{k[6:]}={ds.attrs[k]}" for k in ("scene_M", "scene_g", "scene_k") if k in ds.attrs
        )
        kind = ds.attrs.get("map_kind")
        head = f"conesurvey result ({dims}); method {ds.attrs.get('method', '?')}; {scene}"
        lines = [head + (f"; {kind} map" if kind else "")]
        n = int(cls.notnull().sum())
        if "fate" in ds:  # a fate map: what happened to each ball comes first
            lines.append(f"fates of {n} points: " + _shares(self.flag_counts("fate"), n))
            label = "launch orbits on the ideal cone"
        else:
            label = "classes"
        counts = self.class_counts()
        found = dict(zip(counts.class_name.values.tolist(), counts.values.tolist(), strict=True))
        lines.append(f"{label} of {n} points: " + _shares(found, n))
        prec = self.precession_per_revolution("degree")
        for label, da in (
            ("precession per revolution [degree]", prec),
            ("precession rate [radian s-1]", ds.get("precession_rate")),
            ("mu_required [1]", ds.get("mu_required")),
        ):
            if da is None:
                continue
            v = np.asarray(da.values, float)
            v = v[np.isfinite(v)]
            if v.size:
                lines.append(f"{label}: {v.min():.4g} .. {v.max():.4g} (finite on {v.size})")
        return "\n".join(lines)


def _shares(counts: dict[str, Any], n: int) -> str:
    """``bounded 10823 (76.4%), spills 3352 (23.6%)``: the names with a count above zero."""
    parts = [f"{k} {int(c)} ({100.0 * int(c) / max(n, 1):.1f}%)" for k, c in counts.items() if c]
    return ", ".join(parts)


def _reduce_dims(da: xr.DataArray, dim: str | Sequence[Hashable] | None) -> list[Hashable]:
    if dim is None:
        return list(da.dims)
    dims = [dim] if isinstance(dim, str) else list(dim)
    missing = [d for d in dims if d not in da.dims]
    if missing:
        raise ValueError(f"{missing} are not dimensions of {da.name} {da.dims}")
    return dims


def _fmt(v: Any) -> str:
    arr = np.asarray(v)
    return f"{float(arr):.4g}" if arr.size == 1 else str(arr)

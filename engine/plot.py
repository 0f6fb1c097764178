"""Maps of survey results: any variable over any two survey axes (docs/surveys.md).

:func:`engine.mapspec.plan` checks a request against a Dataset (variable, x and y axes, an
optional facet axis, the values the other axes are fixed at) and :func:`map_figure` draws it.
Everything a map says comes from the file's own attributes: flag variables (CF
``flag_values`` / ``flag_meanings``: ``orbit_class``, ``status``, ...) get a discrete legend,
other variables a colour bar labelled with ``units`` (the ``long_name`` is in the title). An
axis whose values have a constant ratio is drawn on a log scale; a positive variable spanning
1000x or more gets a log colour scale, one of both signs a diverging scale symmetric about
zero. NaN is drawn as "undefined" (light grey), +-inf in the colour bar's extensions, and
points of an unfinished run that are not computed yet hatched white.

matplotlib is an optional extra (``pip install '.[plot]'`` in the checkout): this module imports it
only when a figure is drawn (:func:`engine.figurefile.matplotlib_parts`), so importing
``engine`` never does. The figure's file (its format, its size bounds, the write) is
:mod:`engine.figurefile`'s; its names are re-exported here.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from .figurefile import (
    FORMATS,
    INSTALL_HINT,
    MAX_DPI,
    MAX_PIXELS,
    MIN_DPI,
    check_figure_size,
    figure_png,
    matplotlib_parts,
    output_format,
    save_figure,
)
from .mapspec import (
    MapSpec,
    axis_label,
    facet_panels,
    fixed_text,
    flag_table,
    is_log_spaced,
    variable_label,
)

__all__ = [
    "CLASS_COLORS",
    "FORMATS",
    "INSTALL_HINT",
    "MAX_DPI",
    "MAX_PIXELS",
    "MIN_DPI",
    "Style",
    "check_figure_size",
    "draw_map",
    "figure_png",
    "figure_size",
    "flag_color",
    "legend_handles",
    "map_figure",
    "matplotlib_parts",
    "output_format",
    "save_figure",
    "style_for",
]

#: Characters of medium-size text per inch of figure width (titles are wrapped to fit).
CHARS_PER_INCH = 11
#: Characters per line of a flag legend's title.
LEGEND_TITLE_CHARS = 26

#: What NaN means where it is not "undefined for that orbit class" (the legend's label).
NAN_LABELS: dict[str, str] = {
    name: "NaN: never ends (rolls on without slipping or spilling), or no orbit"
    for name in ("end_r", "end_time", "end_theta")
}

#: Colour of each orbit class and integrator status, by flag name (others: FALLBACK_COLORS).
CLASS_COLORS: dict[str, str] = {
    "forbidden": "#d9d9d9",
    "bounded": "#1f77b4",
    "circular": "#d62728",
    "hyperbolic": "#ff7f0e",
    "radial": "#9467bd",
    "spills": "#2ca02c",
    "slips": "#e377c2",
    "off_cone": "#8c564b",
    "out_of_range": "#000000",
}
FATE_COLORS: dict[str, str] = {
    "no_orbit": "#d9d9d9",
    "rolling": "#1f77b4",
    "spilled": "#17becf",
    "slipped": "#e377c2",
    "rest": "#a65628",
    "vertex": "#9467bd",
    "failed": "#000000",
}
STATUS_COLORS: dict[str, str] = {
    "ok": "#4daf4a",
    "spilled": "#17becf",
    "slipped": "#e377c2",
    "max_steps": "#ff7f00",
    "step_too_small": "#a65628",
    "not_bounded": "#bdbdbd",
    "non_finite": "#000000",
    "unsupported_scene": "#7f7f7f",
    "buffer_full": "#bcbd22",
    "rest": "#a65628",
    "vertex": "#9467bd",
}
FALLBACK_COLORS = ("#e41a1c", "#377eb8", "#984ea3", "#ff7f00", "#a65628", "#f781bf", "#999999")
UNDEFINED_COLOR = "#d9d9d9"
NOT_COMPUTED_COLOR = "#ffffff"
OVER_COLOR, UNDER_COLOR = "#000000", "#ff00ff"
#: Colour of contour lines (``--contour``).
CONTOUR_COLOR = "#000000"
#: A positive variable whose finite values span this factor or more gets a log colour scale.
LOG_COLOR_SPAN = 1e3


# --- axes and colour scales -------------------------------------------------------------------


def _edges(v: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges around sorted centres ``v`` (geometric midpoints on a log axis)."""
    if v.size == 1:
        half = 0.5 * abs(v[0]) or 0.5
        return np.array([v[0] / 1.5, v[0] * 1.5]) if log else np.array([v[0] - half, v[0] + half])
    w = np.log(v) if log else v
    mid = 0.5 * (w[1:] + w[:-1])
    e = np.concatenate(([2 * w[0] - mid[0]], mid, [2 * w[-1] - mid[-1]]))
    return np.exp(e) if log else e


def flag_color(name: str, i: int) -> str:
    """The colour of flag ``name`` (the ``i``-th of its variable)."""
    known = CLASS_COLORS.get(name) or FATE_COLORS.get(name) or STATUS_COLORS.get(name)
    return known or FALLBACK_COLORS[i % len(FALLBACK_COLORS)]


@dataclass
class Style:
    """How values become colours: colormap, norm, flag legend entries or colour-bar label."""

    cmap: Any
    norm: Any
    flags: list[tuple[int, str, str]] | None  # (code, meaning, colour)
    label: str
    extend: str = "neither"
    finite: bool = True  # any finite value to scale the colours by


def style_for(values: np.ndarray, attrs: Mapping[str, Any], name: str) -> Style:
    """The colour scale of a variable whose drawn values are ``values`` (all panels)."""
    m = matplotlib_parts()
    flags = flag_table(attrs)
    units = attrs.get("units")
    label = f"{name} [{units}]" if units else name  # the long name is in the title
    if flags is not None:
        table = [(c, n, flag_color(n, i)) for i, (c, n) in enumerate(flags)]
        codes = [c for c, _, _ in table]
        bounds = [c - 0.5 for c in codes] + [codes[-1] + 0.5]
        cmap = m.colors.ListedColormap([col for _, _, col in table])
        return Style(cmap, m.colors.BoundaryNorm(bounds, cmap.N), table, label)
    v = np.asarray(values, float)
    fin = v[np.isfinite(v)]
    lo, hi = (float(fin.min()), float(fin.max())) if fin.size else (0.0, 1.0)
    cmap = m.mpl.colormaps["viridis"].with_extremes(over=OVER_COLOR, under=UNDER_COLOR)
    extend = {(False, False): "neither", (True, False): "max", (False, True): "min"}.get(
        (bool(np.any(v == np.inf)), bool(np.any(v == -np.inf))), "both"
    )
    if lo > 0 and hi / lo >= LOG_COLOR_SPAN:
        return Style(cmap, m.colors.LogNorm(lo, hi), None, label + ", log scale", extend)
    if lo < 0 < hi:  # both signs: a diverging scale, white at zero
        cmap = m.mpl.colormaps["RdBu_r"].with_extremes(over=OVER_COLOR, under=UNDER_COLOR)
        lo, hi = -max(-lo, hi), max(-lo, hi)
    if lo == hi:
        lo, hi = lo - (0.5 * abs(lo) or 0.5), hi + (0.5 * abs(hi) or 0.5)
    return Style(cmap, m.colors.Normalize(lo, hi), None, label, extend, bool(fin.size))


# --- drawing ----------------------------------------------------------------------------------


def figure_size(panels: int) -> tuple[float, float]:
    """The size [inch] of a map figure of ``panels`` panels (up to 5 a row)."""
    if panels <= 1:
        return (7.2, 5.0)
    ncols = min(panels, 5)
    nrows = -(-panels // ncols)
    return (3.3 * ncols + 1.6, 2.8 * nrows + 1.3)


def draw_map(
    ax: Any,
    da: xr.DataArray,
    x: str,
    y: str,
    style: Style,
    computed: Any = None,
    contours: tuple[float, ...] = (),
) -> tuple[Any, dict[str, bool]]:
    """Draw the 2-D ``da`` over coordinates ``x``, ``y`` into ``ax`` with ``style``; hatch the
    points where ``computed`` (same dims as ``da``) is False; lines where ``da`` crosses each
    value of ``contours`` (through the cell centres). Returns the mesh (for a colour bar) and
    which special cells occur (``undefined``, ``not computed``, ``+inf``, ``-inf``,
    ``contour``: a contour line was drawn)."""
    m = matplotlib_parts()
    xc, yc = da[x], da[y]
    separable = xc.ndim == 1 and yc.ndim == 1 and xc.dims != yc.dims
    if separable:
        order = {xc.dims[0]: np.argsort(xc.values, kind="stable")}
        order[yc.dims[0]] = np.argsort(yc.values, kind="stable")
        da = da.isel(order).transpose(yc.dims[0], xc.dims[0])
        if computed is not None:
            computed = computed.isel(order).transpose(yc.dims[0], xc.dims[0])
        xs, ys = np.asarray(da[x].values, float), np.asarray(da[y].values, float)
        centres = (xs, ys)
        logs = (is_log_spaced(xs), is_log_spaced(ys))
        X, Y = _edges(xs, logs[0]), _edges(ys, logs[1])
        shading = "flat"
    else:  # 2-D coordinates (an evaluate() result): matplotlib's nearest-cell shading
        xb, yb = xr.broadcast(xc, yc)
        X, Y = xb.transpose(*da.dims).values, yb.transpose(*da.dims).values
        centres = (X, Y)
        logs, shading = (False, False), "nearest"
    z = np.array(da.values, float)
    raw = z.copy()  # the values as they are, for the contour lines
    done = np.ones(z.shape, bool) if computed is None else np.asarray(computed.values, bool)
    seen = {
        "undefined": bool((np.isnan(z) & done).any()),
        "not computed": bool((~done).any()),
        "+inf": bool((z == np.inf).any()),
        "-inf": bool((z == -np.inf).any()),
    }
    if style.flags is None:  # +-inf beyond the norm's ends: drawn in the bar's extensions
        lo, hi = float(style.norm.vmin), float(style.norm.vmax)
        z[z == np.inf] = hi + max(hi - lo, 1.0)
        z[z == -np.inf] = lo / 10 if lo > 0 else lo - max(hi - lo, 1.0)
    ax.set_facecolor(UNDEFINED_COLOR)
    mesh = ax.pcolormesh(
        X, Y, np.ma.masked_invalid(z), cmap=style.cmap, norm=style.norm, shading=shading
    )
    if seen["not computed"]:
        ax.pcolor(
            X, Y, np.ma.masked_where(done, np.ones(z.shape)),
            cmap=m.colors.ListedColormap([NOT_COMPUTED_COLOR]),
            hatch="////", edgecolor="#b0b0b0", linewidth=0.0, shading=shading,
        )  # fmt: skip
    seen["contour"] = False
    levels = sorted(set(contours))
    finite = raw[np.isfinite(raw) & done]
    if levels and finite.size and min(levels) <= finite.max() and max(levels) >= finite.min():
        ok = np.isfinite(raw) & done
        ax.contour(*centres, np.ma.masked_where(~ok, raw), levels=levels,
                   colors=CONTOUR_COLOR, linewidths=1.2)  # fmt: skip
        seen["contour"] = True
    if logs[0]:
        ax.set_xscale("log")
    if logs[1]:
        ax.set_yscale("log")
    if separable:
        ax.set_xlim(X[0], X[-1])
        ax.set_ylim(Y[0], Y[-1])
    ax.set_xlabel(axis_label(xc, x))
    ax.set_ylabel(axis_label(yc, y))
    return mesh, seen


def legend_handles(
    style: Style,
    z: np.ndarray,
    seen: Mapping[str, bool],
    variable: str = "",
    contours: tuple[float, ...] = (),
) -> list[Any]:
    """Legend patches: the flags present in ``z`` (flag variables), then undefined (what NaN
    means for ``variable``: :data:`NAN_LABELS`), not computed yet and +-inf where they occur,
    and the contour lines drawn (at ``contours``)."""
    p = matplotlib_parts().patches
    handles = []
    if seen.get("contour"):
        from matplotlib.lines import Line2D

        at = ", ".join(f"{c:g}" for c in sorted(set(contours)))
        handles.append(Line2D([], [], color=CONTOUR_COLOR, lw=1.2, label=f"{variable} = {at}"))
    if style.flags is not None:
        present = set(np.unique(z[np.isfinite(z)]).astype(int).tolist())
        handles += [
            p.Patch(facecolor=col, edgecolor="k", linewidth=0.5, label=name)
            for code, name, col in style.flags
            if code in present
        ]
    extra = [
        ("+inf", OVER_COLOR, None, "+inf"),
        ("-inf", UNDER_COLOR, None, "-inf"),
        ("undefined", UNDEFINED_COLOR, None, NAN_LABELS.get(variable, "undefined (NaN)")),
        ("not computed", NOT_COMPUTED_COLOR, "////", "not computed yet"),
    ]
    for key, color, hatch, label in extra:
        if seen.get(key):
            handles.append(
                p.Patch(facecolor=color, edgecolor="#808080", hatch=hatch, label=label, lw=0.5)
            )
    return handles


def on_grid(ds: xr.Dataset, name: str, dims: Any) -> xr.DataArray:
    """Variable ``name`` of the survey ``ds`` over at least its axes ``dims``: one stored on
    fewer dims (r_circ and V_min on (alpha, h, Lz)) repeated along the others it lacks, as a
    map over them draws it."""
    da = ds[name]
    missing = {d: ds[d].values for d in ds.dims if d in set(dims) - set(da.dims)}
    if not missing:
        return da
    order = [d for d in ds["orbit_class"].dims if d in da.dims or d in missing]
    return da.expand_dims(missing).transpose(*order)


def map_figure(
    ds: xr.Dataset,
    spec: MapSpec,
    computed: xr.DataArray | None = None,
    note: str = "",
    context: bool = True,
) -> Any:
    """The figure of ``spec`` (see :func:`engine.mapspec.plan`): one map, or one per facet
    value, with a legend or colour bar, and a title naming the variable and, with
    ``context``, the survey, the fixed axes and ``note`` (e.g. that the run is unfinished)."""
    m = matplotlib_parts()
    sel = spec.selection()
    da = on_grid(ds, spec.variable, {spec.x, spec.y, spec.facet, *sel}).isel(sel).load()
    comp = None if computed is None else computed.isel(sel)
    if comp is not None and set(comp.dims) - set(da.dims):
        comp = None  # a variable on fewer dims (r_circ, V_min) is computed whole, at once
    comp = None if comp is None else comp.load()
    idx, thinned = facet_panels(ds, spec)
    if idx is not None:
        da = da.isel({spec.facet: idx})
        comp = None if comp is None else comp.isel({spec.facet: idx})
    style = style_for(da.values, da.attrs, spec.variable)
    n = 1 if idx is None else len(idx)
    ncols = min(n, 5)
    nrows = -(-n // ncols)
    size = figure_size(n)
    fig = m.Figure(figsize=size, layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, sharex=True, sharey=True).ravel()
    seen: dict[str, bool] = {}
    mesh = None
    for k, ax in enumerate(axes):
        if k >= n:
            ax.set_visible(False)
            continue
        one = da if idx is None else da.isel({spec.facet: k})
        done = None if comp is None else (comp if idx is None else comp.isel({spec.facet: k}))
        mesh, s = draw_map(ax, one, spec.x, spec.y, style, done, spec.contours)
        ax.label_outer()
        seen = {key: seen.get(key, False) or v for key, v in s.items()}
        if idx is not None:
            value = float(one[spec.facet].values)
            units = ds[spec.facet].attrs.get("units", "")
            unit = f" {units}" if units and units != "1" else ""
            ax.set_title(f"{spec.facet} = {value:.4g}{unit}", fontsize="small")
    used = list(axes[:n])
    handles = legend_handles(
        style, np.asarray(da.values, float), seen, spec.variable, spec.contours
    )
    chars = int(size[0] * CHARS_PER_INCH)  # a line of text as wide as the figure
    if style.flags is None:
        if style.finite:
            fig.colorbar(mesh, ax=used, label=style.label, extend=style.extend)
        if handles:
            wide = sum(len(h.get_label()) + 6 for h in handles) > chars
            fig.legend(
                handles=handles, loc="outside lower center", ncols=1 if wide else len(handles)
            )
    else:
        title = textwrap.fill(str(da.attrs.get("long_name", spec.variable)), LEGEND_TITLE_CHARS)
        fig.legend(handles=handles, loc="outside right center", title=title)
    lines = [variable_label(da.attrs, spec.variable)]
    if not style.finite:
        lines.append("no finite value in this view")
    if context:
        lines = [str(ds.attrs.get("title", "")), *lines, fixed_text(ds, spec), thinned, note]
    lines = [textwrap.fill(line, chars) for line in lines if line]  # never wider than the figure
    fig.suptitle("\n".join(lines), fontsize="medium")
    return fig

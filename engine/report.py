"""``conesurvey report``: one self-contained HTML page about a survey result (docs/surveys.md,
"Look at the results").

The page holds the survey definition (the stored TOML), the provenance (engine, method,
tolerances, scene, fingerprint, history), the count and fraction of every flag (orbit classes;
integrator statuses), the range of every other variable, and a map of every variable over the
two longest axes with the others at their middle values (:mod:`engine.plot`). Images are PNG
data URIs and the style sheet is inline: no script, no network, one file to mail or archive.
Every number is also in a ``data-*`` attribute (exact ``repr``), so that tests and scripts can
read it back; every text from the file is escaped.
"""

from __future__ import annotations

import base64
import html
import math
import os
import struct
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from ._version import __version__
from .io.atomic import fsync_path, replacing
from .io.results import Result
from .mapspec import MapSpec, fixed_text, flag_table, plan
from .plot import figure_png, flag_color, map_figure, matplotlib_parts
from .reportorbits import sample_orbits

__all__ = [
    "Range",
    "Stats",
    "gather",
    "build_report",
    "check_report",
    "map_spec",
    "scene_first",
    "write_report",
]

#: Integrator diagnostics drawn in their own section, in this order.
DIAGNOSTICS = ("status", "energy_drift")
#: Global attributes shown first in the provenance table, in this order.
PROVENANCE = ("source", "method", "rtol", "circular_tol", "energy_axis", "survey_fingerprint")


@dataclass
class Range:
    """Finite minimum and maximum of a variable, and how many values are finite, NaN, +-inf."""

    minimum: float = math.inf
    maximum: float = -math.inf
    finite: int = 0
    nan: int = 0
    posinf: int = 0
    neginf: int = 0

    def add(self, v: np.ndarray) -> None:
        fin = np.isfinite(v)
        self.finite += int(fin.sum())
        self.nan += int(np.isnan(v).sum())
        self.posinf += int((v == np.inf).sum())
        self.neginf += int((v == -np.inf).sum())
        if fin.any():
            self.minimum = min(self.minimum, float(v[fin].min()))
            self.maximum = max(self.maximum, float(v[fin].max()))


@dataclass
class Stats:
    """What the report counts: ``points`` computed, flag counts per flag variable (meaning ->
    count, in flag order) and the ranges of the other variables."""

    points: int
    flags: dict[str, dict[str, int]]
    ranges: dict[str, Range]


def gather(result: Result) -> Stats:
    """Counts and ranges over every computed point, read tile by tile (bounded memory)."""
    ds = result.ds
    tables = {n: flag_table(ds[n].attrs) for n in ds.data_vars}
    flags = {n: {m: 0 for _, m in t} for n, t in tables.items() if t is not None}
    ranges = {str(n): Range() for n, t in tables.items() if t is None}
    points = 0
    for tile in result.tiles():
        sub = ds.isel(tile)
        points += math.prod(int(s.stop - s.start) for s in tile.values())
        for name, table in tables.items():
            v = np.asarray(sub[name].values)
            if table is None:
                ranges[str(name)].add(v.astype(float, copy=False))
                continue
            vals = v[np.isfinite(v)] if v.dtype.kind == "f" else v.ravel()
            codes, counts = np.unique(vals, return_counts=True)
            meaning = dict(table)
            for c, k in zip(codes.tolist(), counts.tolist(), strict=True):
                key = meaning.get(int(c), f"(code {int(c)})")
                flags[str(name)][key] = flags[str(name)].get(key, 0) + k
    return Stats(points, flags, ranges)


# --- HTML -------------------------------------------------------------------------------------

CSS = """
body{font:15px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1d1d1f;
 max-width:1180px;margin:0 auto;padding:1.2em 1.6em 3em;background:#fff}
h1{font-size:1.6em;margin:.2em 0}h2{border-bottom:2px solid #e4e4e7;padding-bottom:.2em;
 margin-top:1.8em}h3{margin:1.2em 0 .4em}
.meta{color:#52525b}.state-complete{color:#15803d;font-weight:600}
.state-unfinished{color:#b45309;font-weight:600}
nav a{margin-right:1.1em}
table{border-collapse:collapse;margin:.4em 0}th,td{padding:.25em .8em;text-align:left;
 border-bottom:1px solid #e4e4e7;vertical-align:top}td.num{text-align:right;
 font-variant-numeric:tabular-nums}th{background:#f4f4f5}
.bar{display:inline-block;height:.8em;background:#1f77b4;vertical-align:middle}
.swatch{display:inline-block;width:.9em;height:.9em;border:1px solid #888;margin-right:.4em;
 vertical-align:-.1em}
.maps{display:grid;grid-template-columns:repeat(auto-fill,minmax(520px,1fr));gap:1em}
figure{margin:0;border:1px solid #e4e4e7;border-radius:6px;padding:.5em;background:#fafafa}
figure img{max-width:100%;height:auto;display:block;margin:auto}
figcaption{font-size:.9em;color:#52525b;margin-top:.3em}
pre{background:#f4f4f5;padding:.8em;border-radius:6px;overflow-x:auto;font-size:.9em}
"""


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _num(x: float) -> str:
    """A number as shown: integers exactly, others to 6 significant digits."""
    if math.isfinite(x) and x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return f"{x:.6g}"


def _png_size(data: bytes) -> tuple[int, int]:
    return struct.unpack(">II", data[16:24])


def _figure(fig: Any, alt: str, caption: str, variable: str) -> str:
    png = figure_png(fig, dpi=72)
    w, h = _png_size(png)
    uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
    return (
        f'<figure id="map-{_e(variable)}"><img src="{uri}" alt="{_e(alt)}" width="{w}" '
        f'height="{h}" data-variable="{_e(variable)}"><figcaption>{caption}</figcaption></figure>'
    )


def map_spec(ds: Any, name: str, base: MapSpec) -> MapSpec:
    """The map of ``name`` on the page: over the base map's axes (``base``), or, for a variable
    stored on fewer dims that lacks one of them (r_circ and V_min do not depend on the energy),
    over the base map's axis it has and its longest other one, the others at their middle
    values."""
    dims = set(map(str, ds[name].dims))
    if {base.x, base.y} <= dims:
        fixed = {d: v for d, v in base.fixed.items() if d in dims}
        return MapSpec(name, base.x, base.y, None, fixed)
    x = base.x if base.x in dims else None  # the base map's axes it has keep their places
    y = base.y if base.y in dims else None
    return plan(ds, name, x, y)


def check_report(result: Result) -> None:
    """LookError, before anything is counted or drawn, for a map of the page larger than a
    figure draws (:data:`engine.mapspec.MAX_CELLS`)."""
    ds = result.ds
    base = plan(ds, "orbit_class")
    for name in ds.data_vars:
        map_spec(ds, str(name), base)


def _maps(result: Result, names: Iterable[str], base: MapSpec) -> list[str]:
    ds = result.ds
    out = []
    for name in names:
        spec = map_spec(ds, name, base)
        fig = map_figure(ds, spec, result.computed(), context=False)
        long_name = ds[name].attrs.get("long_name", name)
        caption = f"<b>{_e(name)}</b>: {_e(long_name)}"
        if (spec.x, spec.y) != (base.x, base.y):
            where = _e(fixed_text(ds, spec)) or "no other axes"
            caption += (
                f" (over {_e(spec.x)} and {_e(spec.y)}: it does not depend on "
                f"{_e(base.y if base.y not in ds[name].dims else base.x)}; {where})"
            )
        out.append(_figure(fig, f"map of {name}", caption, name))
    return out


def _orbits(result: Result) -> str:
    """The section of sample orbits: one per flag found (:mod:`engine.reportorbits`)."""
    samples = sample_orbits(result)
    if not samples:
        return ""
    var = samples[0].variable
    figs, missing = [], []
    for s in samples:
        if s.figure is None:
            missing.append(f"<li><b>{_e(s.flag)}</b>: {_e(s.reason)}</li>")
            continue
        png = figure_png(s.figure, dpi=72)
        w, h = _png_size(png)
        uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
        where = ", ".join(f"{k} = {v:.6g}" for k, v in (s.point or {}).items())
        figs.append(
            f'<figure class="orbit" data-flag="{_e(s.flag)}"><img src="{uri}" '
            f'alt="orbit: {_e(s.flag)}" width="{w}" height="{h}"><figcaption><b>{_e(s.flag)}'
            f"</b> at {_e(where)}: <code>conesurvey orbit {_e(result.path.name)} --at "
            f"{_e(','.join(f'{k}={v:.6g}' for k, v in (s.point or {}).items()))}</code>"
            "</figcaption></figure>"
        )
    tail = f"<p>Not drawn:</p><ul>{''.join(missing)}</ul>" if missing else ""
    return (
        f'<section id="orbits"><h2>Sample orbits</h2><p>For each {_e(var)} found, the first '
        "computed grid point that has it, integrated and drawn from above and as r(t), with "
        "the turning circles of the closed form (dashed) and the events marked.</p>"
        f'<div class="maps">{"".join(figs)}</div>{tail}</section>'
    )


def scene_first(names: list[str]) -> list[str]:
    """The variables of a fate map with ``fate`` and the variables after it (what happened on
    the scene) first, then the launch orbit's on the ideal cone; other maps as they are."""
    if "fate" not in names:
        return list(names)
    i = names.index("fate")
    return names[i:] + names[:i]


def _flag_tables(stats: Stats, result: Result) -> str:
    parts = []
    for var in scene_first(list(stats.flags)):
        counts = stats.flags[var]
        colors = _flag_colors(result, var)
        title = result.ds[var].attrs.get("long_name", var)
        rows = []
        for meaning, n in counts.items():
            frac = n / stats.points if stats.points else 0.0
            rows.append(
                f'<tr data-flag-variable="{_e(var)}" data-flag="{_e(meaning)}" data-count="{n}" '
                f'data-fraction="{float(frac)!r}"><td><span class="swatch" style="background:'
                f'{colors.get(meaning, "#fff")}"></span>{_e(meaning)}</td>'
                f'<td class="num count">{n:,}</td><td class="num fraction">{frac:.4f}</td>'
                f'<td><span class="bar" style="width:{200 * frac:.1f}px"></span></td></tr>'
            )
        parts.append(
            f'<h3>{_e(title)} (<code>{_e(var)}</code>)</h3><table id="flags-{_e(var)}">'
            "<tr><th>flag</th><th>count</th><th>fraction</th><th></th></tr>"
            + "".join(rows)
            + "</table>"
        )
    return "".join(parts)


def _flag_colors(result: Result, var: str) -> dict[str, str]:
    table = flag_table(result.ds[var].attrs) or []
    return {name: flag_color(name, i) for i, (_, name) in enumerate(table)}


def _ranges_table(stats: Stats, result: Result) -> str:
    rows = []
    for var, r in stats.ranges.items():
        units = result.ds[var].attrs.get("units", "")
        lo, hi = (r.minimum, r.maximum) if r.finite else (math.nan, math.nan)
        rows.append(
            f'<tr data-variable="{_e(var)}" data-min="{float(lo)!r}" data-max="{float(hi)!r}" '
            f'data-finite="{r.finite}" data-nan="{r.nan}" data-posinf="{r.posinf}" '
            f'data-neginf="{r.neginf}"><td><code>{_e(var)}</code></td>'
            f'<td class="num min">{_num(lo) if r.finite else "-"}</td>'
            f'<td class="num max">{_num(hi) if r.finite else "-"}</td><td>{_e(units)}</td>'
            f'<td class="num finite">{r.finite:,}</td><td class="num nan">{r.nan:,}</td>'
            f'<td class="num inf">{r.posinf + r.neginf:,}</td></tr>'
        )
    head = (
        "<tr><th>variable</th><th>min</th><th>max</th><th>units</th><th>finite</th>"
        "<th>NaN (undefined)</th><th>&plusmn;inf</th></tr>"
    )
    return f'<table id="ranges">{head}{"".join(rows)}</table>'


def _provenance(result: Result) -> str:
    attrs = dict(result.ds.attrs)
    if result.fingerprint:
        attrs.setdefault("survey_fingerprint", result.fingerprint)
    skip = {"title", "survey_definition", "history"}
    keys = [k for k in PROVENANCE if k in attrs]
    keys += [k for k in attrs if k.startswith("scene_") and k not in keys]
    keys += [k for k in attrs if k not in keys and k not in skip]
    rows = f"<tr><th>file</th><td><code>{_e(result.path.resolve())}</code></td></tr>"
    rows += "".join(
        f'<tr data-attr="{_e(k)}"><th>{_e(k)}</th><td><code>{_e(attrs[k])}</code></td></tr>'
        for k in keys
    )
    history = attrs.get("history")
    tail = f"<h3>history</h3><pre>{_e(history)}</pre>" if history else ""
    return f'<table id="provenance-table">{rows}</table>{tail}'


def _state(result: Result) -> str:
    if result.complete:
        return '<span class="state-complete">complete</span>'
    return f'<span class="state-unfinished">{_e(result.note)}</span>; rerun to finish it'


def build_report(result: Result, *, now: datetime | None = None) -> str:
    """The HTML page about ``result`` (see the module docstring)."""
    matplotlib_parts()  # fail early, before any counting, if matplotlib is missing
    check_report(result)
    ds = result.ds
    stats = gather(result)
    base = plan(ds, "orbit_class")
    state, note = _state(result), result.note
    title = str(ds.attrs.get("title") or result.path.name)
    grid = " &times; ".join(f"{_e(d)} {n}" for d, n in ds.sizes.items())
    names = [str(n) for n in ds.data_vars]
    diagnostics = [n for n in DIAGNOSTICS if n in names]
    others = scene_first([n for n in names if n not in diagnostics])
    where = _e(fixed_text(ds, base)) or "no other axes"
    maps_intro = (
        f"<p>Each map shows <b>{_e(base.x)}</b> (x) against <b>{_e(base.y)}</b> (y), the two "
        f"axes with the most points; the other axes are fixed at {where}. "
        "Light grey: undefined (NaN) for that orbit class"
        + ("; hatched: not computed yet" if note else "")
        + f". Other views: <code>conesurvey plot {_e(result.path.name)} VARIABLE --x AXIS "
        "--y AXIS --at AXIS=VALUE</code>.</p>"
    )
    sections = [
        f'<header><h1>{_e(title)}</h1><p class="meta">{_e(result.path.name)} &middot; {state}'
        f" &middot; grid {grid} = {result.tiling.size:,} points, "
        f'<span id="points" data-points="{stats.points}">{stats.points:,}</span> computed'
        f" &middot; method <code>{_e(ds.attrs.get('method', '?'))}</code></p>",
        '<nav><a href="#flags">flags</a><a href="#maps">maps</a><a href="#orbits">orbits</a>'
        '<a href="#ranges">ranges</a>'
        '<a href="#provenance">provenance</a><a href="#definition">definition</a></nav>'
        "</header>",
        f'<section id="flags"><h2>Counts</h2>{_flag_tables(stats, result)}</section>',
    ]
    if diagnostics:
        figs = "".join(_maps(result, diagnostics, base))
        sections.append(
            '<section id="diagnostics"><h2>Integrator diagnostics</h2><p>Status of each '
            "integration and the relative energy drift over one radial period.</p>"
            f'<div class="maps">{figs}</div></section>'
        )
    figs = "".join(_maps(result, others, base))
    sections += [
        f'<section id="maps"><h2>Maps</h2>{maps_intro}<div class="maps">{figs}</div></section>',
        _orbits(result),
        '<section id="ranges"><h2>Value ranges</h2><p>Over the finite values of the '
        f"computed points.</p>{_ranges_table(stats, result)}</section>",
        f'<section id="provenance"><h2>Provenance</h2>{_provenance(result)}</section>',
        '<section id="definition"><h2>Survey definition</h2><pre id="survey-definition">'
        f"{_e(ds.attrs.get('survey_definition', '(not stored)'))}</pre></section>",
    ]
    stamp = (now or datetime.now(UTC)).strftime("%Y-%m-%d %H:%M UTC")
    footer = f'<footer class="meta"><p>conesurvey {_e(__version__)} report, {stamp}</p></footer>'
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{_e(title)} - conesurvey report</title><style>{CSS}</style></head><body>"
        + "\n".join(sections)
        + footer
        + "</body></html>\n"
    )


def write_report(result: Result, path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
    """Write the report of ``result`` to ``path`` through ``path.tmp`` and a rename;
    FileExistsError if ``path`` exists and not ``overwrite``."""
    path = Path(path)
    text = build_report(result)
    with replacing(path, overwrite=overwrite) as tmp:
        tmp.write_text(text, encoding="utf-8")
        fsync_path(tmp)
    return path

"""``conesurvey accuracy SURVEY.toml``: what accuracy costs on this survey, on this machine.

Each method that can serve the survey's scene is measured on a sample of the survey's grid at
a ladder of tolerances (:func:`engine.accuracy.work_precision`): its errors against the exact
path (or a tighter reference where the scene has no closed form) and its time per point. The
command prints the table, draws the work-precision diagram (``--png``; matplotlib, the
``plot`` extra) and recommends the fastest setting whose error meets ``--target``, with the
time it projects for the whole survey (docs/accuracy.md).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ..accuracy import DEFAULT_RTOLS, SAMPLE_POINTS, recommend, work_precision
from ..figurefile import matplotlib_parts, save_figure
from ..mapspec import LookError
from ..progress import format_duration
from . import PROG, Command, InputError, load_plan

__all__ = ["COMMAND", "diagram", "table"]

DEFAULT_TARGET = 1e-10
DESCRIPTION = """\
What accuracy costs on SURVEY.toml, on this machine. Each method that can serve the survey's
scene (exact, rk45, dop853, symplectic) computes the survey's map on a sample of its grid, each
integrator at a ladder of tolerances; the table gives the largest relative errors over the
sample (period, apsidal angle, turning points and energy against the closed form; on a scene
without one, fates against dop853 at rtol 1e-13) and the time per point and for the whole
survey. The diagram (--png; matplotlib) draws error against time; the last line names the
fastest setting whose error meets --target (docs/accuracy.md)."""
COLUMNS = {  # quantity -> column head
    "period": "period",
    "apsidal_angle": "apsidal",
    "turning_point": "turning",
    "energy": "energy",
    "fate_time": "fate_time",
    "fate_r": "fate_r",
    "energy_lost": "E_lost",
}


def _numbers(text: str, option: str) -> list[float]:
    out = []
    for part in text.split(","):
        try:
            out.append(float(part))
        except ValueError:
            raise InputError(f"{option}: {part.strip()!r} is not a number") from None
    return out


def _seconds(s: float) -> str:
    return f"{s:.3g} s" if s < 60 else f"{s:.0f} s ({format_duration(s)})"


def table(ds: xr.Dataset) -> list[str]:
    """The lines of the table: per setting the largest error (and of each quantity) over the
    sample, the median, (a fate map) the fates that differ from the reference's, failures,
    steps, time per point and for the whole survey."""
    quantities = [q for q in COLUMNS if f"{q}_error" in ds]
    fates = "fate_differs" in ds  # a fate map: how many fates differ from the reference's
    head = f"{'method':10s} {'rtol':>7s} {'error':>8s} {'median':>8s} "
    head += f"{'differ':>6s} " if fates else ""
    head += " ".join(f"{COLUMNS[q]:>9s}" for q in quantities)
    head += f" {'failed':>6s} {'steps':>6s} {'s/point':>8s} {'survey':>9s}"
    lines = [head, "-" * len(head)]
    for s in range(ds.sizes["setting"]):
        row = ds.isel(setting=s)
        integrates = not math.isnan(float(row["rtol"]))
        rtol = f"{float(row['rtol']):7.0e}" if integrates else f"{'-':>7s}"
        err = float(row["error"])
        cells = [f"{str(row['method'].values):10s}", rtol,
                 f"{err:8.1e}" if integrates else f"{err:7.0e}*",
                 f"{float(row['median_error']):8.1e}" if integrates else f"{'-':>8s}"]  # fmt: skip
        if fates:
            cells.append(f"{int(row['fate_differs'].sum()):6d}")
        for q in quantities:
            e = row[f"{q}_error"].values
            cells.append(f"{np.nanmax(e):9.1e}" if integrates and np.isfinite(e).any() else
                         f"{'-':>9s}")  # fmt: skip
        steps = float(row["steps"])
        cells += [f"{int(row['failed']):6d}" if integrates else f"{'-':>6s}",
                  f"{steps:6.0f}" if math.isfinite(steps) else f"{'-':>6s}",
                  f"{float(row['seconds_per_point']):8.1e}",
                  f"{float(row['survey_seconds']):8.3g}s"]  # fmt: skip
        lines.append(" ".join(cells))
    return lines


def diagram(ds: xr.Dataset, best: dict[str, Any] | None, target: float) -> Any:
    """The work-precision diagram: largest error against time per point, log-log, one line
    per integrator (its tolerances marked), the closed form a star, the target dashed."""
    parts = matplotlib_parts()
    fig = parts.Figure(figsize=(7.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    floor = 1e-17
    for k, name in enumerate(dict.fromkeys(ds["method"].values.tolist())):
        sel = ds.isel(setting=np.flatnonzero(ds["method"].values == name))
        t, e = sel["seconds_per_point"].values, np.maximum(sel["error"].values, floor)
        if math.isnan(float(sel["rtol"][0])):
            ax.loglog(t, e, "*", ms=14, color="k", label=f"{name} (tested accuracy)")
            continue
        ax.loglog(t, np.where(np.isfinite(e), e, np.nan), "o-", color=f"C{k}", label=name)
        for ti, ei, r in zip(t, e, sel["rtol"].values, strict=True):
            if np.isfinite(ei):
                ax.annotate(f"{r:.0e}", (ti, ei), fontsize=7, xytext=(4, 2),
                            textcoords="offset points")  # fmt: skip
    ax.axhline(target, ls="--", color="0.5", lw=0.8, label=f"target {target:g}")
    if best is not None:
        ax.loglog(best["seconds_per_point"], max(best["error"], floor), "o", ms=16, mfc="none",
                  mec="r", label=f"fastest within target: {best['method']}")  # fmt: skip
    ax.set_xlabel(f"wall time per survey point [s] ({ds.attrs['threads']} threads)")
    ax.set_ylabel("largest relative error over the sample [1]")
    ax.set_title(f"{ds.attrs['title']}\n{ds.attrs['compared']} orbits of a "
                 f"{ds.attrs['sample_points']}-point sample, against the "
                 f"{ds.attrs['reference']}", fontsize=9)  # fmt: skip
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("survey", metavar="SURVEY.toml", help="survey definition (TOML)")
    parser.add_argument(
        "--target",
        type=float,
        default=DEFAULT_TARGET,
        help="largest relative error to meet (default %(default)g)",
    )
    parser.add_argument(
        "--methods", help="comma-separated methods (default: every one that can serve the scene)"
    )
    parser.add_argument(
        "--rtols",
        help="comma-separated tolerances of the integrators "
        f"(default {','.join(f'{r:.0e}' for r in DEFAULT_RTOLS)})",
    )
    parser.add_argument(
        "--sample",
        type=int,
        default=SAMPLE_POINTS,
        help="points of the sample (default %(default)s)",
    )
    parser.add_argument("--seed", type=int, default=0, help="which sample (default 0)")
    parser.add_argument(
        "--png",
        help="the diagram's file (default: SURVEY_work_precision.png in the working directory)",
    )
    parser.add_argument("--no-png", action="store_true", help="print the table only")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --png")


def _png(args: argparse.Namespace) -> Path | None:
    """The diagram's path, checked before anything is measured (None: --no-png)."""
    if args.no_png:
        return None
    name = f"{Path(args.survey).stem}_work_precision.png"
    out = Path(args.png) if args.png else Path.cwd() / name
    if out.suffix.lower() != ".png":
        raise InputError(f"--png must name a .png file; got {str(out)!r}")
    if out.is_dir():
        raise InputError(f"--png: output path is a directory: {out}")
    if not out.parent.is_dir():
        raise InputError(f"--png: output directory does not exist: {out.parent}")
    if out.exists() and not args.overwrite:
        raise InputError(f"--png: output file exists: {out} (use --overwrite to replace it)")
    try:
        matplotlib_parts()
    except LookError as exc:
        raise InputError(f"{exc}; or --no-png for the table only") from None
    return out


def _accuracy(args: argparse.Namespace, command: str) -> int:
    if not (math.isfinite(args.target) and args.target > 0):
        raise InputError(f"--target must be a number > 0; got {args.target!r}")
    plan = load_plan(args.survey)
    png = _png(args)
    kw: dict[str, Any] = {"sample": args.sample, "seed": args.seed}
    if args.methods is not None:
        kw["methods"] = [m.strip() for m in args.methods.split(",")]
    if args.rtols is not None:
        kw["rtols"] = _numbers(args.rtols, "--rtols")
    try:
        ds = work_precision(plan, **kw)
    except ValueError as exc:  # the message starts with the argument's name
        named = str(exc).split(":")[0].split()[0] in kw
        raise InputError(f"--{exc}" if named else str(exc)) from None
    a = ds.attrs
    print(f"{args.survey}: {a['survey_points']:,} points; sample {a['sample_points']} points "
          f"({a['sample_shape']}), {a['compared']} orbits compared against the "
          f"{a['reference']}; {a['threads']} threads, load average "
          f"{a['load_average']}")  # fmt: skip
    for line in table(ds):
        print(line)
    print("* the closed form's error is the one it is tested to (docs/api.md \"Accuracy\"); "
          "errors are relative, the largest over the sample (inf: an orbit failed)")  # fmt: skip
    best = recommend(ds, args.target)
    if best is None:
        print(
            f"target {args.target:g}: no setting measured here meets it (tighter --rtols, "
            "or a larger target)"
        )
    else:
        rtol = "" if math.isnan(best["rtol"]) else f" at rtol {best['rtol']:g}"
        print(f"target {args.target:g}: {best['method']}{rtol} (largest error "
              f"{best['error']:.1e}), about {_seconds(best['survey_seconds'])} for the whole "
              f"survey ({best['seconds_per_point']:.2e} s per point, {a['threads']} threads, "
              f"{os.cpu_count()} cores)")  # fmt: skip
    if png is not None:
        try:
            save_figure(diagram(ds, best, args.target), png, overwrite=args.overwrite, dpi=110)
        except FileExistsError:
            raise InputError(f"--png: output file exists: {png} (use --overwrite)") from None
        print(f"wrote {png}")
    sys.stdout.flush()
    return 0


COMMAND = Command(
    name="accuracy",
    help="what accuracy costs: each method's errors and time on a sample of the survey",
    description=DESCRIPTION,
    add_arguments=add_arguments,
    run=_accuracy,
    epilog=f"example: {PROG} accuracy surveys/gravity_precession.toml --target 1e-10",
)

"""The commands ``conesurvey plot`` and ``conesurvey report`` (docs/surveys.md).

Both are :class:`~engine.commands.Command` objects (:data:`PLOT`, :data:`REPORT`) that
:mod:`engine.cli` registers. Exit
status: 0 written; 1 the output could not be written; 2 bad input (no such result, variable or
axis, an existing output without ``--overwrite``, matplotlib missing); 130 interrupted. On any
failure nothing is written (figures and pages go through ``OUT.tmp`` and a rename).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from ..accessor import DERIVED, with_derived
from ..io import OutputError
from ..io.results import Result, open_result
from ..mapspec import (
    AXIS_PREFERENCE,
    DEFAULT_VARIABLES,
    MAX_CELLS,
    MAX_PANELS,
    LookError,
    facet_panels,
    fixed_text,
    parse_at,
    plan,
)
from ..plot import (
    FORMATS,
    MAX_DPI,
    MAX_PIXELS,
    MIN_DPI,
    check_figure_size,
    figure_size,
    map_figure,
    matplotlib_parts,
    output_format,
    save_figure,
)
from ..report import check_report, write_report
from . import Command, error

__all__ = ["PLOT", "REPORT"]

_DERIVED_LINES = "\n".join(f"  {name}: {text}" for name, text in DERIVED.items())

PLOT_DESCRIPTION = f"""\
Draw a map of one variable of a survey result over two of its axes, the other axes fixed at
the values nearest to --at (default: their middle values), or one map per value of --facet.

VARIABLE defaults to {" if present, else ".join(DEFAULT_VARIABLES)} (a fate map's fate:
what happened on the scene). The axes default to the two with the most values; of two equally
long ones the first of {", ".join(AXIS_PREFERENCE)} is drawn upwards. Besides the stored
variables, these are computed from the result:
{_DERIVED_LINES}

Flag variables (orbit_class, fate, status) get a legend of their flags, other variables a
colour bar with their long name and units, and --contour lines where they cross a value
(--contour 0: where a precession changes sign); axes with log-spaced values are drawn on a
log scale. Grey cells are undefined (NaN). FILE may be a run that is not finished yet (OUT.nc
absent, OUT.nc.parts/ present): the blocks computed so far are drawn, the rest hatched.

Sizes are bounded, refused before anything is drawn: --dpi {MIN_DPI}..{MAX_DPI}, at most
{MAX_PIXELS:,} pixels a figure, {MAX_CELLS:,} cells a figure, {MAX_PANELS} panels (more values
of --facet are thinned, keeping 0, and the ones left out are named)."""

PLOT_EPILOG = """\
examples:
  conesurvey plot gravity_precession.nc                  # orbit_class, h (x) by energy (y)
  conesurvey plot gravity_precession.nc precession_rate --at alpha=0.5 --x Lz --contour 0
  conesurvey plot gravity_precession.nc precession_per_revolution --x Lz --facet alpha
  conesurvey plot fate_rolling_resistance.nc             # fate, v0 (x) by r0 (y)

exit status: 0 written, 1 output not written, 2 bad input or usage, 130 interrupted"""

REPORT_DESCRIPTION = """\
Write one self-contained HTML page about a survey result: the survey definition, provenance
(engine, method, tolerances, scene, fingerprint, history), the counts of orbit classes (and
integrator statuses), the value range of every variable and a map of every variable. Images
are embedded; the page needs no network and no JavaScript. Works on unfinished runs too."""


def _plot_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", metavar="FILE.nc", help="a conesurvey result (or unfinished run)")
    p.add_argument(
        "variable",
        nargs="?",
        default=None,
        help=f"variable to draw (default: {' if present, else '.join(DEFAULT_VARIABLES)})",
    )
    p.add_argument("--x", metavar="AXIS", help="horizontal axis (default: a longest axis)")
    p.add_argument("--y", metavar="AXIS", help="vertical axis (default: energy if it is long)")
    p.add_argument(
        "--at",
        action="append",
        metavar="AXIS=VALUE[,...]",
        help="fix other axes at the nearest value, e.g. alpha=0.5,h=0 (default: middle value)",
    )
    p.add_argument(
        "--facet",
        metavar="AXIS",
        help=f"one map per value of AXIS (at most {MAX_PANELS}; of more, the ones left out "
        "are named)",
    )
    p.add_argument(
        "--contour",
        action="append",
        type=float,
        default=[],
        metavar="VALUE",
        help="draw the line where the variable equals VALUE (repeatable; e.g. --contour 0)",
    )
    p.add_argument(
        "-o",
        "--output",
        metavar="MAP.png",
        help=f"output ({', '.join(FORMATS)}; default: FILE's stem_VARIABLE.png here)",
    )
    p.add_argument(
        "--dpi",
        type=int,
        default=100,
        help=f"resolution of a PNG (default 100; {MIN_DPI}..{MAX_DPI}, at most "
        f"{MAX_PIXELS:,} pixels)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace the output if it exists")


def _report_arguments(r: argparse.ArgumentParser) -> None:
    r.add_argument("file", metavar="FILE.nc", help="a conesurvey result (or unfinished run)")
    r.add_argument(
        "-o", "--output", metavar="REPORT.html", help="default: FILE's stem_report.html here"
    )
    r.add_argument("--overwrite", action="store_true", help="replace the output if it exists")


def _run(args: argparse.Namespace, command_line: str = "") -> int:
    """Carry out ``conesurvey plot`` or ``report``; returns the exit status."""
    return drawing(lambda: _plot(args) if args.command == "plot" else _report(args))


def drawing(draw: Callable[[], int]) -> int:
    """The exit status of a command that draws (``plot``, ``report``, ``orbit``): ``draw()``'s,
    or, for what stopped it, the one error line and its status (2: bad input or an existing
    output, nothing written; 1: the output could not be written; 130: interrupted)."""
    try:
        return draw()
    except (LookError, OutputError) as exc:
        error(str(exc))
        return 2
    except FileExistsError as exc:
        error(f"output file exists: {exc.filename} (use --overwrite to replace it)")
        return 2
    except OSError as exc:
        error(f"cannot write {exc.filename or 'the output'}: {exc.strerror or exc}")
        return 1
    except KeyboardInterrupt:
        error("interrupted; nothing written")
        return 130


def _stem(result: Result) -> str:
    return result.path.stem


def _check_output(out: Path, overwrite: bool) -> None:
    """LookError for an output that may not or cannot be written (before any drawing)."""
    if out.is_dir():
        raise LookError(f"output path is a directory: {out}")
    if not out.parent.is_dir():
        raise LookError(f"output directory does not exist: {out.parent}")
    if out.exists() and not overwrite:
        raise LookError(f"output file exists: {out} (use --overwrite to replace it)")


def _plot(args: argparse.Namespace) -> int:
    at = parse_at(args.at)
    check_figure_size(figure_size(1), args.dpi)  # the bounds, before any file is opened
    with open_result(args.file) as result:
        ds = result.ds if args.variable is None else with_derived(result.ds, args.variable)
        spec = plan(ds, args.variable, args.x, args.y, at, args.facet, args.contour,
                    derived=tuple(DERIVED))  # fmt: skip
        idx, left_out = facet_panels(ds, spec)
        check_figure_size(figure_size(1 if idx is None else len(idx)), args.dpi)
        name = f"{_stem(result)}_{spec.variable}.png"
        out = Path(args.output) if args.output else Path.cwd() / name
        output_format(out)
        _check_output(out, args.overwrite)
        matplotlib_parts()
        fig = map_figure(ds, spec, result.computed(), result.note)
        save_figure(fig, out, overwrite=args.overwrite, dpi=args.dpi)
        fixed = fixed_text(ds, spec)
    what = f"{spec.variable} over {spec.x} (x) and {spec.y} (y)"
    what += f", one map per {spec.facet}" if spec.facet else ""
    what += f" ({left_out})" if left_out else ""
    print(f"wrote {out}: {what}" + (f"; {fixed}" if fixed else ""))
    return 0


def _report(args: argparse.Namespace) -> int:
    with open_result(args.file) as result:
        out = Path(args.output) if args.output else Path.cwd() / f"{_stem(result)}_report.html"
        if out.suffix.lower() not in (".html", ".htm"):
            raise LookError(f"output {out}: a report is HTML; name it *.html")
        _check_output(out, args.overwrite)
        check_report(result)
        matplotlib_parts()
        write_report(result, out, overwrite=args.overwrite)
        note = result.note
    print(f"wrote {out}" + (f" ({note})" if note else ""))
    return 0


PLOT = Command(
    "plot",
    "draw a map of a variable over two axes (PNG, SVG or PDF)",
    PLOT_DESCRIPTION,
    _plot_arguments,
    _run,
    PLOT_EPILOG,
)
REPORT = Command(
    "report",
    "write a self-contained HTML report (definition, provenance, counts, maps)",
    REPORT_DESCRIPTION,
    _report_arguments,
    _run,
)

"""The commands ``conesurvey plot`` and ``conesurvey report`` (docs/surveys.md).

Both are :class:`~engine.commands.Command` objects (:data:`PLOT`, :data:`REPORT`) that
:mod:`engine.cli` registers. Exit
status: 0 written; 1 the output could not be written; 2 bad input (no such result, variable or
axis, an existing output without ``--overwrite``, matplotlib missing); 130 interrupted. On any
failure nothing is written (figures and pages go through ``OUT.tmp`` and a rename).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..io import OutputError
from ..io.results import Result, open_result
from ..mapspec import LookError, fixed_text, parse_at, plan
from ..plot import FORMATS, map_figure, matplotlib_parts, output_format, save_figure
from ..report import write_report
from . import Command, error

__all__ = ["PLOT", "REPORT"]

PLOT_DESCRIPTION = """\
Draw a map of one variable of a survey result over two of its axes, the other axes fixed at
the values nearest to --at (default: their middle values), or one map per value of --facet.

Flag variables (orbit_class, status) get a legend of their flags, other variables a colour
bar with their long name and units; axes with log-spaced values are drawn on a log scale.
Grey cells are undefined (NaN). FILE may be a run that is not finished yet (OUT.nc absent,
OUT.nc.parts/ present): the blocks computed so far are drawn, the rest hatched."""

PLOT_EPILOG = """\
examples:
  conesurvey plot precession.nc                          # orbit_class, Lz vs energy
  conesurvey plot precession.nc precession_rate --at alpha=0.5,h=0 -o rate.png
  conesurvey plot precession.nc mu_required --x Lz --y energy --facet alpha

exit status: 0 written, 1 output not written, 2 bad input or usage, 130 interrupted"""

REPORT_DESCRIPTION = """\
Write one self-contained HTML page about a survey result: the survey definition, provenance
(engine, method, tolerances, scene, fingerprint, history), the counts of orbit classes (and
integrator statuses), the value range of every variable and a map of every variable. Images
are embedded; the page needs no network and no JavaScript. Works on unfinished runs too."""


def _plot_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", metavar="FILE.nc", help="a conesurvey result (or unfinished run)")
    p.add_argument(
        "variable", nargs="?", default="orbit_class", help="variable to draw (orbit_class)"
    )
    p.add_argument("--x", metavar="AXIS", help="horizontal axis (default: a longest axis)")
    p.add_argument("--y", metavar="AXIS", help="vertical axis (default: energy if it is long)")
    p.add_argument(
        "--at",
        action="append",
        metavar="AXIS=VALUE[,...]",
        help="fix other axes at the nearest value, e.g. alpha=0.5,h=0 (default: middle value)",
    )
    p.add_argument("--facet", metavar="AXIS", help="one map per value of AXIS (at most 16)")
    p.add_argument(
        "-o",
        "--output",
        metavar="MAP.png",
        help=f"output ({', '.join(FORMATS)}; default: FILE's stem_VARIABLE.png here)",
    )
    p.add_argument("--dpi", type=int, default=100, help="resolution of a PNG (default 100)")
    p.add_argument("--overwrite", action="store_true", help="replace the output if it exists")


def _report_arguments(r: argparse.ArgumentParser) -> None:
    r.add_argument("file", metavar="FILE.nc", help="a conesurvey result (or unfinished run)")
    r.add_argument(
        "-o", "--output", metavar="REPORT.html", help="default: FILE's stem_report.html here"
    )
    r.add_argument("--overwrite", action="store_true", help="replace the output if it exists")


def _run(args: argparse.Namespace, command_line: str = "") -> int:
    """Carry out ``conesurvey plot`` or ``report``; returns the exit status."""
    try:
        if args.command == "plot":
            return _plot(args)
        return _report(args)
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
    if args.dpi < 10:
        raise LookError(f"--dpi must be at least 10; got {args.dpi}")
    with open_result(args.file) as result:
        spec = plan(result.ds, args.variable, args.x, args.y, at, args.facet)
        name = f"{_stem(result)}_{spec.variable}.png"
        out = Path(args.output) if args.output else Path.cwd() / name
        output_format(out)
        _check_output(out, args.overwrite)
        matplotlib_parts()
        fig = map_figure(result.ds, spec, result.computed(), result.note)
        save_figure(fig, out, overwrite=args.overwrite, dpi=args.dpi)
        fixed = fixed_text(result.ds, spec)
    what = f"{spec.variable} over {spec.x} (x) and {spec.y} (y)"
    what += f", one map per {spec.facet}" if spec.facet else ""
    print(f"wrote {out}: {what}" + (f"; {fixed}" if fixed else ""))
    return 0


def _report(args: argparse.Namespace) -> int:
    with open_result(args.file) as result:
        out = Path(args.output) if args.output else Path.cwd() / f"{_stem(result)}_report.html"
        if out.suffix.lower() not in (".html", ".htm"):
            raise LookError(f"output {out}: a report is HTML; name it *.html")
        _check_output(out, args.overwrite)
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

"""The ``conesurvey`` command line: ``conesurvey run SURVEY.toml [-o OUT.nc]``.

Exit status: 0 success; 1 the output could not be written; 2 bad input (an invalid or missing
survey file, an existing output without ``--overwrite``); 130 interrupted. On any failure no
output file is created and an existing one is left as it was.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

import numpy as np
import xarray as xr

__all__ = ["main", "build_parser"]

PROG = "conesurvey"

DESCRIPTION = """\
Orbit surveys of a sphere rolling without slipping inside a cone.

A survey evaluates every point of the grid alpha x energy x h x Lz (from a TOML survey
definition), classifies each orbit (forbidden, bounded, circular, hyperbolic, radial, spills)
and stores turning points, period, apsidal angle, precession rate and the friction needed to
roll in a CF-1.11 netCDF file."""

RUN_DESCRIPTION = """\
Run the survey defined in SURVEY.toml and write the results to a netCDF file.

The definition names the scene ([scene]: M [kg], g [m s-2], a [m], k, rim [m]), the method
and the four axes [axes.alpha] [radian], [axes.energy] (radial energy [J], or relative to
V_min with relative_to = "V_min"), [axes.h] [m s-1] and [axes.Lz] [kg m2 s-1], each either
values = [...] or start, stop, num with scale = "linear" or "log". See the examples in
surveys/ and the README's survey format. The TOML text is stored verbatim in the output's
survey_definition attribute."""

EPILOG = """\
example:
  conesurvey run surveys/gravity_precession.toml -o precession.nc
  python -c "import xarray as xr; print(xr.open_dataset('precession.nc'))"

exit status: 0 success, 1 output not written, 2 bad input or usage, 130 interrupted"""


class _InputError(Exception):
    """A problem with the command's input: reported as ``conesurvey: error: ...``, status 2."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``conesurvey``."""
    fmt = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(
        prog=PROG, description=DESCRIPTION, epilog=EPILOG, formatter_class=fmt
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    run = sub.add_parser(
        "run",
        help="run a survey definition and write a netCDF file",
        description=RUN_DESCRIPTION,
        epilog=EPILOG,
        formatter_class=fmt,
    )
    run.add_argument("survey", metavar="SURVEY.toml", help="survey definition (TOML)")
    run.add_argument(
        "-o",
        "--output",
        metavar="OUT.nc",
        help="output netCDF file (default: SURVEY's stem + .nc in the current directory)",
    )
    run.add_argument(
        "--overwrite", action="store_true", help="replace OUT.nc if it exists (default: refuse)"
    )
    run.add_argument(
        "-q", "--quiet", action="store_true", help="no progress bar and no summary; errors only"
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``conesurvey`` command line with ``argv`` (default ``sys.argv[1:]``).

    Returns the exit status; ``--help``, ``--version`` and usage errors exit through
    ``SystemExit`` as argparse does.
    """
    args_list = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(args_list)
    command = shlex.join([PROG, *args_list])
    try:
        if args.command == "run":
            return _run(args, command)
        raise AssertionError(f"unhandled command {args.command!r}")  # pragma: no cover
    except _InputError as exc:
        _error(str(exc))
        return 2
    except KeyboardInterrupt:
        _error("interrupted; no output written")
        return 130


def _error(message: str) -> None:
    print(f"{PROG}: error: {message}", file=sys.stderr)


def _run(args: argparse.Namespace, command: str) -> int:
    from .output import write_survey
    from .progress import Progress
    from .surveyfile import SurveyError, load_survey

    source = Path(args.survey)
    try:
        survey = load_survey(source)
    except FileNotFoundError:
        raise _InputError(f"survey file not found: {source}") from None
    except IsADirectoryError:
        raise _InputError(f"survey file is a directory: {source}") from None
    except OSError as exc:
        raise _InputError(f"cannot read survey file {source}: {exc.strerror or exc}") from None
    except SurveyError as exc:
        raise _InputError(str(exc)) from None

    out = Path(args.output) if args.output else Path.cwd() / (source.stem + ".nc")
    if out.is_dir():
        raise _InputError(f"output path is a directory: {out}")
    if out.exists() and not args.overwrite:
        raise _InputError(f"output file exists: {out} (use --overwrite to replace it)")
    if not out.parent.is_dir():
        raise _InputError(f"output directory does not exist: {out.parent}")

    t0 = time.perf_counter()
    progress = None if args.quiet else Progress(sys.stderr)
    try:
        ds = survey.run(progress=progress)
    except (ValueError, NotImplementedError) as exc:  # inputs engine.survey refuses
        raise _InputError(f"{source}: {exc}") from None
    finally:
        if progress is not None:
            progress.close()
    elapsed = time.perf_counter() - t0

    t1 = time.perf_counter()
    try:
        path = write_survey(ds, out, survey, command=command, overwrite=args.overwrite)
    except FileExistsError:  # created by someone else while the survey ran
        raise _InputError(f"output file exists: {out} (use --overwrite to replace it)") from None
    except OSError as exc:
        _error(f"cannot write {out}: {exc.strerror or exc}")
        return 1
    if not args.quiet:
        writing = time.perf_counter() - t1
        print_summary(ds, title=survey.title, elapsed=elapsed, writing=writing, path=path.resolve())
    return 0


def print_summary(
    ds: xr.Dataset,
    *,
    title: str,
    elapsed: float,
    path: Path,
    writing: float | None = None,
    file: TextIO | None = None,
) -> None:
    """Print the grid shape, class counts and fractions, the range of each result variable
    over its finite values, the survey's time ``elapsed`` [s] (and ``writing`` [s]) and the
    output path."""
    from .kernels.physics import CLASS_NAMES

    out = sys.stdout if file is None else file
    dims = ("alpha", "energy", "h", "Lz")
    shape = " x ".join(f"{d} {ds.sizes[d]}" for d in dims if d in ds.sizes)
    total = math.prod(ds.sizes[d] for d in dims if d in ds.sizes)
    lines = [
        title,
        f"  grid    {shape} = {total:,} points",
        f"  method  {ds.attrs.get('method', '?')}",
    ]
    if "orbit_class" in ds:
        counts = np.bincount(ds["orbit_class"].values.ravel(), minlength=len(CLASS_NAMES))
        lines.append("")
        lines.append(f"  {'class':<12}{'count':>12}{'fraction':>10}")
        for name, n in zip(CLASS_NAMES, counts, strict=False):
            lines.append(f"  {name:<12}{n:>12,}{n / max(total, 1):>10.4f}")
    lines.append("")
    lines.append(f"  {'variable':<16}{'min':>13}{'max':>13}  units  (finite values)")
    for name, var in ds.data_vars.items():
        if name == "orbit_class" or var.dtype.kind != "f":
            continue
        values = var.values
        finite = values[np.isfinite(values)]
        units = var.attrs.get("units", "")
        if finite.size:
            lo, hi = f"{finite.min():.6g}", f"{finite.max():.6g}"
        else:
            lo = hi = "-"
        lines.append(f"  {name:<16}{lo:>13}{hi:>13}  {units}")
    rate = total / elapsed if elapsed > 0 else float("nan")
    lines.append("")
    wrote = f" + {writing:.2f} s writing" if writing is not None else ""
    lines.append(f"  time    {elapsed:.2f} s survey ({rate:,.0f} points/s){wrote}")
    lines.append(f"  output  {path}")
    print("\n".join(lines), file=out)


if __name__ == "__main__":
    raise SystemExit(main())

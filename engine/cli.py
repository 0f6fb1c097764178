"""The ``conesurvey`` command line: ``conesurvey run SURVEY.toml [-o OUT.nc]``.

Exit status: 0 success; 1 the output could not be written; 2 bad input (an invalid or missing
survey file, an existing output without ``--overwrite``); 130 interrupted. On any failure no
output file is created and an existing one is left as it was.
"""

from __future__ import annotations

import argparse
import shlex
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

from . import commands_look
from ._version import __version__
from .grid import BLOCK_POINTS
from .io import OutputError
from .io.blocks import estimate_bytes
from .io.netcdf import ZLIB_LEVEL, read_info
from .kernels.geometry import CLASS_NAMES
from .progress import Progress
from .runner import AlreadyComplete, RunError, RunStats, run_survey
from .schema import DIMS
from .surveyfile import Survey, SurveyError, load_survey

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
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    run = sub.add_parser(
        "run",
        help="run a survey definition and write a netCDF file",
        description=RUN_DESCRIPTION,
        epilog=EPILOG,
        formatter_class=fmt,
    )
    _add_run_arguments(run)
    info = sub.add_parser(
        "info",
        help="show the definition, completion state, class counts and provenance of a result",
        description="Describe a conesurvey result file (or the unfinished run behind it).",
        formatter_class=fmt,
    )
    info.add_argument("file", metavar="FILE.nc", help="a conesurvey netCDF result")
    validate = sub.add_parser(
        "validate",
        help="check a survey definition; print grid size, output size and run-time estimate",
        description="Check SURVEY.toml without running it (exit 2 if it is invalid).",
        formatter_class=fmt,
    )
    validate.add_argument("survey", metavar="SURVEY.toml", help="survey definition (TOML)")
    commands_look.register(sub)
    return parser


def _add_run_arguments(run: argparse.ArgumentParser) -> None:
    """The options of ``conesurvey run``."""
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
    run.add_argument(
        "--block-points",
        type=_positive_int,
        metavar="N",
        help=f"points per block computed and stored at a time (default {BLOCK_POINTS:,}); "
        "memory grows with N, not with the grid",
    )
    # The option's former name, hidden ("chunk" means the netCDF storage chunk): old scripts run.
    run.add_argument(
        "--chunk-points", dest="block_points", type=_positive_int, help=argparse.SUPPRESS
    )
    run.add_argument(
        "--complevel",
        type=int,
        choices=range(10),
        default=ZLIB_LEVEL,
        metavar="0-9",
        help=f"zlib level of the output (default {ZLIB_LEVEL}; 0 = uncompressed, several "
        "times faster to write, ~1.7x larger)",
    )
    run.add_argument(
        "--force",
        action="store_true",
        help="run even if the estimated output does not fit on the disk",
    )
    backend = run.add_mutually_exclusive_group()
    backend.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the blocks on an existing dask.distributed cluster (e.g. tcp://host:8786)",
    )
    backend.add_argument(
        "--workers",
        type=_positive_int,
        metavar="N",
        help="start a local dask cluster of N worker processes (numba threads split among them)",
    )


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return n


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
        if args.command == "info":
            return _info(args)
        if args.command == "validate":
            return _validate(args)
        if args.command in commands_look.COMMANDS:
            return commands_look.run(args)
        raise AssertionError(f"unhandled command {args.command!r}")  # pragma: no cover
    except _InputError as exc:
        _error(str(exc))
        return 2
    except KeyboardInterrupt:
        _error("interrupted; finished blocks are kept: run the same command again to resume")
        return 130


def _error(message: str) -> None:
    print(f"{PROG}: error: {message}", file=sys.stderr)


def _load(path: str) -> Survey:
    source = Path(path)
    try:
        return load_survey(source)
    except FileNotFoundError:
        raise _InputError(f"survey file not found: {source}") from None
    except IsADirectoryError:
        raise _InputError(f"survey file is a directory: {source}") from None
    except OSError as exc:
        raise _InputError(f"cannot read survey file {source}: {exc.strerror or exc}") from None
    except SurveyError as exc:
        raise _InputError(str(exc)) from None


#: Exact-path throughput assumed by ``validate`` [points/s] (2 cores, see the README).
EXACT_RATE = 2.0e6
#: Integrator throughput assumed by ``validate`` [orbits/s] at rtol 1e-10 on 2 cores.
INTEGRATOR_RATE = 2.0e4


def _estimates(survey: Survey) -> tuple[int, float]:
    """(uncompressed output bytes, estimated run time [s])."""
    rate = EXACT_RATE if survey.method == "exact" else INTEGRATOR_RATE
    return estimate_bytes(survey), survey.size / rate


def _run(args: argparse.Namespace, command: str) -> int:
    source = Path(args.survey)
    survey = _load(args.survey)
    out = Path(args.output) if args.output else Path.cwd() / (source.stem + ".nc")
    if out.is_dir():
        raise _InputError(f"output path is a directory: {out}")
    if not out.parent.is_dir():
        raise _InputError(f"output directory does not exist: {out.parent}")
    need, _ = _estimates(survey)
    free = shutil.disk_usage(out.parent).free
    if need > free and not args.force:
        raise _InputError(
            f"the survey needs up to {_size(need)} of disk for its blocks but {out.parent} has "
            f"{_size(free)} free ({survey.size:,} points); use --force to run anyway"
        )
    progress = None if args.quiet else Progress(sys.stderr)
    try:
        stats = run_survey(
            survey,
            out,
            block_points=args.block_points,
            overwrite=args.overwrite,
            progress=progress,
            scheduler=args.scheduler,
            workers=args.workers,
            command=command,
            complevel=args.complevel,
        )
    except AlreadyComplete as exc:
        if progress is not None:
            progress.close()
        print(f"{PROG}: {exc}")
        return 0
    except RunError as exc:
        raise _InputError(str(exc)) from None
    except (ValueError, NotImplementedError) as exc:  # inputs the engine refuses
        raise _InputError(f"{source}: {exc}") from None
    except OSError as exc:
        _error(f"cannot write {out}: {exc.strerror or exc}")
        return 1
    finally:
        if progress is not None:
            progress.close()
    if not args.quiet:
        print_summary(stats, title=survey.title, method=survey.method)
    return 0


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} TB"  # pragma: no cover


def _validate(args: argparse.Namespace) -> int:
    survey = _load(args.survey)
    need, seconds = _estimates(survey)
    shape = " x ".join(f"{d} {n}" for d, n in zip(DIMS, survey.shape, strict=True))
    print(f"{args.survey}: valid")
    print(f"  title   {survey.title}")
    print(
        f"  method  {survey.method}"
        + (f" (rtol {survey.rtol:g})" if survey.method != "exact" else "")
    )
    print(f"  grid    {shape} = {survey.size:,} points")
    print(f"  output  about {_size(need)} uncompressed (zlib shrinks it, class maps ~150x)")
    print(f"  time    about {seconds:.3g} s on 2 cores")
    return 0


def _info(args: argparse.Namespace) -> int:
    path = Path(args.file)
    try:
        info = read_info(path)
    except OutputError as exc:
        raise _InputError(str(exc)) from None
    attrs = info.get("attrs", {})
    print(f"{path}")
    state = "complete" if info.get("complete") else "unfinished"
    if "blocks_done" in info:
        state += f" ({info['blocks_done']}/{info['blocks_total']} blocks stored; rerun to resume)"
    print(f"  state       {state}")
    dims = info.get("dims", {})
    print("  grid        " + " x ".join(f"{d} {n}" for d, n in dims.items()))
    for key in ("title", "source", "method", "history", "survey_fingerprint", "engine"):
        if key in attrs:
            text = str(attrs[key]).replace("\n", "\n              ")
            print(f"  {key:<12}{text}")
    if "counts" in info:
        total = max(1, sum(info["counts"].values()))
        print("  classes")
        for name, n in info["counts"].items():
            print(f"    {name:<12}{n:>14,}{n / total:>10.4f}")
    definition = attrs.get("survey_definition")
    if definition:
        print("  survey definition:")
        for line in str(definition).splitlines():
            print(f"    {line}")
    return 0


def print_summary(stats: RunStats, *, title: str, method: str, file: TextIO | None = None) -> None:
    """Print the grid, class counts and fractions, the range of each result variable over its
    finite values, the time taken and the output path."""
    out = sys.stdout if file is None else file
    total = stats.points
    shape = " x ".join(f"{d} {n}" for d, n in zip(DIMS, stats.shape, strict=True))
    lines = [title, f"  grid    {shape} = {total:,} points", f"  method  {method}", ""]
    lines.append(f"  {'class':<12}{'count':>12}{'fraction':>10}")
    for name, n in zip(CLASS_NAMES, stats.counts, strict=True):
        lines.append(f"  {name:<12}{n:>12,}{n / max(total, 1):>10.4f}")
    lines.append("")
    lines.append(f"  {'variable':<16}{'min':>13}{'max':>13}  units  (finite values)")
    for name, (lo, hi, units) in stats.ranges.items():
        lines.append(f"  {name:<16}{lo:>13.6g}{hi:>13.6g}  {units}")
    lines.append("")
    rate = total / stats.compute_seconds if stats.compute_seconds > 0 else float("nan")
    reused = (
        f", {stats.blocks_reused} of {stats.blocks_total} blocks from an earlier run"
        if stats.blocks_reused
        else ""
    )
    lines.append(
        f"  time    {stats.compute_seconds:.2f} s computing ({rate:,.0f} points/s{reused}) "
        f"+ {stats.write_seconds:.2f} s writing + {stats.compile_seconds:.2f} s compiling "
        "(numba, cached after the first run)"
    )
    lines.append(f"  output  {stats.path.resolve() if stats.path else '?'}")
    print("\n".join(lines), file=out)


if __name__ == "__main__":
    raise SystemExit(main())

"""``conesurvey run SURVEY.toml [-o OUT.nc]``: a streamed, resumable survey run.

Exit status: 0 success (or nothing to do); 1 the run stopped after it began to write (a full
disk, a lost dask cluster: the stored blocks are kept, the same command resumes); 2 refused
before anything was written (an invalid survey, an existing output, another run of the same
output, too little disk); 130 interrupted.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from ..checks import PlanError, check_block_points
from ..errortext import install_hint
from ..grid import BLOCK_POINTS
from ..io.codecs import COMPRESSIONS, DEFAULT_COMPRESSION, DEFAULT_LEVELS
from ..io.formats import FORMATS, format_for, formats_text
from ..io.manifest import fingerprint
from ..plan import RunPlan, plan_from_survey
from ..progress import Progress
from ..runner import AlreadyComplete, RunError, RunFailed, RunStats, run_survey
from ..schema import flag_table
from ..surveyhelp import survey_file_help
from . import PROG, Command, InputError, error, load
from .validate import compile_seconds, energy_warning

if TYPE_CHECKING:
    from ..surveyfile import Survey

__all__ = ["COMMAND", "print_summary"]


DESCRIPTION = f"""\
Run the survey defined in SURVEY.toml and write the results to a netCDF file (or a Zarr
store: -o OUT.zarr).

A survey file holds (see the examples in surveys/ and docs/surveys.md):

{survey_file_help()}

The TOML text is stored verbatim in the output's survey_definition attribute. The first run
compiles the numba kernels (cached: later runs load them). One run at a time writes an output
(a lock file OUT.lock beside it); a killed run resumes where it stopped when the same command
is run again, and says so (docs/guarantees.md)."""

EPILOG = """\
example:
  conesurvey run surveys/gravity_precession.toml -o gravity_precession.nc
  conesurvey plot gravity_precession.nc precession_rate --facet alpha
  python -c "import xarray as xr; print(xr.open_dataset('gravity_precession.nc'))"

exit status: 0 success, 1 stopped after writing began (resumable: run the same command
again), 2 bad input or usage, nothing written, 130 interrupted"""

RESUMABLE = "the run is resumable: run the same command again"


def add_arguments(run: argparse.ArgumentParser) -> None:
    """The options of ``conesurvey run``."""
    run.add_argument("survey", metavar="SURVEY.toml", help="survey definition (TOML)")
    run.add_argument(
        "-o",
        "--output",
        metavar="OUT.nc",
        help="output netCDF file, or a Zarr store if the name ends in .zarr (default: SURVEY's "
        "stem + .nc in the current directory)",
    )
    run.add_argument(
        "--overwrite", action="store_true", help="replace OUT.nc if it exists (default: refuse)"
    )
    run.add_argument(
        "-q", "--quiet", action="store_true", help="no progress bar and no summary; errors only"
    )
    run.add_argument(
        "--block-points",
        type=_block_points,
        metavar="N",
        help=f"points per block computed and stored at a time (default {BLOCK_POINTS:,}); "
        "memory grows with N, not with the grid",
    )
    # The option's former name, hidden ("chunk" means the netCDF storage chunk): old scripts run.
    run.add_argument(
        "--chunk-points", dest="block_points", type=_block_points, help=argparse.SUPPRESS
    )
    run.add_argument(
        "--compression",
        choices=COMPRESSIONS,
        default=None,
        help=f"how the output's variables are compressed (default {DEFAULT_COMPRESSION} for "
        "netCDF, read by every netCDF-4 tool; a Zarr store takes blosc_lz4, its default, or "
        "none); docs/output.md says what each choice costs, saves and which tools read it",
    )
    run.add_argument(
        "--complevel",
        type=int,
        choices=range(10),
        default=None,
        metavar="0-9",
        help="compression level (default: "
        + ", ".join(f"{n} {lvl}" for n, lvl in DEFAULT_LEVELS.items() if lvl)
        + "; 0 = uncompressed)",
    )
    run.add_argument(
        "--force",
        action="store_true",
        help="run even if the blocks and the output do not seem to fit on the disk",
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


def _block_points(text: str) -> int:
    """``--block-points N``, by the API's check (:func:`engine.checks.check_block_points`)."""
    try:
        n: int | str = int(text)
    except ValueError:
        n = text  # not an integer: refused below
    try:
        return check_block_points(n)
    except PlanError as exc:
        raise argparse.ArgumentTypeError(f"{exc.problem}, got {text!r}") from None


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return n


def _output(args: argparse.Namespace, source: Path) -> Path:
    """The output path; InputError if it is a directory, has no directory, or is the survey."""
    out = Path(args.output) if args.output else Path.cwd() / (source.stem + ".nc")
    if not any(fmt.owns(out) for fmt in FORMATS.values()):  # not netCDF whatever its name
        found = f"unknown suffix {out.suffix!r}" if out.suffix else "no suffix"
        raise InputError(f"output {out}: {found}; the suffix names the format: "
                         f"{formats_text()}")  # fmt: skip
    if out.is_dir() and not format_for(out).directory:  # a Zarr store is a directory
        raise InputError(f"output path is a directory: {out}")
    if not out.parent.is_dir():
        raise InputError(f"output directory does not exist: {out.parent}")
    same = out.resolve() == source.resolve()
    if not same and out.exists():
        try:
            same = os.path.samefile(out, source)
        except OSError:
            same = False
    if same:
        raise InputError(f"the output {out} is the survey file itself; give another -o")
    return out


def _run(args: argparse.Namespace, command: str) -> int:
    source = Path(args.survey)
    survey = load(args.survey)
    plan = plan_from_survey(survey)  # checked already by load: the estimates' plan
    out = _output(args, source)
    if (warning := energy_warning(plan)) is not None:
        print(f"{PROG}: warning: {warning}", file=sys.stderr)
    if args.scheduler is not None or args.workers is not None:
        _quiet_dask("--workers" if args.workers is not None else "--scheduler")
    progress = None if args.quiet else Progress(sys.stderr)
    if progress is not None:
        progress.kernels_cached = compile_seconds(plan) == 0.0
    before = _identity(out)
    try:
        return _run_and_report(args, command, survey, plan, source, out, progress)
    except KeyboardInterrupt:
        if not _finished_since(out, plan, before):
            raise
        _close(progress)
        error(f"interrupted after the run had finished: {out} is complete; nothing to resume")
        return 130


def _identity(out: Path) -> tuple[int, int] | None:
    """(device, inode) of the output as it is now (None: none): a finished run renames a new
    file or store into place, so the output it leaves has another."""
    try:
        st = os.lstat(out)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def _finished_since(out: Path, plan: RunPlan, before: tuple[int, int] | None) -> bool:
    """Whether this run renamed its complete output into place (a Ctrl-C after that point
    interrupts only the tidying and the summary: nothing is left to resume)."""
    now = _identity(out)
    if now is None or now == before:
        return False
    try:
        return format_for(out).read_fingerprint(out) == fingerprint(plan)
    except (OSError, ValueError):
        return False


def _run_and_report(
    args: argparse.Namespace,
    command: str,
    survey: Survey,
    plan: RunPlan,
    source: Path,
    out: Path,
    progress: Progress | None,
) -> int:
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
            compression=args.compression,
            complevel=args.complevel,
            check_space=not args.force,
        )
    except AlreadyComplete as exc:
        if progress is not None:
            progress.close()
        print(f"{PROG}: {exc}")
        return 0
    except RunError as exc:
        raise InputError(str(exc)) from None
    except RunFailed as exc:
        _close(progress)
        error(f"{exc}; {RESUMABLE}")
        return 1
    except (ValueError, NotImplementedError) as exc:  # inputs the engine refuses
        raise InputError(f"{source}: {exc}") from None
    except OSError as exc:
        _close(progress)
        error(f"cannot write {out}: {exc.strerror or exc}; {RESUMABLE}")
        return 1
    finally:
        _close(progress)
    if not args.quiet:
        print_summary(stats, title=plan.title, method=plan.method.name, kind=plan.map_kind)
    return 0


def _quiet_dask(option: str) -> None:
    """Silence distributed's loggers (they print tracebacks when a cluster goes away): the
    command reports a failed cluster itself, in one line. distributed sets its loggers' levels
    when it is imported, so it is imported first. Without it, ``option`` is a usage error."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise InputError(
            f"{option} needs dask.distributed, which is not installed; {install_hint('dask')}"
        ) from None
    for name in list(logging.root.manager.loggerDict):
        if name == "distributed" or name.startswith("distributed."):
            logging.getLogger(name).setLevel(logging.CRITICAL)


def _close(progress: Progress | None) -> None:
    if progress is not None:
        progress.close()


def print_summary(
    stats: RunStats,
    *,
    title: str,
    method: str,
    file: TextIO | None = None,
    kind: str | None = None,
) -> None:
    """Print the grid, class counts and fractions (and the fates of a fate map of ``kind``),
    the range of each result variable over its finite values, the time taken and the output
    path."""
    out = sys.stdout if file is None else file
    total = stats.points
    shape = " x ".join(f"{d} {n}" for d, n in zip(stats.dims, stats.shape, strict=True))
    lines = [title, f"  grid    {shape} = {total:,} points", f"  method  {method}", ""]
    classes = tuple(n for _, n in flag_table("orbit_class", kind))
    counts = stats.counts[: len(classes)]
    tables = [("class", classes, counts)]
    if "fate" in stats.flags:  # a fate map: what happened to each ball first
        codes, names = zip(*flag_table("fate", kind), strict=True)
        tables.insert(0, ("fate", names, stats.flags["fate"][list(codes)]))
        ideal = "surface" if kind is not None and kind.startswith("surface") else "cone"
        tables[1] = ("class", classes, counts, f"  (the launch orbits on the ideal {ideal})")
    for i, (label, names, counts, *note) in enumerate(tables):
        lines += [""] if i else []
        lines.append(f"  {label:<12}{'count':>12}{'fraction':>10}" + "".join(note))
        for name, n in zip(names, counts, strict=True):
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
        f"  time    {stats.compute_seconds:.2f} s computing ({rate:,.0f} points/s{reused}; "
        f"the output written meanwhile) + {stats.write_seconds:.2f} s finishing the output + "
        f"{stats.compile_seconds:.2f} s compiling the kernels (or loading them from the cache)"
    )
    lines.append(f"  output  {stats.path.resolve() if stats.path else '?'}")
    print("\n".join(lines), file=out)


COMMAND = Command(
    name="run",
    help="run a survey definition and write a netCDF file or a Zarr store",
    description=DESCRIPTION,
    add_arguments=add_arguments,
    run=_run,
    epilog=EPILOG,
)

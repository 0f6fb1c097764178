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
from typing import TextIO

from ..grid import BLOCK_POINTS
from ..io import zarr as zarr_io
from ..io.codecs import COMPRESSIONS, DEFAULT_COMPRESSION, DEFAULT_LEVELS
from ..kernels.fate import FATE_NAMES
from ..kernels.geometry import CLASS_NAMES
from ..progress import Progress
from ..runner import AlreadyComplete, RunError, RunFailed, RunStats, run_survey
from . import PROG, Command, InputError, error, load

__all__ = ["COMMAND", "print_summary"]

DESCRIPTION = """\
Run the survey defined in SURVEY.toml and write the results to a netCDF file (or a Zarr
store: -o OUT.zarr).

The definition names the scene ([scene]: M [kg], g [m s-2], a [m], k, rim [m]), the method
and the four axes [axes.alpha] [radian], [axes.energy] (radial energy [J], or relative to
V_min with relative_to = "V_min"), [axes.h] [m s-1] and [axes.Lz] [kg m2 s-1], each either
values = [...] or start, stop, num with scale = "linear" or "log". See the examples in
surveys/ and the README's survey format. The TOML text is stored verbatim in the output's
survey_definition attribute.

One run at a time writes an output (a lock file OUT.lock beside it); a killed run resumes
where it stopped when the same command is run again (README: "Guarantees")."""

EPILOG = """\
example:
  conesurvey run surveys/gravity_precession.toml -o precession.nc
  python -c "import xarray as xr; print(xr.open_dataset('precession.nc'))"

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
        "--compression",
        choices=COMPRESSIONS,
        default=None,
        help=f"how the output's variables are compressed (default {DEFAULT_COMPRESSION}: "
        "deflate with shuffle, read by every netCDF-4/HDF5 tool, compressed on every core; "
        "blosc_lz4, zstd: need HDF5 filter plugins to read; a Zarr store takes blosc_lz4 "
        "(its default) or none; docs/output.md)",
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
    if out.is_dir() and not zarr_io.is_zarr(out):  # a Zarr store is a directory
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
    out = _output(args, source)
    if args.scheduler is not None or args.workers is not None:
        _quiet_dask()
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
        print_summary(stats, title=survey.title, method=survey.method)
    return 0


def _quiet_dask() -> None:
    """Silence distributed's loggers (they print tracebacks when a cluster goes away): the
    command reports a failed cluster itself, in one line. distributed sets its loggers' levels
    when it is imported, so it is imported first."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return  # the backend says how to install it
    for name in list(logging.root.manager.loggerDict):
        if name == "distributed" or name.startswith("distributed."):
            logging.getLogger(name).setLevel(logging.CRITICAL)


def _close(progress: Progress | None) -> None:
    if progress is not None:
        progress.close()


def print_summary(stats: RunStats, *, title: str, method: str, file: TextIO | None = None) -> None:
    """Print the grid, class counts and fractions, the range of each result variable over its
    finite values, the time taken and the output path."""
    out = sys.stdout if file is None else file
    total = stats.points
    shape = " x ".join(f"{d} {n}" for d, n in zip(stats.dims, stats.shape, strict=True))
    lines = [title, f"  grid    {shape} = {total:,} points", f"  method  {method}", ""]
    lines.append(f"  {'class':<12}{'count':>12}{'fraction':>10}")
    for name, n in zip(CLASS_NAMES, stats.counts, strict=True):
        lines.append(f"  {name:<12}{n:>12,}{n / max(total, 1):>10.4f}")
    if "fate" in stats.flags:
        lines += ["", f"  {'fate':<12}{'count':>12}{'fraction':>10}"]
        for name, n in zip(FATE_NAMES, stats.flags["fate"], strict=True):
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
        f"{stats.compile_seconds:.2f} s compiling (numba, cached after the first run)"
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

"""``conesurvey convert SRC DST``: a finished result to the other format (netCDF <-> Zarr).

The output's format follows its name (``.zarr``: a Zarr store, anything else: netCDF-4). The
copy is exact and checked (:mod:`engine.io.convert`): the source's content checksum is verified
as its values are copied and the output records the same one. Refusals come before anything is
written (exit 2): a missing, unfinished, unreadable or damaged source (its values do not match
its recorded content checksum), an output of the same format, an existing output without
``--overwrite``, another run or conversion writing the output, too little disk. A refusal or a
failed write (exit 1) leaves nothing under the output's name.
"""

from __future__ import annotations

import argparse
import os
import shutil
from pathlib import Path

from ..io import OutputError, WriteError
from ..io.atomic import output_name_problem
from ..io.convert import convert, output_bytes
from ..io.formats import format_for
from ..io.lock import Locked, LockError, OutputLock, describe_holder
from ..io.manifest import parts_dir
from ..progress import format_bytes
from . import PROG, Command, InputError, error

__all__ = ["COMMAND"]

DESCRIPTION = """\
Copy a finished result to the other format: OUT.nc to OUT.zarr, or OUT.zarr to OUT.nc. The
output's format follows its name (.zarr: a Zarr store, anything else: netCDF-4).

The copy is exact: the same values bit for bit, the same attributes and chunks, one more
history line. The source's content checksum is verified while its values are copied, and
the output records the same checksum, so 'conesurvey info --verify DST' checks the copy
against the original run.

Refused before anything is written (exit status 2): a missing, unfinished, unreadable or
damaged source, an output of the source's format, an existing output without --overwrite,
another run or conversion writing the output, too little disk space. A failed write
(exit status 1) leaves nothing under the output's name."""

EPILOG = """\
examples:
  conesurvey convert precession.zarr precession.nc
  conesurvey convert precession.nc precession.zarr --overwrite

exit status: 0 converted, 1 the output could not be written (nothing left under its name),
2 bad input (a missing, unfinished or damaged source too), nothing written"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", metavar="SRC", help="a finished result: OUT.nc or OUT.zarr")
    parser.add_argument(
        "output", metavar="DST", help="the output: a Zarr store if it ends in .zarr, else netCDF"
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace DST if it exists (default: refuse)"
    )
    parser.add_argument(
        "--force", action="store_true", help="convert even if DST does not seem to fit on the disk"
    )


def _format(path: Path) -> str:
    return format_for(path).label


def _check_names(source: Path, out: Path) -> None:
    """InputError for the refusals that the names alone decide (before any lock is taken)."""
    if not os.path.lexists(source):
        if parts_dir(source).is_dir():
            raise InputError(
                f"{source} is an unfinished run ({parts_dir(source).name}/ holds its blocks); "
                "run it again to finish it, then convert"
            )
        raise InputError(f"no such result: {source}")
    if _format(source) == _format(out):
        raise InputError(f"{source} and {out} are both {_format(out)}; nothing to convert")
    if not out.parent.is_dir():
        raise InputError(f"output directory does not exist: {out.parent}")
    if why := output_name_problem(out):
        raise InputError(why)


def _check(source: Path, out: Path, args: argparse.Namespace) -> None:
    """InputError for every other refusal that needs no writing."""
    if os.path.lexists(out) and not args.overwrite:
        raise InputError(f"output exists: {out} (use --overwrite to replace it)")
    if not args.force:
        need = output_bytes(source, out)
        free = shutil.disk_usage(out.parent).free
        if need > free:
            raise InputError(
                f"the output needs up to {format_bytes(need)} but {out.parent} has "
                f"{format_bytes(free)} free; use --force to convert anyway"
            )


def _convert(args: argparse.Namespace, command: str) -> int:
    source, out = Path(args.source), Path(args.output)
    _check_names(source, out)
    try:
        with OutputLock.acquire(out, command), OutputLock.acquire(source, command):
            _check(source, out, args)
            try:
                done = convert(source, out, command=command, overwrite=args.overwrite)
            except FileExistsError:
                raise InputError(f"output exists: {out} (use --overwrite)") from None
            except WriteError as exc:
                error(f"{exc}; nothing was written")
                return 1
            except OSError as exc:
                error(f"cannot write {out}: {exc.strerror or exc}; nothing was written")
                return 1
    except Locked as exc:
        raise InputError(
            f"another run is writing {exc.path.name[: -len('.lock')]} "
            f"({describe_holder(exc.holder)}); try again when it has finished"
        ) from None
    except LockError as exc:
        raise InputError(str(exc)) from None
    except OutputError as exc:  # unreadable, unfinished or damaged: nothing was written
        raise InputError(str(exc)) from None
    carried = "carried over" if done.checksum == done.source_checksum else "computed"
    print(f"{PROG}: wrote {out} ({_format(out)}, {done.blocks} blocks)")
    print(f"  content_checksum {done.checksum} ({carried}; the source's was verified)"
          if done.source_checksum else f"  content_checksum {done.checksum} (new; "
          "unverified source: it had no content checksum)")  # fmt: skip
    return 0


COMMAND = Command(
    name="convert",
    help="convert a finished result between netCDF and Zarr (checksum verified and kept)",
    description=DESCRIPTION,
    add_arguments=add_arguments,
    run=_convert,
    epilog=EPILOG,
)

"""The ``conesurvey`` command line: ``conesurvey run SURVEY.toml [-o OUT.nc]``, ``validate``,
``info``, ``plot``, ``report``, ``orbit``, ``convert``.

Each command lives in its own module of :mod:`engine.commands` and is registered here with
:func:`register` (a new command is one module and one ``register`` call).

Exit status: 0 success; 1 the run stopped after it began to write (resumable) or ``info
--verify`` found damage; 2 bad input (an invalid or missing survey file, an existing output
without ``--overwrite``, another run writing the same output), nothing written; 130
interrupted; 141 (128 + SIGPIPE) when the reader of the output went away (``info ... | head
-1``). On any failure no output file is created and an existing one is left as it was.
"""

from __future__ import annotations

import argparse
import errno
import os
import shlex
import sys
from collections.abc import Sequence

from ._startup import INTERRUPTED, started
from ._version import __version__
from .commands import PROG, Command, InputError, error
from .commands import accuracy as _accuracy
from .commands import convert as _convert
from .commands import info as _info
from .commands import look as _look
from .commands import orbit as _orbit
from .commands import run as _run
from .commands import validate as _validate
from .commands.interrupts import interrupts_outside_compile_hooks

__all__ = ["COMMANDS", "build_parser", "main", "register"]

DESCRIPTION = """\
Orbit surveys of a sphere inside a cone: rolling without slipping on the ideal cone, and on a
scene with rolling resistance, a rim, a friction limit, sliding under kinetic friction and
spin friction.

A survey evaluates every point of the grid alpha x energy x h x Lz (from a TOML survey
definition) or over launch states alpha x r0 x v0 x w0 (and, where the ball may slide, its
radial speed u0 and slip or backspin at release), classifies each orbit (forbidden, bounded,
circular, hyperbolic, radial, spills, slips, off_cone, out_of_range) and stores turning
points, period, apsidal angle, precession rate, the friction needed to roll and, on a scene
with effects, each orbit's fate (rolling, spilled, slipped or sliding, rest, vertex) and where
and when it came, in a CF-1.11 netCDF file (or a Zarr store). plot and report show a result;
orbit draws one orbit on its cone (and animates it)."""

#: The registered commands, by name, in the order ``--help`` lists them.
COMMANDS: dict[str, Command] = {}
#: Exit status when stdout's reader went away (as for a process killed by SIGPIPE).
BROKEN_PIPE = 141


def register(command: Command) -> None:
    """Add ``command`` to the command line (ValueError if its name is taken)."""
    if command.name in COMMANDS:
        raise ValueError(f"a command {command.name!r} is already registered")
    COMMANDS[command.name] = command


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``conesurvey``."""
    fmt = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(
        prog=PROG, description=DESCRIPTION, epilog=_run.EPILOG, formatter_class=fmt
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in COMMANDS.values():
        p = sub.add_parser(
            command.name,
            help=command.help,
            description=command.description,
            epilog=command.epilog,
            formatter_class=fmt,
        )
        command.add_arguments(p)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``conesurvey`` command line with ``argv`` (default ``sys.argv[1:]``).

    Returns the exit status; ``--help``, ``--version`` and usage errors exit through
    ``SystemExit`` as argparse does.
    """
    args_list = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(args_list)
    command_line = shlex.join([PROG, *args_list])
    try:
        with interrupts_outside_compile_hooks():  # a Ctrl-C while numba loads a kernel, too
            status = COMMANDS[args.command].run(args, command_line)
        sys.stdout.flush()  # a closed pipe shows up here, inside the handler below
        return status
    except InputError as exc:
        error(str(exc))
        return 2
    except KeyboardInterrupt:
        error("interrupted; finished blocks are kept: run the same command again to resume")
        return INTERRUPTED
    except BrokenPipeError:
        _silence_stdout()
        return BROKEN_PIPE
    except OSError as exc:  # stdout on a full device (/dev/full), EIO: the work itself is done
        if not _stdout_fails(exc):
            raise
        _silence_stdout()
        error(f"cannot write the standard output: {exc.strerror or exc}")
        return 1


def _stdout_fails(exc: OSError) -> bool:
    """Whether ``exc`` is a failed write of the standard output (no file name: the commands
    name the files they write), or flushing it fails again."""
    if exc.filename is None and exc.errno in (errno.ENOSPC, errno.EIO, errno.EDQUOT):
        return True
    try:
        sys.stdout.flush()
    except OSError:
        return True
    return False


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so that the interpreter's final flush cannot fail again (the
    recipe of the Python documentation, "Note on SIGPIPE")."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, ValueError, OSError):
        return  # not a real file (a test's capture): nothing will be flushed to a pipe
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)


for _command in (
    _run.COMMAND,
    _validate.COMMAND,
    _info.COMMAND,
    _look.PLOT,
    _look.REPORT,
    _orbit.COMMAND,
    _convert.COMMAND,
    _accuracy.COMMAND,
):
    register(_command)


if __name__ == "__main__":
    started()  # Python's SIGINT handler again (engine/_startup.py guarded the imports)
    try:
        raise SystemExit(main())
    except KeyboardInterrupt:  # before main's own handling starts (parsing the arguments)
        error("interrupted; nothing written")
        raise SystemExit(INTERRUPTED) from None

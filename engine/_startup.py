"""A Ctrl-C while ``python -m engine.cli`` starts ends as the ``conesurvey`` console script's
does (conesurvey_cli.py): one line on stderr, exit status 130, nothing written.

``python -m engine.cli`` imports this package (numpy, xarray, numba: seconds on a cold start)
before engine/cli.py runs, so no handler in engine/cli.py can catch an interrupt there. The
package imports this module first: when the interpreter was started as ``python -m
engine.cli``, it installs a SIGINT handler that ends the start-up so; engine/cli.py puts
Python's own handler back (:func:`started`) just before it runs the command, whose Ctrl-C
handling then applies. Imported any other way (the console script, a library, the tests) it
does nothing.
"""

from __future__ import annotations

import signal
import sys
from types import FrameType

__all__ = ["INTERRUPTED", "as_module_command", "started"]

#: Exit status of an interrupted command (128 + SIGINT).
INTERRUPTED = 130
#: The module whose ``python -m`` start this guards.
COMMAND_MODULE = "engine.cli"
#: The interpreter's options that take the next argument as their value.
_WITH_VALUE = ("-X", "-W", "--check-hash-based-pycs")


def as_module_command(argv: list[str]) -> bool:
    """Whether the interpreter's command line ``argv`` (``sys.orig_argv``) runs
    ``python [options] -m engine.cli ...``."""
    args = iter(argv[1:])
    for arg in args:
        if arg == "-m":
            return next(args, None) == COMMAND_MODULE
        if arg.startswith("-m"):
            return arg[2:] == COMMAND_MODULE
        if arg in _WITH_VALUE:
            next(args, None)  # -X importtime, -W ignore
        elif arg in ("-c", "-") or not arg.startswith("-"):
            return False  # a script, -c or stdin: not -m
    return False


def _interrupted(signum: int, frame: FrameType | None) -> None:
    print("conesurvey: error: interrupted; nothing written", file=sys.stderr)
    raise SystemExit(INTERRUPTED)


def started() -> None:
    """The command is about to run: Python's own SIGINT handler again (if this module's was
    installed)."""
    if signal.getsignal(signal.SIGINT) is _interrupted:
        signal.signal(signal.SIGINT, signal.default_int_handler)


if as_module_command(getattr(sys, "orig_argv", [])) and (
    signal.getsignal(signal.SIGINT) is signal.default_int_handler
):
    signal.signal(signal.SIGINT, _interrupted)

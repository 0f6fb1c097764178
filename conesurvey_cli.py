"""The ``conesurvey`` console script: :func:`engine.cli.main`, with the package imported inside
the handler of a Ctrl-C.

Importing ``engine`` loads numpy, xarray and numba (seconds on a cold start); a Ctrl-C in that
time would otherwise end in a KeyboardInterrupt traceback. Here it ends as any interrupted
command does: one line on stderr and exit status 130, nothing written. This module lives outside
the package because ``engine/__init__.py`` runs before any module of the package can act.
"""

from __future__ import annotations

import sys

#: Exit status of an interrupted command (128 + SIGINT), as :mod:`engine.cli` documents.
INTERRUPTED = 130


def main() -> int:
    """Run the ``conesurvey`` command line (``sys.argv``); its exit status."""
    try:
        from engine.cli import main as cli_main

        return cli_main()
    except KeyboardInterrupt:
        print("conesurvey: error: interrupted; nothing written", file=sys.stderr)
        return INTERRUPTED


if __name__ == "__main__":
    raise SystemExit(main())

"""The figure scripts' one way to run a conesurvey command in this process (a failure stops the
script naming the command and its exit status), and their one rule for where they write: the
folder ``--out`` names, by default the working directory (never the checkout's tracked
figures unless asked: ``--out docs/figures``)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from engine import cli

#: The help of every script's --tiny flag.
TINY_HELP = (
    "a smoke run (tests/test_scripts.py): seconds once the kernels are compiled; a first run "
    "compiles them (minutes, announced on stderr)"
)


def add_out(parser: argparse.ArgumentParser) -> None:
    """The ``--out DIR`` option: where the script writes (default: the working directory)."""
    parser.add_argument(
        "--out", type=Path, default=Path.cwd(),
        help="folder to write into (default: the working directory; docs/figures to update "
             "the documentation's figures)",
    )  # fmt: skip


def conesurvey(*args: str | Path) -> None:
    """``conesurvey ARGS``; SystemExit if it does not succeed."""
    status = cli.main([str(a) for a in args])
    if status != 0:
        raise SystemExit(f"conesurvey {args[0]} failed with status {status}")


def shrunk(survey: Path, dest: Path, num: int = 3) -> Path:
    """A copy of ``survey`` in the folder ``dest`` with every ranged axis cut to ``num`` values
    (the scripts' --tiny runs)."""
    out = dest / survey.name
    out.write_text(re.sub(r"(?m)^num\s*=\s*\d+", f"num = {num}", survey.read_text()))
    return out

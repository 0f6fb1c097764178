"""The figure scripts' one way to run a conesurvey command in this process (a failure stops the
script naming the command and its exit status)."""

from __future__ import annotations

from pathlib import Path

from engine import cli


def conesurvey(*args: str | Path) -> None:
    """``conesurvey ARGS``; SystemExit if it does not succeed."""
    status = cli.main([str(a) for a in args])
    if status != 0:
        raise SystemExit(f"conesurvey {args[0]} failed with status {status}")

"""``conesurvey info FILE [--verify]``: what a result (a netCDF file or a Zarr store ``.zarr``, or
the unfinished run behind it) holds, and whether its contents are intact.

It never shows a traceback: a file written by another tool, a damaged file, a block store
without a manifest or with one that is not JSON are described, not crashed on. With
``--verify`` every value is read again and the content checksum recomputed
(:mod:`engine.io.contents`). Exit status: 0 described (and, with ``--verify``, intact); 1
``--verify`` found damage or could not verify; 2 no such file, or not a readable netCDF file.

Leftovers of a finished run (the block store a killed cleanup left beside the file) are removed
here too, unless a run holds the output's lock.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from ..io import OutputError
from ..io.formats import format_for
from ..io.leftovers import remove_leftovers
from ..io.lock import Locked, LockError, OutputLock, describe_holder
from ..io.manifest import MANIFEST, parts_dir, read_manifest
from ..plan import plan_from_survey
from ..surveyfile import SurveyError, parse_survey
from . import Command, InputError

__all__ = ["COMMAND"]

_KEYS = ("title", "source", "method", "history", "survey_fingerprint", "content_checksum")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "file", metavar="FILE", help="a conesurvey result: a netCDF file or a Zarr store (.zarr)"
    )
    parser.add_argument(
        "--verify",
        action="store_true",
        help="read every value again and compare with the content checksum (exit 1 if not)",
    )


def _running(path: Path) -> str | None:
    """Who holds the output's lock (None if nobody, or if it cannot be told here)."""
    try:
        OutputLock.acquire(path, "conesurvey info").release()
    except Locked as exc:
        return describe_holder(exc.holder)
    except LockError:
        return None
    return None


def _store_problem(path: Path) -> str | None:
    """Why the unfinished run behind ``path`` cannot be resumed by the survey its manifest
    records (None if it can, or if that definition no longer parses)."""
    try:
        m = read_manifest(parts_dir(path))
        why = m.mismatch(plan_from_survey(parse_survey(m.survey_definition)))
    except (OutputError, SurveyError, ValueError):
        return None
    return None if why is None else f"its manifest does not match its own survey ({why})"


def _state(info: dict[str, Any], path: Path, verify: bool) -> tuple[str, int]:
    """The state line and the exit status."""
    if not info.get("complete"):
        if "blocks_done" in info and (problem := _store_problem(path)):
            info["problem"] = problem
        if "problem" in info:
            hint = (
                "the next run removes it and starts over"
                if not os.path.lexists(parts_dir(path) / MANIFEST)
                else "run with --overwrite to discard it"
            )
            state = f"unfinished, cannot be resumed: {info['problem']}; {hint}"
        elif "blocks_done" in info:
            state = f"unfinished ({info['blocks_done']}/{info['blocks_total']} blocks stored; "
            state += "rerun to resume)"
        else:
            return "not a finished conesurvey result (no survey fingerprint)", 1 if verify else 0
        holder = _running(path)
        if holder is not None:
            state += f"; a run is writing it now ({holder})"
        return state, 1 if verify else 0
    if not verify:
        extra = (
            "not verified: --verify reads every value"
            if info.get("checksum")
            else "no content checksum recorded"
        )
        return f"complete ({extra})", 0
    ok, found = info["verified"]
    return (f"complete, verified: {found}", 0) if ok else (f"DAMAGED: {found}", 1)


def _printable(text: str) -> str:
    """``text`` with terminal control bytes (escape sequences, carriage returns) written as
    ``\\xNN`` escapes: a title cannot drive the terminal. Newlines are kept."""
    return "".join(
        c if c in "\n\t" or (c.isprintable() and c != "\x7f") else repr(c)[1:-1] for c in text
    )


def _info(args: argparse.Namespace, command: str) -> int:
    path = Path(args.file)
    try:
        info = format_for(path).read_info(path, verify=args.verify)
    except OutputError as exc:
        raise InputError(str(exc)) from None
    notes = list(info.get("notes", []))
    if info.get("complete") and info.get("leftover_parts") and remove_leftovers(path):
        notes.append(f"removed {path}.parts, left behind by the run that finished this file")
    state, status = _state(info, path, args.verify)
    attrs = info.get("attrs", {})
    print(f"{path}")
    print(f"  state       {state}")
    dims = info.get("dims", {})
    print("  grid        " + " x ".join(f"{d} {n}" for d, n in dims.items()))
    for key in (*_KEYS, "engine"):
        if key in attrs:
            text = _printable(str(attrs[key])).replace("\n", "\n              ")
            print(f"  {key + ' ':<12}{text}")
    tables = [("fates", info.get("fate_counts")), ("classes", info.get("counts"))]
    for label, counts in tables:  # a fate map: what happened to each ball first
        if counts is None:
            continue
        if label == "classes" and "fate_counts" in info:
            label = "classes     (of the launch orbits on the ideal cone)"
        total = max(1, sum(counts.values()))
        print(f"  {label}")
        for name, n in counts.items():
            print(f"    {name:<12}{n:>14,}{n / total:>10.4f}")
    for note in notes:
        print(f"  note        {note}")
    definition = attrs.get("survey_definition")
    if definition:
        print("  survey definition:")
        for line in str(definition).splitlines():
            print(f"    {_printable(line)}")
    return status


COMMAND = Command(
    name="info",
    help="show the definition, completion state, fate and class counts and provenance of a result",
    description="Describe a conesurvey result file (or the unfinished run behind it); "
    "--verify checks every value against the file's content checksum.",
    add_arguments=add_arguments,
    run=_info,
)

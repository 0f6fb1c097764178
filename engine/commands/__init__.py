"""The commands of the ``conesurvey`` command line, one module each.

A command is a :class:`Command`: its name, help texts, a function that adds its arguments to
its sub-parser and a function that runs it and returns the exit status. :mod:`engine.cli`
registers each one with :func:`engine.cli.register`; a new command (``plot``, ``report``) is
one module here and one ``register`` call there.

Shared here: :class:`InputError` (reported as ``conesurvey: error: ...``, exit status 2),
:func:`error`, :func:`load` (a survey definition, with every problem an InputError) and
:func:`load_plan` (its run plan).
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..io.atomic import NotRegularFile
from ..plan import RunPlan, plan_from_survey
from ..surveyfile import Survey, SurveyError, load_survey

__all__ = ["PROG", "Command", "InputError", "error", "load", "load_plan"]

PROG = "conesurvey"


class InputError(Exception):
    """A problem with the command's input: reported as ``conesurvey: error: ...``, status 2."""


@dataclass(frozen=True)
class Command:
    """One sub-command: ``run(args, command_line) -> exit status``."""

    name: str
    help: str
    description: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace, str], int]
    epilog: str | None = None


def error(message: str) -> None:
    """Print ``conesurvey: error: message`` on stderr."""
    one_line = re.sub(r"\s*\n\s*", " ", str(message)).strip()  # HDF5's text holds newlines
    print(f"{PROG}: error: {one_line}", file=sys.stderr)


def load(path: str) -> Survey:
    """The survey defined in the file ``path``; InputError for every problem with it."""
    source = Path(path)
    try:
        return load_survey(source)
    except FileNotFoundError:
        raise InputError(f"survey file not found: {source}") from None
    except IsADirectoryError:
        raise InputError(f"survey file is a directory: {source}") from None
    except NotRegularFile as exc:
        raise InputError(f"survey file {source} {exc.strerror}; give a TOML file") from None
    except OSError as exc:
        raise InputError(f"cannot read survey file {source}: {exc.strerror or exc}") from None
    except SurveyError as exc:
        raise InputError(str(exc)) from None


def load_plan(path: str) -> RunPlan:
    """The run plan of the survey file ``path`` (:func:`engine.plan.plan_from_survey`; its
    output in memory); InputError for every problem with the file."""
    return plan_from_survey(load(path))

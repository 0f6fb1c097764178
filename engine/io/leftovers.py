"""The block store left beside a finished output by a killed cleanup: how to tell it from a run
to resume, and its removal (by ``conesurvey info``, under the output's lock; README,
"Guarantees")."""

from __future__ import annotations

import os
from pathlib import Path

from . import OutputError
from .blocks import check_parts_dir, remove_store
from .formats import format_for
from .lock import LockError, OutputLock
from .manifest import MANIFEST, parts_dir, read_manifest


def is_debris(root: Path, finished: str | None) -> bool:
    """Whether the store ``root`` holds nothing to resume: it has no manifest (a killed cleanup
    or start), or it is the store of the finished output's own survey."""
    if not os.path.lexists(root / MANIFEST):
        return True
    if finished is None:
        return False
    try:
        return read_manifest(root).fingerprint == finished
    except OutputError:
        return False


def remove_leftovers(out: Path) -> bool:
    """Remove the block store left beside the finished output ``out`` by a killed cleanup
    (under the output's lock; nothing is done while a run holds it). Returns whether it did."""
    root, fmt = parts_dir(out), format_for(out)
    try:
        with OutputLock.acquire(out, "conesurvey info"):
            if not check_parts_dir(root) or not is_debris(root, fmt.read_fingerprint(out)):
                return False
            if not os.path.lexists(out):
                return False
            remove_store(root)
            return True
    except (LockError, OutputError, OSError):
        return False

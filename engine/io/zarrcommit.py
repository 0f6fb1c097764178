"""The final commit of a Zarr store, and the checks of every byte a reader of a store can use.

A store is committed in three steps, each atomic (README, "Guarantees"; docs/guarantees.md):

1. a *commit record* ``OUT.zarr.parts/commit.json`` is written (:func:`write_record`): the
   run's id and the root metadata the store had before (``before``). From here on the store is
   being committed: a rerun that finds the record first puts ``before`` back (:func:`undo`),
   which makes the store an unfinished run again, then verifies the blocks and commits anew;
2. the root's ``zarr.json`` is replaced, through a temporary file and a rename, by the final
   one: the provenance attributes with the content checksum, and the consolidated metadata
   (each array's ``zarr.json`` as the plan makes it, :mod:`engine.io.zarrskeleton`, which the
   store was checked to hold byte for byte, so that a reader with or without consolidated
   metadata sees the same arrays);
3. the store is renamed to its output name (:func:`engine.io.zarr.put_in_place`); the run's
   directory, record included, is removed after.

A run killed, or out of space, at any moment of this resumes with the same command.

:func:`check_tree` is what ``info`` does before it reads a store: every entry a directory or a
regular file (a symbolic link, a FIFO or a device is never opened), each chunk file no larger
than its array's chunk can be, the arrays on disk exactly those of the consolidated metadata
and each array's ``zarr.json`` equal to its entry there (:func:`metadata_problem`).
"""

from __future__ import annotations

import json
import math
import os
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from . import OutputError
from .atomic import NotRegularFile, fsync_dir, read_regular, write_atomic
from .contents import CHECKSUM_ATTR, ContentHasher
from .zarrlayout import ZarrView, json_attr, read_meta

__all__ = [
    "COMMIT",
    "check_tree",
    "commit_store",
    "consolidated",
    "consolidated_from",
    "metadata_problem",
    "read_record",
    "undo",
]

#: The commit record, in the run's directory.
COMMIT = "commit.json"
META = "zarr.json"
_MAX_RECORD_BYTES = 64 << 20
#: What a chunk file may hold beyond its values (Blosc's header is 16 bytes).
_CHUNK_OVERHEAD = 1 << 10
#: A chunk of an array whose metadata is missing may hold at most this much.
_MAX_CHUNK_BYTES = 64 << 20


def _kind(mode: int) -> str:
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _arrays_on_disk(path: Path) -> list[str]:
    return sorted(n for n in os.listdir(path) if n != META)


def consolidated(path: Path) -> dict[str, Any]:
    """The consolidated metadata of the store ``path`` (zarr-python's inline form): each
    array's ``zarr.json`` as it is on disk, read without following links."""
    metadata = {}
    for name in _arrays_on_disk(path):
        metadata[name] = read_meta(path / name / META)
    return {"kind": "inline", "must_understand": False, "metadata": metadata}


def _chunk_limit(meta: Mapping[str, Any]) -> int:
    """The largest a chunk file of the array ``meta`` can be [bytes]."""
    try:
        chunk = meta["chunk_grid"]["configuration"]["chunk_shape"]
        itemsize = np.dtype(meta["data_type"]).itemsize
        return itemsize * math.prod(int(c) for c in chunk) + _CHUNK_OVERHEAD
    except (KeyError, TypeError, ValueError):
        return _CHUNK_OVERHEAD


def check_tree(path: Path) -> None:
    """OutputError unless every entry of the store ``path`` is a directory or a regular file
    (nothing is followed or opened) and every chunk file is no larger than its array's chunk
    can be: what makes the store safe to read."""
    for dirpath, dirnames, filenames in os.walk(path, followlinks=False):
        limit = None
        rel = Path(dirpath).relative_to(path).parts
        if len(rel) >= 2 and rel[1] == "c":
            try:
                limit = _chunk_limit(read_meta(path / rel[0] / META))
            except OutputError:  # reported by metadata_problem
                limit = _MAX_CHUNK_BYTES
        for name in [*dirnames, *filenames]:
            p = Path(dirpath) / name
            st = os.lstat(p)
            if not (stat.S_ISDIR(st.st_mode) or stat.S_ISREG(st.st_mode)):
                raise OutputError(f"{p} is {_kind(st.st_mode)}; refusing to read the store")
            if limit is not None and stat.S_ISREG(st.st_mode) and st.st_size > limit:
                raise OutputError(
                    f"{p} holds {st.st_size:,} bytes, more than a chunk of its array can "
                    f"({limit:,}); refusing to read the store"
                )


def metadata_problem(path: Path) -> str | None:
    """What a reader without consolidated metadata would see differently from the
    consolidated metadata of the finished store ``path`` (None if nothing)."""
    root = read_meta(path / META)
    meta = root.get("consolidated_metadata")
    if not isinstance(meta, dict) or not isinstance(meta.get("metadata"), dict):
        return "the store has no consolidated metadata"
    listed = meta["metadata"]
    on_disk = _arrays_on_disk(path)
    if extra := sorted(set(on_disk) - set(listed)):
        return f"the store holds arrays its metadata does not list: {', '.join(extra)}"
    if missing := sorted(set(listed) - set(on_disk)):
        return f"arrays of the store are missing: {', '.join(missing)}"
    for name in on_disk:
        try:
            own = read_meta(path / name / META)
        except OutputError as exc:
            return str(exc)
        if own != listed[name]:
            return f"{name}/{META} differs from the store's consolidated metadata"
    return None


# --- the commit -------------------------------------------------------------------------------


def read_record(root: Path) -> dict[str, str] | None:
    """The commit record in the run's directory ``root`` (None if there is none);
    OutputError if it is damaged."""
    try:
        data = read_regular(root / COMMIT, _MAX_RECORD_BYTES, follow_links=False)
    except FileNotFoundError:
        return None
    except (NotRegularFile, ValueError) as exc:
        raise OutputError(f"{root / COMMIT} is unreadable ({exc})") from None
    try:
        record = json.loads(data)
    except ValueError:
        record = None
    if not (
        isinstance(record, dict)
        and isinstance(record.get("run_id"), str)
        and isinstance(record.get("before"), str)
    ):
        raise OutputError(f"{root / COMMIT} is damaged")
    return record


def write_record(root: Path, run_id: str, store: Path) -> None:
    """Step 1: the record of a commit of ``store`` begun by the run ``run_id``."""
    before = read_regular(store / META, _MAX_RECORD_BYTES, follow_links=False)
    record = {"run_id": run_id, "before": before.decode()}
    write_atomic(root / COMMIT, lambda f: f.write(json.dumps(record).encode()), mode=0o600)


def undo(root: Path, store: Path) -> None:
    """Put back the root metadata of a commit that did not finish (the store is an unfinished
    run again) and remove the record."""
    record = read_record(root)
    if record is None:
        return
    write_atomic(store / META, lambda f: f.write(record["before"].encode()))
    os.unlink(root / COMMIT)
    fsync_dir(root)


def consolidated_from(files: Mapping[str, bytes]) -> dict[str, Any]:
    """The consolidated metadata of a store's skeleton ``files`` (key -> bytes,
    :mod:`engine.io.zarrskeleton`; zarr-python's inline form): each array's ``zarr.json``."""
    names = sorted(k.split("/")[0] for k in files if k.count("/") == 1 and k.endswith("/" + META))
    metadata = {name: json.loads(files[f"{name}/{META}"]) for name in names}
    return {"kind": "inline", "must_understand": False, "metadata": metadata}


def commit_store(
    path: Path,
    attrs: Mapping[str, Any],
    hasher: ContentHasher,
    files: Mapping[str, bytes],
    *,
    record: tuple[Path, str] | None = None,
) -> tuple[str, bytes]:
    """The final commit of the store ``path`` (steps 1 and 2 above), whose files were checked
    against its skeleton ``files`` (:func:`engine.io.zarrverify.check_store`, which also
    removed the debris of dead writers and refused anything else): the root's attributes
    replaced by ``attrs`` plus the content checksum (``hasher``, whose values were all added;
    the arrays' headers from ``files``, not from the disk), the consolidated metadata (from
    ``files``), all durable. ``record``: (the run's directory, the run's id) where a commit
    record is kept. Returns the checksum and the root's new bytes."""
    final = {k: json_attr(v) for k, v in attrs.items() if k != CHECKSUM_ATTR}
    final[CHECKSUM_ATTR] = hasher.finish(ZarrView(path, final, files=files))
    root = {
        "attributes": final,
        "zarr_format": 3,
        "consolidated_metadata": consolidated_from(files),
        "node_type": "group",
    }
    data = json.dumps(root, indent=2).encode()
    if record is not None:
        write_record(record[0], record[1], path)
    write_atomic(path / META, lambda f: f.write(data))
    return final[CHECKSUM_ATTR], data

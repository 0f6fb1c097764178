"""What a Zarr run checks before its commit: every file of its store is what the run wrote.

Just before the final commit (:func:`check_store`, docs/guarantees.md):

- nothing is in the store that the run did not write (an extra array, a link, a directory or
  a FIFO at a chunk's name: :func:`engine.io.zarrskeleton.extra_entries`);
- every skeleton file (metadata, axes, the variables on fewer dims) is held
  (:mod:`engine.io.hold`) and then compared, byte for byte, with the skeleton made from the
  plan;
- every block is journaled and its chunk files are what its receipt says: a chunk file held
  since it was written or verified, whose lease is intact and whose name still leads to it,
  is not read again; any other (its lease broken, a file system without leases, a dask
  worker's file) is held anew and hashed, and refused while another process has it open for
  writing.

Then :func:`check_held` is the last look before the store is renamed into place: every held
file still held, under its name. A writer that opens a held file from then on waits until the
run lets go, after the rename.
"""

from __future__ import annotations

import hashlib
import os
import stat
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from . import OutputError
from .hold import BUSY, HELD, HeldFiles
from .zarrlayout import READ_ONLY, files_digest, read_all
from .zarrskeleton import META, extra_entries

__all__ = ["block_digest", "check_held", "check_store", "hold_file"]


def block_digest(
    store: Path, keys: list[str], held: HeldFiles, limit: int, hold: bool
) -> tuple[int, str] | str | None:
    """(bytes, files digest) of the chunk files ``keys`` of ``store`` as they are now; None if
    one is missing, not a regular file or larger than ``limit``. With ``hold``, each is held
    (in ``held``) before it is read; BUSY if another process has one open for writing."""
    entries = []
    for key in keys:
        try:  # never through a link, never blocking on a FIFO
            fd = os.open(store / key, READ_ONLY)
        except OSError:
            return None
        got = None
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode) or st.st_size > limit:
                return None
            got = held.hold(key, fd) if hold else None
            if got == BUSY:
                return BUSY
            data = read_all(fd, limit + 1)
        finally:
            if got != HELD:
                os.close(fd)
        if len(data) > limit:
            return None
        entries.append((key, len(data), hashlib.sha256(data).hexdigest()))
    return sum(n for _, n, _ in entries), files_digest(entries)


def hold_file(held: HeldFiles, store: Path, key: str, data: bytes) -> None:
    """Hold the file ``key`` of ``store``, then compare it with ``data``: OutputError if it
    differs, is missing or another process has it open for writing."""
    held.drop(key)
    try:
        fd = os.open(store / key, READ_ONLY)
    except OSError as exc:
        raise OutputError(f"{key} of {store} cannot be read ({exc.strerror}); "
                          "the next run writes it again") from None  # fmt: skip
    got = held.hold(key, fd)
    try:
        if got == BUSY:
            raise OutputError(f"{key} of {store} is open for writing by another process")
        if not stat.S_ISREG(os.fstat(fd).st_mode) or read_all(fd, len(data) + 1) != data:
            raise OutputError(
                f"{key} of {store} is not what the run wrote (changed since); "
                "the next run writes it again"
            )
    finally:
        if got != HELD:
            os.close(fd)


def check_store(
    store: Path,
    files: Mapping[str, bytes],
    held: HeldFiles,
    keys: Callable[[int], list[str]],
    receipts: Mapping[int, dict],
    limit: int,
) -> None:
    """OutputError unless ``store`` holds exactly what the run wrote (see the module's
    docstring): the skeleton ``files``, and for every block ``i`` of ``receipts`` (all of
    them) the chunk files ``keys(i)``, each no larger than ``limit``, whose sizes and
    SHA-256 its receipt records. Every file is then held, or was hashed here."""
    blocks = sorted(receipts)
    chunks = [k for i in blocks for k in keys(i)]
    debris: list[str] = []  # writers that died midway left these: removed
    extra = extra_entries(store, files, chunks, debris)
    for key in debris:
        os.unlink(store / key)
    if extra:
        more = f" (and {len(extra) - 1} more)" if len(extra) > 1 else ""
        raise OutputError(f"{store} holds {extra[0]}{more}, which the run did not write; "
                          "the next run removes it")  # fmt: skip
    where = f"{store}/"
    for key, data in files.items():
        if key != META and not held.intact(key, where + key):  # the root: replaced next
            hold_file(held, store, key, data)
    todo = [i for i in blocks if not all(held.intact(k, where + k) for k in keys(i))]
    for i in todo:
        for key in keys(i):
            held.drop(key)

    def digest(i: int) -> tuple[int, str] | str | None:
        return block_digest(store, keys(i), held, limit, True)

    with ThreadPoolExecutor(os.cpu_count() or 1) as pool:  # hashing releases the GIL
        got = dict(zip(todo, pool.map(digest, todo), strict=True))
    for index, found in got.items():
        if found == BUSY:
            raise OutputError(
                f"a chunk file of block {index} is open for writing by another process; "
                "it will be computed again"
            )
        if found != (receipts[index]["bytes"], receipts[index]["files"]):
            raise OutputError(
                f"the chunk files of block {index} changed since they were written; "
                "it will be computed again"
            )


def check_held(held: HeldFiles, store: Path) -> None:
    """OutputError unless every file ``held`` holds is still held, unbroken, under its name
    in ``store``."""
    where = f"{store}/"
    for key in held.keys():
        if not held.intact(key, where + key):
            raise OutputError(
                f"{key} of {store} was opened for writing or replaced during the commit; "
                "the next run checks it again"
            )

"""The unfinished Zarr run: chunks written where a block is computed, a journal of receipts.

Layout while a run of ``OUT.zarr`` is under way (README, "Scale out: Zarr output")::

    OUT.zarr.lock               the output's lock (engine.io.lock)
    OUT.zarr.parts/             created by the run, mode 0700 (engine.io.blocks.check_parts_dir)
    OUT.zarr.parts/store.zarr/  the Zarr v3 store being written; its root attributes say it is
                                unfinished (``conesurvey_unfinished``) and name the run
    OUT.zarr.parts/manifest.json  as for netCDF (engine.io.manifest), written after the store
    OUT.zarr.parts/journal      one line per committed block: its receipt and a line check

Whoever computes a block (a dask worker, or the run itself) writes its chunks with
:class:`ChunkWriter`: each chunk file under a fresh ``O_EXCL | O_NOFOLLOW`` temporary name,
fsynced and renamed, every directory opened without following links, relative to one open
descriptor of the store (a store that was removed and made again by another run is never
written through: the writer checks the run's id first). A block's chunks are whole chunks, so
no two writers ever write one chunk. The writer returns a receipt: the bytes and SHA-256 of
the block's chunk files and the SHA-256 of each variable's values (the content checksum's
block digests, :mod:`engine.io.contents`). The run appends the receipt to the journal (fsynced)
and nothing else crosses from the writer to the run. A block counts only if its chunk files
hash to its last journal line (:meth:`RunStore.scan`, on resume); a block whose writer died
midway is computed again and its chunks replaced.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import secrets
import stat
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..grid import Tiling
from . import OutputError
from .atomic import (
    NEW_FILE,
    O_CLOEXEC,
    O_NOFOLLOW,
    O_NONBLOCK,
    fsync_dir,
)
from .blocks import Scan, make_parts_dir, remove_store
from .journal import JOURNAL, journal_lines
from .manifest import Manifest, read_manifest, write_manifest
from .zarrchunks import SEPARATOR, chunk_keys
from .zarrcommit import read_record, undo
from .zarrlayout import RUN_ATTR, STORE, ChunkWriter, Stamp, files_digest, read_meta, stamp

__all__ = ["JOURNAL", "RunStore", "parts_state", "read_journal"]


# --- the journal ------------------------------------------------------------------------------


def _line(receipt: dict) -> bytes:
    body = json.dumps(receipt, sort_keys=True, separators=(",", ":"))
    return f"{body} {hashlib.sha256(body.encode()).hexdigest()[:16]}\n".encode()


def _valid(receipt: Any, names: list[str], nblocks: int) -> bool:
    if not isinstance(receipt, dict) or set(receipt) != {
        "i",
        "bytes",
        "files",
        "values",
        "summary",
    }:
        return False
    i, n, files, values, summary = (
        receipt[k] for k in ("i", "bytes", "files", "values", "summary")
    )
    return (
        _valid_summary(summary)
        and isinstance(i, int)
        and 0 <= i < nblocks
        and isinstance(n, int)
        and n >= 0
        and isinstance(files, str)
        and len(files) == 64
        and isinstance(values, dict)
        and sorted(values) == sorted(names)
        and all(isinstance(v, str) and len(v) == 64 for v in values.values())
    )


def _valid_summary(summary: Any) -> bool:
    """The statistics of a receipt: flag counts (lists of counts) and value ranges (lo, hi)."""
    if not isinstance(summary, dict) or set(summary) != {"flags", "ranges"}:
        return False
    flags, ranges = summary["flags"], summary["ranges"]
    return (
        isinstance(flags, dict)
        and isinstance(ranges, dict)
        and all(
            isinstance(c, list) and all(isinstance(x, int) and x >= 0 for x in c)
            for c in flags.values()
        )
        and all(
            isinstance(r, list) and len(r) == 2 and all(isinstance(x, int | float) for x in r)
            for r in ranges.values()
        )
    )


def read_journal(root: Path, names: list[str], nblocks: int) -> dict[int, dict]:
    """index -> receipt of the last valid journal line of each block (torn, damaged or foreign
    lines are skipped); {} if there is no journal."""
    out: dict[int, dict] = {}
    for raw in journal_lines(root):
        body, _, check = raw.rpartition(b" ")
        try:
            receipt = json.loads(body)
        except ValueError:
            continue
        if _valid(receipt, names, nblocks) and _line(receipt) == raw + b"\n":
            out[receipt["i"]] = receipt
    return out


# --- the run's store --------------------------------------------------------------------------


@dataclass
class RunStore:
    """The unfinished Zarr store of one run and its journal (the runner's view; the same
    methods as :class:`engine.io.blocks.BlockStore`)."""

    root: Path
    tiling: Tiling
    names: dict[str, np.dtype]
    run_id: str
    complevel: int
    warn: Callable[[str], None] = field(default=lambda msg: None)
    journal: dict[int, dict] = field(default_factory=dict)
    separator: str = SEPARATOR  # of the chunk keys (a store made before 2026-11-27: "/")
    #: The stamps of the chunk files this process wrote or verified, by block (the commit
    #: checks those blocks by their stamps instead of reading them again).
    stamps: dict[int, dict[str, Stamp]] = field(default_factory=dict)

    @property
    def store(self) -> Path:
        return self.root / STORE

    @property
    def writer(self) -> ChunkWriter:
        arrays = tuple((n, dt.str) for n, dt in self.names.items())
        return ChunkWriter(
            os.path.abspath(self.store),  # not resolved: a link there is refused
            self.run_id,
            self.tiling.shape,
            self.tiling.chunk,
            arrays,
            self.complevel,
            self.separator,
            self.stamps,
        )

    @classmethod
    def create(
        cls,
        root: Path,
        manifest: Manifest,
        make_store: Callable[[Path, str], None],
        complevel: int,
        warn: Callable[[str], None] = lambda msg: None,
    ) -> RunStore:
        """A new run: the directory (mode 0700; FileExistsError if it exists), the store made by
        ``make_store(path, run_id)``, then the manifest (a store without one is debris) and an
        empty journal. Removed again if any of that fails."""
        make_parts_dir(root)
        run_id = secrets.token_hex(16)
        try:
            make_store(root / STORE, run_id)
            write_manifest(root, manifest)
            os.close(os.open(root / JOURNAL, NEW_FILE, 0o600))
            fsync_dir(root)
            fsync_dir(root.parent)
        except BaseException:
            with contextlib.suppress(OSError):
                remove_store(root)
            raise
        m = manifest
        return cls(root, m.tiling, m.names, run_id, complevel, warn, separator=SEPARATOR)

    @classmethod
    def open(cls, root: Path, warn: Callable[[str], None] = lambda msg: None) -> RunStore:
        """The existing run ``root``: manifest, journal, the store's run id and compression."""
        m = read_manifest(root)
        store = root / STORE
        if os.path.islink(store) or not os.path.isdir(store):
            raise OutputError(f"{store} is not a directory (a symbolic link is not followed)")
        meta = read_meta(store / "zarr.json")
        run_id = meta.get("attributes", {}).get(RUN_ATTR)
        record = read_record(root)  # a commit that did not finish: undone by discard()
        if not isinstance(run_id, str) and record is not None:
            run_id = record["run_id"]
        if not isinstance(run_id, str):
            raise OutputError(f"{store} is not the store of an unfinished run")
        for name in os.listdir(store):  # every array's metadata, never through a link
            if name != "zarr.json":
                read_meta(store / name / "zarr.json")
        metas = {name: read_meta(store / name / "zarr.json") for name in m.names}
        first = metas[next(iter(m.names))]
        level = 0 if len(first.get("codecs", [])) < 2 else 1
        separators = {name: _separator(meta) for name, meta in metas.items()}
        if None in separators.values():
            name = next(n for n, sep in separators.items() if sep is None)
            raise OutputError(f"{store}: the chunk key encoding of {name} is not conesurvey's")
        if len(set(separators.values())) > 1:  # one separator per run: keys() assumes it
            raise OutputError(
                f"{store}: its arrays do not share one chunk key separator "
                f"({', '.join(f'{n} {s!r}' for n, s in separators.items())})"
            )
        separator = separators[next(iter(m.names))]
        journal = read_journal(root, list(m.names), m.tiling.nblocks)
        return cls(root, m.tiling, m.names, run_id, level, warn, journal, separator=separator)

    def path(self, index: int) -> Path:
        """Where block ``index`` is written (for messages)."""
        return self.store

    def keys(self, index: int) -> list[str]:
        slab = self.tiling.slices(index)
        chunk = self.tiling.chunk
        return [k for n in self.names for k in chunk_keys(n, slab, chunk, self.separator)]

    def commit(self, index: int, receipt: dict) -> None:
        """Journal the receipt of block ``index`` (its chunks are written and fsynced)."""
        if not _valid(receipt, list(self.names), self.tiling.nblocks) or receipt["i"] != index:
            raise OutputError(f"block {index}: the writer's receipt is not valid")
        fd = os.open(self.root / JOURNAL, os.O_WRONLY | os.O_APPEND | O_NOFOLLOW | O_CLOEXEC)
        try:
            os.write(fd, _line(receipt))
            os.fsync(fd)
        finally:
            os.close(fd)
        self.journal[index] = receipt

    @property
    def receipt_limit(self) -> int:
        """The largest a chunk file can be [bytes] (values, Blosc's header, a margin)."""
        itemsize = max(np.dtype(dt).itemsize for dt in self.names.values())
        return itemsize * math.prod(self.tiling.chunk) + 1024

    def _digest(self, index: int, stamps: dict[str, Stamp] | None = None) -> tuple[int, str] | None:
        """(bytes, files digest) of block ``index``'s chunk files as they are now, None if one is
        missing, not a regular file or too large; with ``stamps``, each file's stamp (taken
        before it is read: a change while it is read shows) goes there."""
        entries = []
        for key in self.keys(index):
            try:  # never through a link, never blocking on a FIFO
                fd = os.open(self.store / key, os.O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC)
            except OSError:
                return None
            with os.fdopen(fd, "rb") as f:
                st = os.fstat(fd)
                if not stat.S_ISREG(st.st_mode) or st.st_size > self.receipt_limit:
                    return None
                data = f.read()
            if stamps is not None:
                stamps[key] = stamp(st)
            entries.append((key, len(data), hashlib.sha256(data).hexdigest()))
        return sum(n for _, n, _ in entries), files_digest(entries)

    def _unchanged(self, index: int) -> bool:
        """Whether every chunk file of block ``index`` still has the stamp it had when this
        process wrote or verified it (False where it has none)."""
        stamps = self.stamps.get(index)
        if stamps is None or set(stamps) != set(self.keys(index)):
            return False
        try:
            return all(
                stamp(os.stat(self.store / key, follow_symlinks=False)) == s
                for key, s in stamps.items()
            )
        except OSError:
            return False

    def scan(self) -> Scan:
        """Hash the chunk files of every journaled block against its receipt (changes
        nothing); blocks not journaled are simply written again."""
        found = Scan()
        for index, receipt in sorted(self.journal.items()):
            stamps: dict[str, Stamp] = {}
            got = self._digest(index, stamps)
            if got == (receipt["bytes"], receipt["files"]):
                found.good.add(index)
                self.stamps[index] = stamps
            else:
                why = "missing" if got is None else "its checksum does not match the journal"
                found.bad[f"block {index}"] = f"chunk files {why}"
        return found

    def discard(self, found: Scan) -> None:
        """Undo a commit that did not finish (:mod:`engine.io.zarrcommit`); report the bad
        blocks (their chunks are replaced when they are computed again)."""
        undo(self.root, self.store)
        for name, why in found.bad.items():
            self.warn(f"{name} of {self.store} is corrupt ({why}); recomputing")

    def check_files(self) -> None:
        """OutputError unless every block is journaled and its chunk files are what its
        receipt says, just before the commit: a chunk changed since the resume scan or since
        it was written is caught. The files this process wrote or verified are checked by
        their stamps (a write changes a file's change time); the others, and any whose stamp
        changed, are read and hashed again."""
        missing = [i for i in range(self.tiling.nblocks) if i not in self.journal]
        if missing:
            raise OutputError(f"block {missing[0]} is not recorded in the journal")
        todo = [i for i in range(self.tiling.nblocks) if not self._unchanged(i)]
        with ThreadPoolExecutor(os.cpu_count() or 1) as pool:  # hashing releases the GIL
            got = dict(zip(todo, pool.map(self._digest, todo), strict=True))
        for index, digest in got.items():
            receipt = self.journal[index]
            if digest != (receipt["bytes"], receipt["files"]):
                raise OutputError(
                    f"the chunk files of block {index} changed since they were written; "
                    "it will be computed again"
                )

    def temporaries(self) -> Iterator[Path]:
        """Temporary files left in the store by writers that died midway."""
        for dirpath, _, filenames in os.walk(self.store):
            for name in filenames:
                if name.startswith(".") and name.endswith(".tmp"):
                    yield Path(dirpath) / name

    def remove(self) -> list[str]:
        """Delete the run's directory: the manifest first (what is left is debris); returns
        the names of a user's files left in it."""
        return remove_store(self.root)


def _separator(meta: dict) -> str | None:
    """The separator of an array's chunk keys ("default" encoding, "/" or "."), None if its
    metadata names another encoding."""
    enc = meta.get("chunk_key_encoding", {})
    if not isinstance(enc, dict) or enc.get("name") != "default":
        return None
    conf = enc.get("configuration") or {}
    sep = conf.get("separator", "/") if isinstance(conf, dict) else None
    return sep if sep in ("/", ".") else None


def parts_state(root: Path) -> dict[str, Any]:
    """What an unfinished Zarr run says (``read_info``): OutputError if it cannot be read.
    Blocks are counted from the journal, not verified."""
    m = read_manifest(root)
    journal = read_journal(root, list(m.names), m.tiling.nblocks)
    return {
        "complete": False,
        "attrs": {"survey_definition": m.survey_definition, "engine": m.engine},
        "blocks_done": len(journal),
        "blocks_total": m.tiling.nblocks,
        "shape": m.tiling.shape,
    }

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
import dataclasses
import hashlib
import json
import math
import os
import secrets
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..grid import Tiling
from . import OutputError
from . import zarrverify as verify
from .atomic import (
    NEW_FILE,
    O_CLOEXEC,
    O_NOFOLLOW,
    fsync_dir,
)
from .blocks import Scan, make_parts_dir, remove_store
from .hold import BUSY, HeldFiles
from .journal import JOURNAL, journal_lines
from .manifest import Manifest, read_manifest, survey_families, write_manifest
from .zarrchunks import SEPARATOR, chunk_keys
from .zarrcommit import read_record, undo
from .zarrlayout import STORE, ChunkWriter, read_meta
from .zarrskeleton import layout, make_store, repair, skeleton

if TYPE_CHECKING:
    from .planshape import RunPlan

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
    #: The skeleton files the store must hold (:mod:`engine.io.zarrskeleton`): known once the
    #: store is made, or once a resume is given its plan (:meth:`expect`).
    files: dict[str, bytes] | None = None
    #: The files this process holds until the commit (:mod:`engine.io.hold`): the chunk files
    #: it wrote or verified, then the skeleton.
    held: HeldFiles = field(init=False, repr=False)

    def __post_init__(self) -> None:
        chunks = math.prod(-(-n // c) for n, c in zip(self.tiling.shape, self.tiling.chunk,
                                                       strict=True))  # fmt: skip
        self.held = HeldFiles(chunks * len(self.names) + 64)

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
            self.held,
        )

    @classmethod
    def create(
        cls,
        root: Path,
        manifest: Manifest,
        files: Callable[[str, int, str], dict[str, bytes]],
        complevel: int,
        warn: Callable[[str], None] = lambda msg: None,
    ) -> RunStore:
        """A new run: the directory (mode 0700; FileExistsError if it exists), the store made
        from its skeleton ``files(run_id, complevel, separator)``, then the manifest (a store
        without one is debris) and an empty journal. Removed again if any of that fails."""
        make_parts_dir(root)
        run_id = secrets.token_hex(16)
        level = int(complevel != 0)
        try:
            skeleton = files(run_id, level, SEPARATOR)
            make_store(root / STORE, skeleton)
            write_manifest(root, dataclasses.replace(manifest, zarr=(level, SEPARATOR)))
            os.close(os.open(root / JOURNAL, NEW_FILE, 0o600))
            fsync_dir(root)
            fsync_dir(root.parent)
        except BaseException:
            with contextlib.suppress(OSError):
                remove_store(root)
            raise
        m = manifest
        return cls(root, m.tiling, m.names, run_id, level, warn, separator=SEPARATOR,
                   files=skeleton)  # fmt: skip

    @classmethod
    def open(cls, root: Path, warn: Callable[[str], None] = lambda msg: None) -> RunStore:
        """The existing run ``root``: manifest, journal, the store's compression and chunk key
        separator (the manifest's; of a store made before it said them, its arrays'). Its
        metadata is not trusted: a resume writes it again from the plan (:meth:`expect`)."""
        m = read_manifest(root)
        store = root / STORE
        if os.path.islink(store) or not os.path.isdir(store):
            raise OutputError(f"{store} is not a directory (a symbolic link is not followed)")
        read_record(root)  # a commit that did not finish (undone by discard()): readable
        level, separator = m.zarr if m.zarr is not None else _inferred(store, m)
        journal = read_journal(root, list(m.names), m.tiling.nblocks)
        run_id = secrets.token_hex(16)  # the store's own is replaced when it is resumed
        return cls(root, m.tiling, m.names, run_id, level, warn, journal, separator=separator)

    def expect(self, plan: RunPlan) -> None:
        """Know what the store must hold: the skeleton of ``plan`` (whose survey the manifest
        matches), with this run's id; :meth:`discard` makes the store hold it."""
        lay = layout(plan, self.names, survey_families(plan))
        self.files = skeleton(self.run_id, **lay, tiling=self.tiling, complevel=self.complevel,
                              separator=self.separator)  # fmt: skip

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

    def digest(self, index: int, hold: bool = False) -> tuple[int, str] | str | None:
        """(bytes, files digest) of block ``index``'s chunk files as they are now; None if one
        is missing, not a regular file or too large. With ``hold``, each is held
        (:mod:`engine.io.hold`) before it is read, and let go again unless its block matches
        its journal line; BUSY if another process has one open for writing."""
        return verify.block_digest(self.store, self.keys(index), self.held, self.receipt_limit,
                                   hold)  # fmt: skip

    def scan(self) -> Scan:
        """Hash the chunk files of every journaled block against its receipt, holding those of
        the blocks that match (changes nothing); blocks not journaled are simply written
        again."""
        found = Scan()
        for index, receipt in sorted(self.journal.items()):
            got = self.digest(index, hold=True)
            if got == (receipt["bytes"], receipt["files"]):
                found.good.add(index)
                continue
            for key in self.keys(index):
                self.held.drop(key)
            why = {None: "missing", BUSY: "open for writing by another process"}.get(
                got,
                "its checksum does not match the journal",  # type: ignore[arg-type]
            )
            found.bad[f"block {index}"] = f"chunk files {why}"
        return found

    def discard(self, found: Scan) -> None:
        """Undo a commit that did not finish (:mod:`engine.io.zarrcommit`); make the store hold
        its skeleton again, with this run's id (:func:`engine.io.zarrskeleton.repair`); report
        the bad blocks (their chunks are replaced when they are computed again)."""
        undo(self.root, self.store)
        if self.files is None:
            raise OutputError(f"{self.store}: resumed without its plan (RunStore.expect)")
        chunks = (k for i in range(self.tiling.nblocks) for k in self.keys(i))
        repair(self.store, self.files, chunks, self.warn)
        for name, why in found.bad.items():
            self.warn(f"{name} of {self.store} is corrupt ({why}); recomputing")

    def check_files(self) -> None:
        """OutputError unless every block is journaled and its chunk files are what its
        receipt says, the skeleton is what the run wrote and nothing else is in the store,
        just before the commit (:func:`engine.io.zarrverify.check_store`): every file is then
        held, or was hashed here."""
        missing = [i for i in range(self.tiling.nblocks) if i not in self.journal]
        if missing:
            raise OutputError(f"block {missing[0]} is not recorded in the journal")
        if self.files is None:
            raise OutputError(f"{self.store}: its skeleton is not known (RunStore.expect)")
        verify.check_store(self.store, self.files, self.held, self.keys, self.journal,
                           self.receipt_limit)  # fmt: skip

    def check_held(self) -> None:
        """OutputError unless every held file is still held, unbroken, under its name (the
        last check before the store is renamed into place)."""
        verify.check_held(self.held, self.store)

    def release(self) -> None:
        """Let go of every held file (once the store is in place, or the run ends)."""
        self.held.release()

    def temporaries(self) -> Iterator[Path]:
        """Temporary files left in the store by writers that died midway."""
        for dirpath, _, filenames in os.walk(self.store):
            for name in filenames:
                if name.startswith(".") and name.endswith(".tmp"):
                    yield Path(dirpath) / name

    def remove(self) -> list[str]:
        """Delete the run's directory: the manifest first (what is left is debris); returns
        the names of a user's files left in it."""
        self.release()
        return remove_store(self.root)


def _inferred(store: Path, m: Manifest) -> tuple[int, str]:
    """The compression level and chunk key separator of a store whose manifest does not say
    them (made before it did): from its arrays' metadata."""
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
    return level, separators[next(iter(m.names))]


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
    """What an unfinished Zarr run says (``read_info``): OutputError if it cannot be read, or
    cannot be resumed (what :meth:`RunStore.open` refuses: the rerun's refusal). Blocks are
    counted from the journal, not verified."""
    m = read_manifest(root)
    RunStore.open(root)  # what the rerun opens; its metadata it makes whole again
    journal = read_journal(root, list(m.names), m.tiling.nblocks)
    return {
        "complete": False,
        "attrs": {"survey_definition": m.survey_definition, "engine": m.engine},
        "blocks_done": len(journal),
        "blocks_total": m.tiling.nblocks,
        "shape": m.tiling.shape,
    }

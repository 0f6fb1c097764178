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
import os
import secrets
import shutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..grid import Tiling
from . import OutputError
from .atomic import NEW_FILE, O_CLOEXEC, O_NOFOLLOW, NotRegularFile, fsync_dir, read_regular
from .blocks import Scan, Summary, remove_store
from .contents import block_digest
from .manifest import Manifest, read_manifest, write_manifest

__all__ = [
    "JOURNAL",
    "RUN_ATTR",
    "STORE",
    "UNFINISHED_ATTR",
    "ChunkWriter",
    "RunStore",
    "chunk_keys",
    "codecs",
    "zarr_module",
]

STORE = "store.zarr"
JOURNAL = "journal"
#: Root attribute of a store being written: what it is, and when it is complete.
UNFINISHED_ATTR = "conesurvey_unfinished"
#: Root attribute of a store being written: the run's random id (checked by every writer).
RUN_ATTR = "conesurvey_run"
UNFINISHED_TEXT = (
    "a conesurvey run is writing this store; it is complete when it is renamed to its output "
    "name and its root carries survey_fingerprint and content_checksum"
)
_DIR_FLAGS = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | O_NOFOLLOW | O_CLOEXEC
_MAX_JOURNAL_BYTES = 1 << 30
_MAX_META_BYTES = 64 << 20
_RECEIPT = ("i", "bytes", "files", "values", "summary")
#: Blosc (lz4, level 5, byte shuffle): 1.57x on survey blocks at ~600 MB/s on one core, where
#: netCDF's zlib 1 + shuffle gives 1.63x at ~33 MB/s (README, "Scale out: Zarr output").
BLOSC = {"cname": "lz4", "clevel": 5, "shuffle": "shuffle"}


def zarr_module() -> Any:
    """The ``zarr`` package (an optional dependency); OutputError saying how to install it."""
    try:
        import zarr
    except ImportError:
        raise OutputError(
            "Zarr output needs the zarr package: pip install 'conesurvey[zarr]'"
        ) from None
    return zarr


def codecs(complevel: int) -> list[Any]:
    """The compressors of a data variable: Blosc (:data:`BLOSC`), none for ``complevel`` 0."""
    if complevel == 0:
        return []
    from zarr.codecs import BloscCodec

    return [BloscCodec(**BLOSC)]


def fill_value(dtype: np.dtype) -> Any:
    """Zarr's fill value of a variable (never read: every chunk is written): NaN for floats,
    netCDF's default fill for integers (not a flag value). It is not a CF ``_FillValue``."""
    if dtype.kind == "f":
        return np.nan
    return {1: -127, 2: -32767, 4: -2147483647, 8: -9223372036854775806}[dtype.itemsize]


def chunk_keys(name: str, slab: tuple[slice, ...], chunk: tuple[int, ...]) -> list[str]:
    """The keys of the chunk files of variable ``name`` that the hyperslab ``slab`` covers
    (chunk key encoding "default", separator "/")."""
    ranges = [range(s.start // c, -(-s.stop // c)) for s, c in zip(slab, chunk, strict=True)]
    out = []
    for pos in np.ndindex(*(len(r) for r in ranges)):
        idx = (str(r[p]) for r, p in zip(ranges, pos, strict=True))
        out.append(f"{name}/c/" + "/".join(idx))
    return out


def _files_digest(entries: list[tuple[str, int, str]]) -> str:
    text = "".join(f"{k} {n} {h}\n" for k, n, h in sorted(entries))
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class ChunkWriter:
    """Writes the chunks of one block into the store ``root`` (picklable: a dask task carries
    it to a worker). ``arrays``: (name, dtype, fill) of each data variable, in file order."""

    root: str
    run_id: str
    shape: tuple[int, ...]
    chunk: tuple[int, ...]
    arrays: tuple[tuple[str, str], ...]
    complevel: int

    def encode(self, slab: tuple[slice, ...], values: dict[str, np.ndarray]) -> dict[str, bytes]:
        """The chunk files (key -> bytes) of the hyperslab ``slab`` of every variable, encoded
        by zarr exactly as the store's arrays declare."""
        zarr = zarr_module()
        mem: dict[str, Any] = {}
        store = zarr.storage.MemoryStore(mem)
        for name, dtype in self.arrays:
            dt = np.dtype(dtype)
            arr = zarr.create_array(
                store,
                name=name,
                shape=self.shape,
                chunks=self.chunk,
                dtype=dt,
                fill_value=fill_value(dt),
                compressors=codecs(self.complevel),
                config={"write_empty_chunks": True},
            )
            arr[slab] = values[name]
        return {k: v.to_bytes() for k, v in mem.items() if "/c/" in k}

    def write(self, index: int, slab: tuple[slice, ...], values: dict[str, np.ndarray]) -> dict:
        """Write block ``index`` (its hyperslab ``slab``); returns its receipt. OSError if the
        store cannot be written or is no longer this run's."""
        clean = {n: np.ascontiguousarray(values[n], dtype=dt) for n, dt in self.arrays}
        digests = {n: block_digest(a).hex() for n, a in clean.items()}
        files = self.encode(slab, clean)
        fd = self._open_store()
        try:
            entries = _put_files(fd, files)
        finally:
            os.close(fd)
        stats = Summary()
        stats.add(clean)
        return {
            "i": index,
            "bytes": sum(n for _, n, _ in entries),
            "files": _files_digest(entries),
            "values": digests,
            "summary": {
                "flags": {n: c.tolist() for n, c in stats.flags.items()},
                "ranges": {n: [lo, hi] for n, (lo, hi, _) in stats.ranges.items()},
            },
        }

    def _open_store(self) -> int:
        try:
            fd = os.open(self.root, _DIR_FLAGS)
        except OSError as exc:
            why = f"cannot open the Zarr store ({exc.strerror})"
            raise OSError(exc.errno, why, self.root) from None
        try:
            meta = json.loads(_read_at(fd, "zarr.json"))
            found = meta.get("attributes", {}).get(RUN_ATTR)
        except (OSError, ValueError, AttributeError):
            found = None
        if found != self.run_id:
            os.close(fd)
            raise OSError(
                2, "the Zarr store is no longer this run's (removed or replaced)", self.root
            )
        return fd


def _read_at(dir_fd: int, name: str) -> bytes:
    fd = os.open(name, os.O_RDONLY | O_NOFOLLOW | O_CLOEXEC, dir_fd=dir_fd)
    with os.fdopen(fd, "rb") as f:
        return f.read(_MAX_META_BYTES)


def _open_dirs(root_fd: int, parts: list[str], cache: dict[str, int]) -> int:
    """A descriptor of the directory ``root/parts...`` (made where missing), every component
    opened with O_NOFOLLOW relative to its parent."""
    fd, path = root_fd, ""
    for part in parts:
        path = f"{path}/{part}"
        if path not in cache:
            with contextlib.suppress(FileExistsError):
                os.mkdir(part, 0o777, dir_fd=fd)
            cache[path] = os.open(part, _DIR_FLAGS, dir_fd=fd)
        fd = cache[path]
    return fd


def _put_files(root_fd: int, files: dict[str, bytes]) -> list[tuple[str, int, str]]:
    """Write every file atomically (temporary name, fsync, rename), then fsync the directories
    that changed; returns (key, size, SHA-256) of each."""
    cache: dict[str, int] = {}
    entries = []
    try:
        for key, data in sorted(files.items()):
            *dirs, leaf = key.split("/")
            dfd = _open_dirs(root_fd, dirs, cache)
            tmp = f".{leaf}.{secrets.token_hex(6)}.tmp"
            fd = os.open(tmp, NEW_FILE, 0o666, dir_fd=dfd)
            try:
                with os.fdopen(fd, "wb") as f:
                    f.write(data)
                    f.flush()
                    os.fsync(f.fileno())
                os.rename(tmp, leaf, src_dir_fd=dfd, dst_dir_fd=dfd)
            except BaseException:
                with contextlib.suppress(OSError):
                    os.unlink(tmp, dir_fd=dfd)
                raise
            entries.append((key, len(data), hashlib.sha256(data).hexdigest()))
        for dfd in [root_fd, *cache.values()]:
            os.fsync(dfd)
    finally:
        for dfd in cache.values():
            os.close(dfd)
    return entries


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
    try:
        data = read_regular(root / JOURNAL, _MAX_JOURNAL_BYTES, follow_links=False)
    except FileNotFoundError:
        return {}
    except (NotRegularFile, ValueError) as exc:
        raise OutputError(f"{root / JOURNAL} is unreadable ({exc})") from None
    out: dict[int, dict] = {}
    for raw in data.split(b"\n")[:-1]:  # the part after the last newline is torn
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

    @property
    def store(self) -> Path:
        return self.root / STORE

    @property
    def writer(self) -> ChunkWriter:
        arrays = tuple((n, dt.str) for n, dt in self.names.items())
        return ChunkWriter(
            str(self.store.resolve()),
            self.run_id,
            self.tiling.shape,
            self.tiling.chunk,
            arrays,
            self.complevel,
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
        os.mkdir(root, 0o700)
        run_id = secrets.token_hex(16)
        try:
            make_store(root / STORE, run_id)
            write_manifest(root, manifest)
            os.close(os.open(root / JOURNAL, NEW_FILE, 0o600))
            fsync_dir(root)
            fsync_dir(root.parent)
        except BaseException:
            shutil.rmtree(root, ignore_errors=True)
            raise
        return cls(root, manifest.tiling, manifest.names, run_id, complevel, warn)

    @classmethod
    def open(cls, root: Path, warn: Callable[[str], None] = lambda msg: None) -> RunStore:
        """The existing run ``root``: manifest, journal, the store's run id and compression."""
        m = read_manifest(root)
        meta = _root_meta(root / STORE)
        run_id = meta.get("attributes", {}).get(RUN_ATTR)
        if not isinstance(run_id, str):
            raise OutputError(f"{root / STORE} is not the store of an unfinished run")
        first = next(iter(m.names))
        level = 0 if len(_array_meta(root / STORE, first).get("codecs", [])) < 2 else 1
        journal = read_journal(root, list(m.names), m.tiling.nblocks)
        return cls(root, m.tiling, m.names, run_id, level, warn, journal)

    def path(self, index: int) -> Path:
        """Where block ``index`` is written (for messages)."""
        return self.store

    def keys(self, index: int) -> list[str]:
        slab = self.tiling.slices(index)
        return [k for n in self.names for k in chunk_keys(n, slab, self.tiling.chunk)]

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

    def _digest(self, index: int) -> tuple[int, str] | None:
        entries = []
        for key in self.keys(index):
            try:
                fd = os.open(self.store / key, os.O_RDONLY | O_NOFOLLOW | O_CLOEXEC)
            except OSError:
                return None
            with os.fdopen(fd, "rb") as f:
                data = f.read()
            entries.append((key, len(data), hashlib.sha256(data).hexdigest()))
        return sum(n for _, n, _ in entries), _files_digest(entries)

    def scan(self) -> Scan:
        """Hash the chunk files of every journaled block against its receipt (changes
        nothing); blocks not journaled are simply written again."""
        found = Scan()
        for index, receipt in sorted(self.journal.items()):
            got = self._digest(index)
            if got == (receipt["bytes"], receipt["files"]):
                found.good.add(index)
            else:
                why = "missing" if got is None else "its checksum does not match the journal"
                found.bad[f"block {index}"] = f"chunk files {why}"
        return found

    def discard(self, found: Scan) -> None:
        """Report the bad blocks (their chunks are replaced when they are computed again)."""
        for name, why in found.bad.items():
            self.warn(f"{name} of {self.store} is corrupt ({why}); recomputing")

    def check_sizes(self) -> None:
        """OutputError unless every block is journaled and its chunk files have the recorded
        total size (a cheap check before the store is committed: no value is read)."""
        for index in range(self.tiling.nblocks):
            receipt = self.journal.get(index)
            if receipt is None:
                raise OutputError(f"block {index} is not recorded in the journal")
            try:
                size = sum(os.lstat(self.store / k).st_size for k in self.keys(index))
            except OSError:
                size = -1
            if size != receipt["bytes"]:
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

    def remove(self) -> None:
        """Delete the run's directory: the manifest first (what is left is debris)."""
        remove_store(self.root)


def _root_meta(store: Path) -> dict:
    return _meta(store / "zarr.json")


def _array_meta(store: Path, name: str) -> dict:
    return _meta(store / name / "zarr.json")


def _meta(path: Path) -> dict:
    try:
        doc = json.loads(read_regular(path, _MAX_META_BYTES, follow_links=False))
    except FileNotFoundError:
        raise OutputError(f"{path} is missing") from None
    except (OSError, ValueError, RecursionError) as exc:
        raise OutputError(f"{path} is unreadable ({exc})") from None
    if not isinstance(doc, dict):
        raise OutputError(f"{path} is not Zarr metadata")
    return doc


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

"""The block store of a streamed run: verified blocks, a journal of their checksums, cleanup.

Layout while a run is under way, next to the output ``OUT``::

    OUT.parts/                  created by the run, mode 0700 (a link or another user's
                                directory is refused)
    OUT.parts/manifest.json     the survey's fingerprint, tiling, variables (engine.io.manifest)
    OUT.parts/journal           one line per committed block: index, size, SHA-256, line check
    OUT.parts/b00000042.chunks  block 42 as compressed storage chunks, the bytes the output
                                gets (engine.io.chunkfile; a run whose output is deflated)
    OUT.parts/b00000042.npz     or its values (engine.io.npz; any other compression)

A block is committed in this order: its file is written under a fresh temporary name (``O_EXCL |
O_NOFOLLOW``), fsynced and renamed into place; then its size and SHA-256 are appended to the journal
and the journal is fsynced (during a run, on a thread of their own while the run goes on:
:meth:`BlockStore.behind`, :mod:`engine.io.journal`). A block counts only if its file's bytes have
the size and hash its last journal line records: a file without a journal line (killed between the
two steps), a truncated, edited or swapped file, or a link in its place is reported and computed
again (:meth:`BlockStore.scan`, on resume), and every block is hashed again as the merge reads it
(:meth:`BlockStore.blocks`). A torn last journal line (killed mid-append) fails its line check and
is ignored. Files that are not the store's are reported and left alone.

Removing a store (:meth:`BlockStore.remove`) deletes the manifest first: a store without a
manifest is the debris of a killed cleanup (or of a run killed as it started) and holds nothing
that can be verified; the next run removes it.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import re
import shutil
import stat
import tomllib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..grid import Tiling
from ..schema import grid_dims
from . import OutputError
from .atomic import (
    NEW_FILE,
    O_CLOEXEC,
    O_NOFOLLOW,
    TMP_SUFFIX,
    NotRegularFile,
    fsync_dir,
    read_regular,
    write_unsynced,
)
from .chunkfile import SUFFIX, ChunkCodec, StoredBlock, read_block, write_block
from .deflate import compress_pool
from .journal import JOURNAL, Durability, append_journal, read_journal
from .manifest import MANIFEST, Manifest, read_manifest, survey_variables, write_manifest
from .npz import write_npz

if TYPE_CHECKING:
    from .planshape import RunPlan

__all__ = [
    "JOURNAL",
    "BlockStore",
    "Scan",
    "block_file_bytes",
    "check_parts_dir",
    "estimate_bytes",
    "make_parts_dir",
    "parts_info",
]

_BLOCK = re.compile(r"b(\d{8})\.(?:npz|chunks)")
#: Zip headers of one member of a block file, an upper bound [bytes].
_NPZ_MEMBER_OVERHEAD = 512
_CHUNK_OVERHEAD = 64  # a deflated chunk's framing and header entry, an upper bound [bytes]


def estimate_bytes(plan: RunPlan) -> int:
    """Uncompressed size [bytes] of the results (the block files hold this much)."""
    per_point = sum(dt.itemsize for dt in survey_variables(plan).values())
    return per_point * plan.size


def block_file_bytes(names: dict[str, np.dtype], points: int, chunks: int = 1) -> int:
    """Upper bound of the size [bytes] of one block file of ``points`` points in ``chunks``
    storage chunks per variable (deflate grows what it cannot shrink by < 1/8192 + framing;
    the zeros padding an edge chunk shrink to next to nothing)."""
    values = sum(dt.itemsize for dt in names.values()) * points
    framing = _CHUNK_OVERHEAD * chunks * len(names)
    return values + values // 8192 + framing + _NPZ_MEMBER_OVERHEAD * (len(names) + 1)


def check_parts_dir(root: Path) -> bool:
    """Whether the block store ``root`` exists; OutputError if it is a link, not a directory,
    another user's, or writable by others (nothing in it could be trusted)."""
    try:
        st = os.lstat(root)
    except FileNotFoundError:
        return False
    if stat.S_ISLNK(st.st_mode):
        raise OutputError(f"{root} is a symbolic link; refusing to use it (remove it)")
    if not stat.S_ISDIR(st.st_mode):
        raise OutputError(f"{root} is not a directory; refusing to use it (remove it)")
    uid = getattr(os, "getuid", None)
    if uid is not None and st.st_uid != uid():
        raise OutputError(f"{root} belongs to another user (uid {st.st_uid}); refusing to use it")
    if st.st_mode & 0o022:
        raise OutputError(f"{root} is writable by other users; refusing to use it")
    return True


def _file_digest(path: Path, size: int) -> str | None:
    """SHA-256 of the regular file ``path`` (not followed), None if it is not one or its size
    is not ``size``; FileNotFoundError if it is gone."""
    try:
        fd = os.open(path, os.O_RDONLY | O_NOFOLLOW | O_CLOEXEC)
    except OSError as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        return None
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_size != size:
            return None
        return hashlib.file_digest(f, "sha256").hexdigest()


@dataclass
class Scan:
    """What :meth:`BlockStore.scan` found: verified block indices, bad block files (name ->
    reason), stale temporary files and files that are not the store's."""

    good: set[int] = field(default_factory=set)
    bad: dict[str, str] = field(default_factory=dict)
    tmp: list[str] = field(default_factory=list)
    stray: list[str] = field(default_factory=list)


@dataclass
class BlockStore:
    """The committed blocks of one run, verified against the journal."""

    root: Path
    tiling: Tiling
    names: dict[str, np.dtype]
    warn: Callable[[str], None] = field(default=lambda msg: None)
    journal: dict[int, tuple[int, str]] = field(default_factory=dict)
    codec: ChunkCodec | None = None  # None: .npz files of the values
    _behind: Durability | None = field(default=None, repr=False)

    @classmethod
    def create(
        cls, root: Path, manifest: Manifest, warn: Callable[[str], None] = lambda msg: None
    ) -> BlockStore:
        """A new store: the directory (mode 0700; FileExistsError if it exists), the manifest
        and an empty journal. Removed again if any of that fails."""
        make_parts_dir(root)
        try:
            write_manifest(root, manifest)
            os.close(os.open(root / JOURNAL, NEW_FILE, 0o600))
            fsync_dir(root)
            fsync_dir(root.parent)
        except BaseException:
            with contextlib.suppress(OSError):
                remove_store(root)
            raise
        return cls(root, manifest.tiling, manifest.names, warn, codec=manifest.codec)

    @classmethod
    def open(cls, root: Path, warn: Callable[[str], None] = lambda msg: None) -> BlockStore:
        """The existing store ``root`` (its manifest and journal read and checked)."""
        m = read_manifest(root)
        return cls(root, m.tiling, m.names, warn, read_journal(root, m.tiling.nblocks), m.codec)

    def path(self, index: int) -> Path:
        return self.root / f"b{index:08d}{'.npz' if self.codec is None else SUFFIX}"

    # -- writing --

    def commit(self, index: int, arrays: dict[str, np.ndarray]) -> StoredBlock:
        """Store block ``index``: write its file atomically, then journal its size and hash.
        Returns the block as stored (the store's variables, C-contiguous, its dtypes; with a
        codec, the compressed chunks its file holds, made here on every core)."""
        clean = {n: np.ascontiguousarray(arrays[n], dtype=dt) for n, dt in self.names.items()}
        block, codec = StoredBlock(clean), self.codec
        if codec is not None:
            slab, chunk = self.tiling.slices(index), self.tiling.chunk
            block = StoredBlock(clean, codec.encode(slab, chunk, clean, compress_pool()), codec)
        fill = (lambda f: write_block(f, block)) if codec else (lambda f: write_npz(f, clean))
        path, sequential = self.path(index), bool(codec)
        if self._behind is not None:  # written, made durable and journaled on its thread
            self._behind.submit(
                index,
                lambda: write_unsynced(
                    path, fill, mode=0o600, sequential=sequential, direct=sequential
                ),
            )
            return block
        written = write_unsynced(path, fill, mode=0o600, sequential=sequential, direct=sequential)
        written.finish()
        self._journaled(index, written.size, written.digest)
        return block

    def _journaled(self, index: int, size: int, digest: str) -> None:
        append_journal(self.root, index, size, digest)
        self.journal[index] = (size, digest)

    @contextlib.contextmanager
    def behind(self, on_durable: Callable[[int], None] | None = None) -> Iterator[None]:
        """Inside, :meth:`commit` returns once the block is compressed: a thread writes its file,
        makes it durable and journals it, at most :data:`DEPTH` blocks behind, then calls
        ``on_durable(index)`` (:class:`engine.io.journal.Durability`; :meth:`load` waits for a
        block still on its way). Leaving waits for every committed block (and raises the
        thread's error, unless leaving on an error)."""
        sync = Durability(self._journaled, on_durable)
        self._behind = sync
        try:
            with sync:
                yield
        finally:
            self._behind = None

    # -- verifying --

    def scan(self) -> Scan:
        """Check every file of the store against the journal (reads and hashes every block;
        changes nothing)."""
        found = Scan()
        for name in sorted(os.listdir(self.root)):
            if name in (MANIFEST, JOURNAL):
                continue
            if name.endswith(TMP_SUFFIX):
                found.tmp.append(name)
                continue
            m = _BLOCK.fullmatch(name)
            index = int(m.group(1)) if m else -1  # a block of this store's kind, in range:
            if not 0 <= index < self.tiling.nblocks or name != self.path(index).name:
                found.stray.append(name)
                continue
            entry = self.journal.get(index)
            if entry is None:
                found.bad[name] = "not recorded in the journal"
                continue
            try:
                digest = _file_digest(self.root / name, entry[0])
            except FileNotFoundError:
                continue
            if digest is None:
                found.bad[name] = "not a regular file of the recorded size"
            elif digest != entry[1]:
                found.bad[name] = "its checksum does not match the journal"
            else:
                found.good.add(index)
        return found

    def discard(self, found: Scan) -> None:
        """Report and delete the bad blocks and stale temporary files; report strays."""
        for name, why in found.bad.items():
            self.warn(f"block file {name} is corrupt ({why}); recomputing")
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.root / name)
        for name in found.tmp:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.root / name)
        if found.stray:
            shown = ", ".join(found.stray[:5]) + (" ..." if len(found.stray) > 5 else "")
            self.warn(f"ignoring files that are not blocks of this run in {self.root}: {shown}")

    def load(self, index: int) -> StoredBlock:
        """Block ``index``, its bytes verified against the journal as they are read;
        OutputError if it is missing, changed or of the wrong layout."""
        if self._behind is not None:
            self._behind.wait(index)
        entry = self.journal.get(index)
        p = self.path(index)
        if entry is None:
            raise OutputError(f"block {index} is not recorded in the journal")
        try:
            data = read_regular(p, entry[0], follow_links=False)
        except FileNotFoundError:
            raise OutputError(f"block file {p.name} vanished") from None
        except (NotRegularFile, ValueError):
            data = b""
        if len(data) != entry[0] or hashlib.sha256(data).hexdigest() != entry[1]:
            raise OutputError(f"block file {p.name} changed since it was written")
        return self.decode(index, data)

    def decode(self, index: int, data: bytes) -> StoredBlock:
        """Block ``index`` from its file's bytes ``data`` (not verified here); OutputError if
        they are not a block of this store."""
        p, slab = self.path(index), self.tiling.slices(index)
        try:
            if self.codec is not None:
                return read_block(data, self.codec, self.names, slab, self.tiling.chunk)
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                out = {n: z[n] for n in self.names}
        except Exception as exc:  # a journaled file that numpy cannot read: not ours
            raise OutputError(f"block file {p.name} is unreadable ({exc})") from None
        for n, dt in self.names.items():
            if out[n].shape != tuple(s.stop - s.start for s in slab) or out[n].dtype != dt:
                raise OutputError(f"block file {p.name} has the wrong {n} layout")
        return StoredBlock(out)

    def take(self, index: int) -> StoredBlock:
        """Block ``index`` for the merge, verified as it is read (:meth:`load`); a bad block is
        deleted (so that the next run computes it again) and raises OutputError."""
        try:
            return self.load(index)
        except OutputError as exc:
            with contextlib.suppress(OSError):
                os.unlink(self.path(index))
            raise OutputError(f"{exc}; it will be computed again") from None

    def blocks(self) -> Iterator[tuple[tuple[slice, ...], StoredBlock]]:
        """(hyperslab, block) of every block in order, each read by :meth:`take`."""
        return ((self.tiling.slices(i), self.take(i)) for i in range(self.tiling.nblocks))

    def remove(self) -> list[str]:
        """Delete the store: the manifest first (what is left is recognisable debris); returns
        the names of a user's files left in it."""
        return remove_store(self.root)


#: The names a run (netCDF or Zarr) makes in its directory besides the block files and the
#: temporary files; anything else there is a user's, and left alone.
RUN_FILES = (MANIFEST, JOURNAL, "store.zarr", "replaced.zarr", "commit.json")


def _is_runs(name: str) -> bool:
    return name in RUN_FILES or bool(_BLOCK.fullmatch(name)) or name.endswith(TMP_SUFFIX)


def make_parts_dir(root: Path) -> None:
    """Create the run's directory ``root`` (mode 0700); an existing one is taken only if it
    holds no run (its manifest removed: a user's files left in it are kept)."""
    try:
        os.mkdir(root, 0o700)
    except FileExistsError:
        if not check_parts_dir(root) or os.path.lexists(root / MANIFEST):
            raise
        if any(_is_runs(n) for n in os.listdir(root)):
            raise


def remove_store(root: Path) -> list[str]:
    """Delete the run's directory ``root`` (a link is not followed): manifest first, then the
    run's own files; files a user put there are left, with the directory (their names are
    returned)."""
    with contextlib.suppress(FileNotFoundError):
        os.unlink(root / MANIFEST)
    fsync_dir(root)
    kept = []
    for name in sorted(os.listdir(root)):
        p = root / name
        if not _is_runs(name):
            kept.append(name)
        elif os.path.isdir(p) and not os.path.islink(p):
            shutil.rmtree(p)
        else:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(p)
    if not kept:
        os.rmdir(root)
    return kept


def survey_dims(definition: str) -> tuple[str, ...]:
    """The axes named in a survey definition (launch states or invariants)."""
    return grid_dims(_axes_table(definition))


def _axes_table(definition: str) -> dict[str, Any]:
    try:
        axes = tomllib.loads(definition).get("axes", {})
    except (tomllib.TOMLDecodeError, RecursionError):
        return {}
    return axes if isinstance(axes, dict) else {}


def parts_info(root: Path) -> dict[str, Any]:
    """What an unfinished run's block store says about it (``read_info`` of a backend):
    OutputError if the manifest is missing or invalid. Blocks are counted, not verified."""
    m = read_manifest(root)
    names = os.listdir(root)
    done = {int(mm.group(1)) for n in names if (mm := _BLOCK.fullmatch(n))}
    return {
        "complete": False,
        "attrs": {"survey_definition": m.survey_definition, "engine": m.engine},
        "dims": dict(zip(survey_dims(m.survey_definition), m.tiling.shape, strict=True)),
        "blocks_done": len({i for i in done if i < m.tiling.nblocks}),
        "blocks_total": m.tiling.nblocks,
    }

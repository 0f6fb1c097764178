"""What a conesurvey Zarr store looks like, and the writer of its chunks.

- the metadata (made by :func:`engine.io.zarrskeleton.make_store`): a Zarr v3 root group, the
  axes and the variables on fewer dims (their values), the data variables with the netCDF
  file's storage chunks,
  ``dimension_names``, CF attributes from :mod:`engine.schema` (``_FillValue`` NaN on floats
  as xarray encodes it in Zarr v3; none on integers and axes), Blosc
  (:data:`engine.io.zarrchunks.BLOSC`), chunk keys ``name/c.i.j.k.l`` (one directory per
  variable: :data:`engine.io.zarrchunks.SEPARATOR`);
- :class:`ChunkWriter`: the chunks of one block, encoded as zarr encodes them for the store's arrays
  (:mod:`engine.io.zarrchunks`), each written under a fresh ``O_EXCL | O_NOFOLLOW`` temporary name,
  fsynced and renamed, every directory opened without following links from one descriptor of the
  store, after checking the store is still the run's (its root names the run's id); returns the
  block's receipt (:mod:`engine.io.zarrstore`);
- :class:`ZarrView`: a store seen through the netCDF4 calls :mod:`engine.io.contents` makes,
  so the content checksum is computed and verified the same way in both formats.
"""

from __future__ import annotations

import base64
import contextlib
import hashlib
import json
import os
import secrets
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errortext import install_hint
from . import OutputError
from .atomic import NEW_FILE, O_CLOEXEC, O_NOFOLLOW, O_NONBLOCK, read_regular
from .cf import typed_flags
from .contents import block_digest
from .hold import BUSY, HELD, HeldFiles
from .pagecache import drop_cached
from .summary import Summary
from .zarrchunks import SEPARATOR, encode

__all__ = [
    "RUN_ATTR",
    "STORE",
    "UNFINISHED_ATTR",
    "ChunkWriter",
    "ZarrView",
    "fill_attr",
    "json_attr",
    "READ_ONLY",
    "read_all",
    "read_meta",
    "zarr_module",
]

STORE = "store.zarr"
#: Root attribute of a store being written: what it is, and when it is complete.
UNFINISHED_ATTR = "conesurvey_unfinished"
#: Root attribute of a store being written: the run's random id (checked by every writer).
RUN_ATTR = "conesurvey_run"
UNFINISHED_TEXT = (
    "a conesurvey run is writing this store; it is complete when it is renamed to its output "
    "name and its root carries survey_fingerprint and content_checksum"
)
_DIR_FLAGS = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | O_NOFOLLOW | O_CLOEXEC
_MAX_META_BYTES = 64 << 20


def zarr_module() -> Any:
    """The ``zarr`` package (an optional dependency); OutputError saying how to install it."""
    try:
        import zarr
    except ImportError:
        raise OutputError(f"Zarr output needs the zarr package: {install_hint('zarr')}") from None
    return zarr


def files_digest(entries: list[tuple[str, int, str]]) -> str:
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
    separator: str = SEPARATOR  # of the chunk keys: the store's own (its arrays' metadata)
    #: The files the run's own process holds (:mod:`engine.io.hold`): each chunk file is read
    #: back once written and held until the commit, its pages then leaving the cache; None in
    #: a writer that travelled to another process (its files are hashed again at the commit).
    held: HeldFiles | None = field(default=None, compare=False)

    def __reduce__(self) -> tuple:
        """Pickled without ``held``: a dask worker's writes are checked by their hashes."""
        fields = (self.root, self.run_id, self.shape, self.chunk, self.arrays, self.complevel)
        return (ChunkWriter, (*fields, self.separator))

    def encode(self, slab: tuple[slice, ...], values: dict[str, np.ndarray]) -> dict[str, bytes]:
        """The chunk files (key -> bytes) of the hyperslab ``slab`` of every variable
        (:func:`engine.io.zarrchunks.encode`)."""
        return encode(slab, self.chunk, self.arrays, values, self.complevel, self.separator)

    def write(self, index: int, slab: tuple[slice, ...], values: dict[str, np.ndarray]) -> dict:
        """Write block ``index`` (its hyperslab ``slab``); returns its receipt. OSError if the
        store cannot be written or is no longer this run's."""
        clean = {n: np.ascontiguousarray(values[n], dtype=dt) for n, dt in self.arrays}
        digests = dict(
            zip(clean, _on_threads(lambda a: block_digest(a).hex(), [*clean.values()]), strict=True)
        )
        files = self.encode(slab, clean)
        fd = self._open_store()
        try:
            entries = _put_files(fd, files, self.held)
        finally:
            os.close(fd)
        stats = Summary()
        stats.add(clean)
        return {
            "i": index,
            "bytes": sum(n for _, n, _ in entries),
            "files": files_digest(entries),
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


def _put_files(
    root_fd: int, files: dict[str, bytes], held: HeldFiles | None = None
) -> list[tuple[str, int, str]]:
    """Write every file atomically (temporary name, fsync, rename), then fsync the directories
    that changed; returns (key, size, SHA-256) of each. Each file is created, written, fsynced
    and hashed on one of :data:`IO_THREADS` threads (making an inode can take ~1 ms: ext4
    without a journal passes over the inodes deleted in the last minutes; one after another
    the files took most of the writer's time, docs/output.md "Zarr stores"), then the files
    are renamed in order: none before its fsync. With ``held``, each file is held
    (:func:`_hold_written`) before it is renamed, and its pages leave the cache."""
    cache: dict[str, int] = {}
    items = sorted(files.items())
    pending: list[tuple[int, str, str]] = []  # (directory fd, temporary name, name) to rename
    try:
        for key, _ in items:
            *dirs, leaf = key.split("/")
            dfd = _open_dirs(root_fd, dirs, cache)
            pending.append((dfd, f".{leaf}.{secrets.token_hex(6)}.tmp", leaf))

        def put(job: tuple[tuple[int, str, str], tuple[str, bytes]]) -> tuple[str, int, str]:
            (dfd, tmp, _), (key, data) = job
            fd = os.open(tmp, NEW_FILE, 0o666, dir_fd=dfd)
            ro = None
            try:
                view = memoryview(data)
                while view:
                    view = view[os.write(fd, view) :]
                os.fsync(fd)
                if held is not None:  # read-only, of this very file; the writable one closed
                    ro = os.open(tmp, READ_ONLY, dir_fd=dfd)
                    if _inode(ro) != _inode(fd):
                        os.close(ro)
                        raise OutputError(f"{key}: its temporary file was replaced while written")
            finally:
                os.close(fd)
            if ro is not None:
                _hold_written(held, key, ro, data)  # type: ignore[arg-type]
            return key, len(data), hashlib.sha256(data).hexdigest()

        entries = _on_threads(put, list(zip(pending, items, strict=True)))
        for dfd, tmp, leaf in list(pending):
            os.rename(tmp, leaf, src_dir_fd=dfd, dst_dir_fd=dfd)
            pending.pop(0)
        _on_threads(os.fsync, [root_fd, *cache.values()])
    finally:
        for dfd, tmp, _ in pending:  # not renamed: an error on the way (or never made)
            with contextlib.suppress(OSError):
                os.unlink(tmp, dir_fd=dfd)
        for dfd in cache.values():
            os.close(dfd)
    return entries


#: How a store's file is opened to be read or held: never through a link, never blocking.
READ_ONLY = os.O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC


def _inode(fd: int) -> tuple[int, int]:
    st = os.fstat(fd)
    return st.st_dev, st.st_ino


def read_all(fd: int, limit: int) -> bytes:
    """Up to ``limit`` bytes of the open file ``fd`` from its start (the descriptor's own
    offset is neither used nor moved)."""
    parts, offset = [], 0
    while offset < limit:
        got = os.pread(fd, min(limit - offset, 1 << 26), offset)
        if not got:
            break
        parts.append(got)
        offset += len(got)
    return b"".join(parts)


def _hold_written(held: HeldFiles, key: str, fd: int, data: bytes) -> None:
    """Hold the chunk file ``key`` just written with ``data`` (``fd``: read-only, of it): its
    lease taken, then its bytes read back (from the cache: they were just written) and
    compared with ``data``, then its pages given back. OutputError if another process has it
    open for writing, or changed it between the write and the lease. Where it is not held (a
    file system without leases, no descriptor left) it is closed: the commit hashes it."""
    got = held.hold(key, fd)
    try:
        if got == BUSY:
            raise OutputError(
                f"{key}: another process has the chunk file open for writing while the run "
                "writes it (a writable mapping counts)"
            )
        if got == HELD and read_all(fd, len(data) + 1) != data:
            raise OutputError(
                f"{key}: the chunk file changed while it was written (another process wrote it)"
            )
        drop_cached(fd)
    except BaseException:
        if got == HELD:
            held.drop(key)
        else:
            os.close(fd)
        raise
    if got != HELD:
        os.close(fd)


#: Threads that fsync a block's chunk files and hash its variables (work that releases the
#: GIL; not the numba threads).
IO_THREADS = 8


def _on_threads(fn: Callable[[Any], Any], items: list[Any]) -> list[Any]:
    """``fn`` of every item, on up to :data:`IO_THREADS` threads; the first error raised."""
    if len(items) <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(min(IO_THREADS, len(items))) as pool:
        return list(pool.map(fn, items))


# --- metadata ---


def json_attr(value: Any) -> Any:
    """An attribute value as JSON (numpy scalars and arrays become numbers and lists)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def fill_attr(dtype: np.dtype) -> str:
    """The CF ``_FillValue`` (NaN) of a float variable as xarray encodes it in Zarr v3
    attributes: base64 of its little-endian bytes as float64 (xarray decodes 8 bytes whatever
    the variable's float type)."""
    return base64.b64encode(np.array(np.nan, "<f8").tobytes()).decode()


def _decoded(attrs: Mapping[str, Any], dtype: np.dtype) -> dict[str, Any]:
    """Variable attributes as the netCDF file gives them: ``flag_values`` of the variable's
    type, ``_FillValue`` as a number."""
    out = typed_flags(attrs, dtype)
    fill = out.get("_FillValue")
    if isinstance(fill, str):
        with contextlib.suppress(ValueError, TypeError):
            raw = np.frombuffer(base64.b64decode(fill), "<f8")[0]
            out["_FillValue"] = np.asarray(raw, dtype.newbyteorder("="))[()]
    return out


class _Attrs:
    """The attributes of a store or array, as netCDF4 gives them."""

    _attrs: dict[str, Any]

    def ncattrs(self) -> list[str]:
        return list(self._attrs)

    def getncattr(self, key: str) -> Any:
        return self._attrs[key]

    def set_auto_maskandscale(self, flag: bool) -> None:
        """Nothing to switch off: a Zarr array gives its stored values."""


class _Var(_Attrs):
    """One array of a store, as engine.io.contents reads a netCDF variable."""

    def __init__(self, arr: Any) -> None:
        self.arr = arr
        self.dtype = np.dtype(arr.dtype)
        self.shape = tuple(arr.shape)
        self.ndim = len(self.shape)
        self.dimensions = tuple(arr.metadata.dimension_names or ())
        self._attrs = _decoded(dict(arr.attrs), self.dtype)

    def chunking(self) -> list[int]:
        return list(self.arr.chunks)

    def __getitem__(self, key: Any) -> np.ndarray:
        return np.asarray(self.arr[key])


class ZarrView(_Attrs):
    """A Zarr store seen through the netCDF4 calls :mod:`engine.io.contents` makes (the
    content checksum is computed and verified the same way in both formats). ``attrs``
    replaces the root's attributes (the ones a commit is about to write); ``files``, a
    store's skeleton (key -> bytes, :mod:`engine.io.zarrskeleton`), replaces its metadata on
    disk (the arrays' values cannot be read then)."""

    def __init__(
        self,
        path: Path,
        attrs: Mapping[str, Any] | None = None,
        files: Mapping[str, bytes] | None = None,
    ) -> None:
        zarr = zarr_module()
        if files is None:
            store = zarr.storage.LocalStore(path, read_only=True)
        else:
            from zarr.core.buffer import default_buffer_prototype

            buffer = default_buffer_prototype().buffer
            found = {k: buffer.from_bytes(v) for k, v in files.items()}
            store = zarr.storage.MemoryStore(found, read_only=True)
        group = zarr.open_group(store, mode="r", zarr_format=3)
        self._attrs = dict(group.attrs) if attrs is None else dict(attrs)
        self.variables = {name: _Var(arr) for name, arr in group.arrays()}


def read_meta(path: Path) -> dict:
    try:
        doc = json.loads(read_regular(path, _MAX_META_BYTES, follow_links=False))
    except FileNotFoundError:
        raise OutputError(f"{path} is missing") from None
    except (OSError, ValueError, RecursionError) as exc:
        raise OutputError(f"{path} is unreadable ({exc})") from None
    if not isinstance(doc, dict):
        raise OutputError(f"{path} is not Zarr metadata")
    return doc

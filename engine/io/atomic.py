"""Files that appear under their name complete or not at all, never written through a link.

Every file conesurvey writes (a netCDF result, a block of a streamed run, the run's manifest)
goes through :func:`write_atomic` or :func:`replacing`: it is written under a fresh temporary
name in the same directory, ``NAME.<random>.tmp``, created with ``O_CREAT | O_EXCL |
O_NOFOLLOW`` (so it is never an existing file, and never a symbolic link planted there), made
durable (fsync), renamed to ``NAME`` and the directory is fsynced so that the rename survives a
power cut. On any error, KeyboardInterrupt included, the temporary file is removed and ``NAME``,
new or old, is untouched. Two writers of the same name never share a temporary file.

Renaming either replaces an existing ``NAME`` atomically (``os.replace``; a link at ``NAME`` is
replaced, its target untouched; a FIFO, a device, a socket or a directory never is:
:func:`refuse_special`) or refuses to (:func:`rename_no_clobber`: a hard link, which
fails if ``NAME`` appeared meanwhile).

Policy for the directory fsync (:func:`fsync_dir`): skipped on Windows, where a directory cannot
be opened; elsewhere an error that means "this file system cannot fsync a directory"
(:data:`NOT_SUPPORTED`) is ignored and any other error (EIO, ...) is raised, since the rename
may then not be durable.

:func:`read_regular` is the one way conesurvey reads a file it did not just write (a survey
definition, a manifest): regular files only (a FIFO or a device is refused without blocking),
at most a given number of bytes.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import secrets
import stat
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from .pagecache import O_CLOEXEC, O_NOFOLLOW, DirectWriter, drop_cached

__all__ = [
    "NOT_SUPPORTED",
    "NotRegularFile",
    "create_new",
    "fsync_path",
    "fsync_dir",
    "exists_error",
    "not_regular",
    "output_name_problem",
    "read_regular",
    "refuse_special",
    "rename_no_clobber",
    "replacing",
    "write_atomic",
    "write_unsynced",
    "Written",
]

#: errno values of a directory fsync that mean "not supported here", not "the data is lost".
NOT_SUPPORTED = frozenset(
    {errno.EINVAL, errno.EBADF, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS}
)
#: Whether directories can be opened (and fsynced) on this operating system.
DIRECTORIES_OPEN = os.name != "nt"
O_NONBLOCK = getattr(os, "O_NONBLOCK", 0)
#: Flags of a file created by this package: new, never through a link.
NEW_FILE = os.O_RDWR | os.O_CREAT | os.O_EXCL | O_NOFOLLOW | O_CLOEXEC | getattr(os, "O_BINARY", 0)
#: Suffix of every temporary file (a killed run may leave some; they are never reused).
TMP_SUFFIX = ".tmp"


class NotRegularFile(OSError):
    """A path that is a FIFO, a device, a socket or a directory where a file was expected."""


def create_new(directory: Path, stem: str, mode: int = 0o666) -> tuple[int, Path]:
    """Create ``directory/stem.<random>.tmp`` exclusively (``O_EXCL | O_NOFOLLOW``): a new,
    empty regular file of this process. Returns (open file descriptor, path)."""
    for _ in range(64):
        path = directory / f"{stem}.{secrets.token_hex(6)}{TMP_SUFFIX}"
        try:
            return os.open(path, NEW_FILE, mode), path
        except FileExistsError:  # taken (or a planted link): draw another name
            continue
    raise FileExistsError(errno.EEXIST, "no free temporary name", str(directory / stem))


#: Bytes the longest name made from an output's name adds to it (``NAME.<12 hex>.tmp``).
NAME_OVERHEAD = 17


def output_name_problem(path: Path) -> str | None:
    """Why ``path`` cannot be an output's name (None if it can): a name that is not UTF-8
    (it is written into the results and their manifest), or one too long for the temporary
    names made from it (``NAME.<random>.tmp``, ``NAME.parts``)."""
    name = os.fsencode(Path(path).name)
    try:
        name.decode("utf-8")
    except UnicodeDecodeError:
        return f"output name {name!r} is not valid UTF-8; give a UTF-8 file name"
    try:
        limit = os.pathconf(Path(path).parent, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        limit = 255
    if len(name) + NAME_OVERHEAD > limit:
        return (
            f"output name is {len(name)} bytes long; at most {limit - NAME_OVERHEAD} fit "
            f"(the temporary names made from it add {NAME_OVERHEAD} to the file system's "
            f"{limit})"
        )
    return None


def fsync_path(path: Path) -> None:
    """Flush the contents of the file ``path`` to the disk."""
    fd = os.open(path, os.O_RDONLY | O_NOFOLLOW | O_CLOEXEC)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(directory: Path) -> None:
    """Make a rename in ``directory`` durable (see the module docstring for what is ignored)."""
    if not DIRECTORIES_OPEN:
        return
    try:
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | O_CLOEXEC)
    except OSError as exc:
        if exc.errno in NOT_SUPPORTED:
            return
        raise
    try:
        os.fsync(fd)
    except OSError as exc:
        if exc.errno not in NOT_SUPPORTED:
            raise
    finally:
        os.close(fd)


def exists_error(path: Path) -> FileExistsError:
    """The error for an output that exists and may not be replaced."""
    return FileExistsError(
        errno.EEXIST, "output file exists (pass overwrite to replace it)", str(path)
    )


def rename_no_clobber(src: Path, dst: Path) -> None:
    """Rename ``src`` to ``dst``, failing with FileExistsError if ``dst`` exists.

    Atomic where hard links work; elsewhere (some network or FAT file systems) ``dst`` is
    checked just before ``os.replace``.
    """
    try:
        os.link(src, dst)  # atomic: fails if dst exists
    except FileExistsError:
        raise exists_error(dst) from None
    except OSError as exc:
        if exc.errno == errno.ENOSPC:
            raise
        if os.path.lexists(dst):  # no hard links here
            raise exists_error(dst) from None
        os.replace(src, dst)
        return
    os.unlink(src)


def refuse_special(path: Path) -> None:
    """NotRegularFile if ``path`` (not followed) is a FIFO, a device, a socket or a directory:
    what ``--overwrite`` never replaces (a symbolic link is replaced, its target untouched)."""
    kind = not_regular(path, follow_links=False)
    if kind not in (None, "a symbolic link"):
        raise NotRegularFile(errno.EINVAL, f"is {kind}; refusing to replace it", str(path))


def _put_in_place(tmp: Path, path: Path, overwrite: bool) -> None:
    if overwrite:
        refuse_special(path)  # checked again just before the rename
        os.replace(tmp, path)
    else:
        rename_no_clobber(tmp, path)
    fsync_dir(path.parent)
    if tmp.parent != path.parent:
        fsync_dir(tmp.parent)


@contextlib.contextmanager
def replacing(path: Path, *, overwrite: bool = True, tmp_dir: Path | None = None) -> Iterator[Path]:
    """Yield a new empty temporary file (:func:`create_new`) for a writer that needs a path
    (HDF5); the caller writes it and makes it durable (:func:`fsync_path`); then it is renamed
    to ``path`` and the directory fsynced.

    ``tmp_dir`` (default: beside ``path``, on the same file system) is where the temporary file
    lives; the streamed runs use their private block store. Without ``overwrite`` an existing
    ``path`` is never replaced (FileExistsError, checked before writing and again, atomically,
    when renaming). On any error the temporary file is removed and ``path`` is untouched.
    """
    if not overwrite and os.path.lexists(path):
        raise exists_error(path)
    refuse_special(path)
    fd, tmp = create_new(tmp_dir or path.parent, path.name)
    os.close(fd)
    try:
        yield tmp
        _put_in_place(tmp, path, overwrite)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise


def write_atomic(
    path: Path,
    write: Callable[[BinaryIO], None],
    *,
    mode: int = 0o666,
    overwrite: bool = True,
    sequential: bool = False,
) -> tuple[int, str]:
    """Write ``path`` with ``write(file)`` (binary) through a new temporary file opened with
    ``O_EXCL | O_NOFOLLOW``, fsync it and rename it into place (replacing ``path`` unless not
    ``overwrite``). Returns the size [bytes] and SHA-256 (hex) of what was written, read back
    through the same descriptor before the rename; with ``sequential`` (``write`` only calls
    ``file.write``, never seeks), hashed as it is written instead (no second pass)."""
    written = write_unsynced(path, write, mode=mode, overwrite=overwrite, sequential=sequential)
    written.finish()
    return written.size, written.digest


def write_unsynced(
    path: Path,
    write: Callable[[BinaryIO], None],
    *,
    mode: int = 0o666,
    overwrite: bool = True,
    sequential: bool = False,
    direct: bool = False,
) -> Written:
    """The first half of :func:`write_atomic`: ``path``'s bytes written and hashed under a new
    temporary name, not yet durable nor in place; :meth:`Written.finish` does the rest (the
    descriptor stays open until then). On any error the temporary file is removed. With
    ``direct`` (and ``sequential``), written past the page cache where the file system takes
    it (:class:`engine.io.pagecache.DirectWriter`): for a file that is not read back soon."""
    if overwrite:
        refuse_special(path)
    fd, tmp = create_new(path.parent, path.name, mode)
    try:
        if direct and sequential:
            sink = DirectWriter(fd)
            hashed = _Hashed(sink)  # type: ignore[arg-type]
            write(hashed)  # type: ignore[arg-type]
            sink.close()
            return Written(fd, tmp, path, hashed.size, hashed.sha.hexdigest(), overwrite)
        with os.fdopen(fd, "w+b", closefd=False) as f:
            hashed = _Hashed(f)
            write(hashed if sequential else f)  # type: ignore[arg-type]
            f.flush()
            if sequential:
                digest, size = hashed.sha.hexdigest(), hashed.size
            else:
                f.seek(0)
                digest = hashlib.file_digest(f, "sha256").hexdigest()
                size = f.tell()
    except BaseException:
        os.close(fd)
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise
    return Written(fd, tmp, path, size, digest, overwrite)


@dataclass
class Written:
    """A file written by :func:`write_unsynced`: its open descriptor and temporary name, the
    name it goes to, and the size [bytes] and SHA-256 (hex) of its bytes."""

    fd: int
    tmp: Path
    path: Path
    size: int
    digest: str
    overwrite: bool = True

    def finish(self) -> None:
        """fsync the file, close it, rename it into place and fsync the directory. On any
        error the temporary file is removed."""
        try:
            try:
                os.fsync(self.fd)
                drop_cached(self.fd)
            finally:
                os.close(self.fd)
                self.fd = -1
            _put_in_place(self.tmp, self.path, self.overwrite)
        except BaseException:
            with contextlib.suppress(OSError):
                self.tmp.unlink(missing_ok=True)
            raise


class _Hashed:
    """The ``write`` of a binary file, hashing what passes."""

    def __init__(self, f: BinaryIO) -> None:
        self.f, self.sha, self.size = f, hashlib.sha256(), 0

    def write(self, data: bytes) -> int:
        self.sha.update(data)
        self.size += memoryview(data).nbytes
        return self.f.write(data)


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    return "not a regular file"


def not_regular(path: Path, *, follow_links: bool = True) -> str | None:
    """What ``path`` is if it is not a regular file ("a FIFO (named pipe)", "a device", ...);
    None if it is one or does not exist."""
    try:
        st = os.stat(path, follow_symlinks=follow_links)
    except (FileNotFoundError, NotADirectoryError):
        return None
    return None if stat.S_ISREG(st.st_mode) else _kind(st.st_mode)


def read_regular(path: Path, limit: int, *, follow_links: bool = True) -> bytes:
    """The bytes of the regular file ``path``.

    NotRegularFile (an OSError) for a FIFO, device, socket or directory (checked before and
    after opening, which never blocks), or for a link when not ``follow_links``; ValueError if
    the file holds more than ``limit`` bytes (only ``limit + 1`` are read).
    """
    try:
        st = os.stat(path, follow_symlinks=follow_links)
    except OSError:
        st = None  # let open() report it
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise NotRegularFile(errno.EINVAL, f"is {_kind(st.st_mode)}", str(path))
    flags = os.O_RDONLY | O_NONBLOCK | O_CLOEXEC | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags | (0 if follow_links else O_NOFOLLOW))
    except OSError as exc:
        if exc.errno == errno.ELOOP and not follow_links:
            raise NotRegularFile(errno.ELOOP, "is a symbolic link", str(path)) from None
        raise
    with os.fdopen(fd, "rb") as f:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise NotRegularFile(errno.EINVAL, f"is {_kind(mode)}", str(path))
        data = f.read(limit + 1)
    if len(data) > limit:
        raise ValueError(f"{path} is larger than {limit:,} bytes")
    return data

"""Files that appear under their name complete or not at all.

Every file conesurvey writes (a netCDF result, a block of a streamed run, the run's manifest)
goes through :func:`replacing`: it is written as ``NAME.tmp`` in the same directory, made
durable (fsync), renamed to ``NAME`` and the directory is fsynced so that the rename survives a
power cut. On any error, KeyboardInterrupt included, the ``.tmp`` file is removed and ``NAME``,
new or old, is untouched.

Renaming either replaces an existing ``NAME`` atomically (``os.replace``) or refuses to
(:func:`rename_no_clobber`: a hard link, which fails if ``NAME`` appeared meanwhile).

Policy for the directory fsync (:func:`fsync_dir`): skipped on Windows, where a directory cannot
be opened; elsewhere an error that means "this file system cannot fsync a directory"
(:data:`NOT_SUPPORTED`) is ignored and any other error (EIO, ...) is raised, since the rename
may then not be durable.
"""

from __future__ import annotations

import contextlib
import errno
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import BinaryIO

__all__ = [
    "NOT_SUPPORTED",
    "tmp_path",
    "fsync_path",
    "fsync_dir",
    "exists_error",
    "rename_no_clobber",
    "replacing",
    "write_atomic",
]

#: errno values of a directory fsync that mean "not supported here", not "the data is lost".
NOT_SUPPORTED = frozenset(
    {errno.EINVAL, errno.EBADF, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS}
)
#: Whether directories can be opened (and fsynced) on this operating system.
DIRECTORIES_OPEN = os.name != "nt"


def tmp_path(path: Path) -> Path:
    """Where ``path`` is written before it is renamed: ``path.tmp`` in the same directory."""
    return path.with_name(path.name + ".tmp")


def fsync_path(path: Path) -> None:
    """Flush the contents of the file ``path`` to the disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(directory: Path) -> None:
    """Make a rename in ``directory`` durable (see the module docstring for what is ignored)."""
    if not DIRECTORIES_OPEN:
        return
    try:
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
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
    except OSError:  # no hard links here
        if dst.exists():
            raise exists_error(dst) from None
        os.replace(src, dst)
        return
    os.unlink(src)


@contextlib.contextmanager
def replacing(path: Path, *, overwrite: bool = True) -> Iterator[Path]:
    """Yield ``path.tmp`` to be written and made durable (:func:`fsync_path`) by the caller;
    then rename it to ``path`` and fsync the directory.

    Without ``overwrite`` an existing ``path`` is never replaced (FileExistsError, checked
    before writing and again when renaming). A stale ``.tmp`` is removed first; on any error
    the ``.tmp`` is removed and ``path`` is untouched.
    """
    if not overwrite and path.exists():
        raise exists_error(path)
    tmp = tmp_path(path)
    try:
        tmp.unlink(missing_ok=True)  # left over by a crashed run
        yield tmp
        if overwrite:
            os.replace(tmp, path)
        else:
            rename_no_clobber(tmp, path)
        fsync_dir(path.parent)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise


def write_atomic(path: Path, write: Callable[[BinaryIO], None]) -> None:
    """Write ``path`` through :func:`replacing` with ``write(file)`` (binary), replacing it."""
    with replacing(path) as tmp, open(tmp, "wb") as f:
        write(f)
        f.flush()
        os.fsync(f.fileno())

"""engine.io.atomic: a file appears under its name complete or not at all."""

from __future__ import annotations

import errno
import hashlib
import os
import re

import pytest

from engine.io import atomic
from engine.io.atomic import fsync_dir, rename_no_clobber, replacing, write_atomic


def listing(directory):
    return sorted(p.name for p in directory.iterdir())


# --- rename -----------------------------------------------------------------------------------


def test_rename_no_clobber_moves_the_file(tmp_path):
    (tmp_path / "a.tmp").write_bytes(b"new")
    rename_no_clobber(tmp_path / "a.tmp", tmp_path / "a")
    assert (tmp_path / "a").read_bytes() == b"new"
    assert listing(tmp_path) == ["a"]


def test_rename_no_clobber_refuses_an_existing_target(tmp_path):
    (tmp_path / "a.tmp").write_bytes(b"new")
    (tmp_path / "a").write_bytes(b"precious")
    with pytest.raises(FileExistsError) as info:
        rename_no_clobber(tmp_path / "a.tmp", tmp_path / "a")
    assert info.value.errno == errno.EEXIST and str(tmp_path / "a") in str(info.value)
    assert (tmp_path / "a").read_bytes() == b"precious"
    assert (tmp_path / "a.tmp").read_bytes() == b"new"  # the caller decides what to do with it


@pytest.mark.parametrize("target_exists", [False, True])
def test_rename_no_clobber_without_hard_links(tmp_path, monkeypatch, target_exists):
    """File systems without hard links (FAT, some network mounts): checked, then replaced."""

    def no_links(src, dst):
        raise OSError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(os, "link", no_links)
    (tmp_path / "a.tmp").write_bytes(b"new")
    if target_exists:
        (tmp_path / "a").write_bytes(b"precious")
        with pytest.raises(FileExistsError):
            rename_no_clobber(tmp_path / "a.tmp", tmp_path / "a")
        assert (tmp_path / "a").read_bytes() == b"precious"
    else:
        rename_no_clobber(tmp_path / "a.tmp", tmp_path / "a")
        assert listing(tmp_path) == ["a"] and (tmp_path / "a").read_bytes() == b"new"


# --- replacing / write_atomic -----------------------------------------------------------------


TMP = re.compile(r"f\.[0-9a-f]{12}\.tmp")


def test_write_atomic_replaces_and_leaves_no_tmp(tmp_path):
    """A stale temporary file (of an old version, or of a live writer) is never reused nor
    removed: each writer creates its own name."""
    (tmp_path / "f").write_bytes(b"old")
    (tmp_path / "f.tmp").write_bytes(b"stale, left by a crash")
    size, digest = write_atomic(tmp_path / "f", lambda f: f.write(b"new"))
    assert (tmp_path / "f").read_bytes() == b"new"
    assert (size, digest) == (3, hashlib.sha256(b"new").hexdigest())
    assert listing(tmp_path) == ["f", "f.tmp"]
    assert (tmp_path / "f.tmp").read_bytes() == b"stale, left by a crash"


@pytest.mark.parametrize("error", [ValueError, KeyboardInterrupt])
def test_a_failed_write_leaves_no_tmp_and_the_old_file(tmp_path, error):
    (tmp_path / "f").write_bytes(b"old")

    def fail(f):
        f.write(b"half")
        raise error

    with pytest.raises(error):
        write_atomic(tmp_path / "f", fail)
    assert (tmp_path / "f").read_bytes() == b"old"
    assert listing(tmp_path) == ["f"]


def test_replacing_without_overwrite_refuses_before_writing(tmp_path):
    (tmp_path / "f").write_bytes(b"precious")
    body_ran = []
    with pytest.raises(FileExistsError), replacing(tmp_path / "f", overwrite=False):
        body_ran.append(True)
    assert not body_ran
    assert listing(tmp_path) == ["f"] and (tmp_path / "f").read_bytes() == b"precious"


def test_replacing_refuses_a_target_that_appeared_meanwhile(tmp_path):
    with pytest.raises(FileExistsError), replacing(tmp_path / "f", overwrite=False) as tmp:
        tmp.write_bytes(b"ours")
        (tmp_path / "f").write_bytes(b"theirs")
    assert listing(tmp_path) == ["f"] and (tmp_path / "f").read_bytes() == b"theirs"


def test_write_atomic_fsyncs_the_file_then_the_directory(tmp_path, monkeypatch):
    synced = []
    real_fsync = os.fsync

    def spy(fd):
        synced.append(os.readlink(f"/proc/self/fd/{fd}") if os.path.exists("/proc/self") else fd)
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", spy)
    write_atomic(tmp_path / "f", lambda f: f.write(b"x"))
    if os.path.exists("/proc/self"):
        assert len(synced) == 2 and synced[1] == str(tmp_path)
        assert TMP.fullmatch(os.path.basename(synced[0])), synced
        assert os.path.dirname(synced[0]) == str(tmp_path)
    else:
        assert len(synced) == 2


# --- fsync_dir --------------------------------------------------------------------------------


@pytest.mark.parametrize("code", sorted(atomic.NOT_SUPPORTED))
def test_fsync_dir_tolerates_a_file_system_that_cannot(tmp_path, monkeypatch, code):
    closed = []
    real_close = os.close

    def unsupported(fd):
        raise OSError(code, os.strerror(code))

    def spy_close(fd):
        closed.append(fd)
        real_close(fd)

    monkeypatch.setattr(os, "fsync", unsupported)
    monkeypatch.setattr(os, "close", spy_close)
    fsync_dir(tmp_path)
    assert len(closed) == 1  # the directory's descriptor is not leaked


def test_fsync_dir_tolerates_a_directory_that_cannot_be_opened(tmp_path, monkeypatch):
    def unsupported(path, flags, *args):
        raise OSError(errno.EINVAL, "Invalid argument")

    monkeypatch.setattr(os, "open", unsupported)
    fsync_dir(tmp_path)


def test_fsync_dir_is_skipped_where_directories_cannot_be_opened(tmp_path, monkeypatch):
    """Windows: opening a directory fails (EACCES), so it is not tried."""

    def refuse(path, flags, *args):
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(atomic, "DIRECTORIES_OPEN", False)
    monkeypatch.setattr(os, "open", refuse)
    fsync_dir(tmp_path)


@pytest.mark.parametrize("where", ["open", "fsync"])
def test_fsync_dir_reports_a_real_failure(tmp_path, monkeypatch, where):
    def broken(*args):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(os, where, broken)
    with pytest.raises(OSError) as info:
        fsync_dir(tmp_path)
    assert info.value.errno == errno.EIO


# --- written now, durable later (the block files of a run) -------------------------------------


def test_write_unsynced_is_not_in_place_until_finished(tmp_path, monkeypatch):
    written = atomic.write_unsynced(tmp_path / "a", lambda f: f.write(b"abc"), sequential=True)
    assert not (tmp_path / "a").exists() and written.tmp.read_bytes() == b"abc"
    assert (written.size, written.digest) == (3, hashlib.sha256(b"abc").hexdigest())
    calls = []
    real_fsync = os.fsync
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: calls.append("fsync") or real_fsync(fd))
    monkeypatch.setattr(
        atomic.os, "posix_fadvise", lambda fd, at, n, how: calls.append((at, n, how)), raising=False
    )
    written.finish()
    assert (tmp_path / "a").read_bytes() == b"abc" and listing(tmp_path) == ["a"]
    # the file reaches the disk, its cached pages are given back, then the rename is made durable
    assert calls == ["fsync", (0, 0, getattr(os, "POSIX_FADV_DONTNEED", 4)), "fsync"]


def test_a_failed_finish_leaves_no_tmp(tmp_path, monkeypatch):
    written = atomic.write_unsynced(tmp_path / "a", lambda f: f.write(b"abc"))

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.os, "fsync", full)
    with pytest.raises(OSError, match="No space"):
        written.finish()
    assert listing(tmp_path) == []

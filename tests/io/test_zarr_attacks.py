"""Attacks on the Zarr path: killed or out of space inside the final commit, a finished store's
per-array metadata edited, a verified chunk changed while the rerun computes, links, FIFOs and
devices planted in a store. Each either resumes to the uninterrupted store or is refused
without being followed, read without bound or blocking."""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import runs

from engine.cli import main
from engine.runner import RunFailed, run_survey
from engine.surveyfile import parse_survey

pytest.importorskip("zarr")

# 4 x 20 x 33 x 100 = 264,000 points in 8 blocks of one storage chunk
SURVEY = runs.gravity_survey("zarr attacks", energy=20)
BLOCK = 65536
ARGS = ("run", "s.toml", "-o", "out.zarr", "-q", "--block-points", str(BLOCK))


def cli(capsys, *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    status = main(list(args))
    out, err = capsys.readouterr()
    return status, out, err


def checksum(store: Path) -> str:
    return json.loads((store / "zarr.json").read_text())["attributes"]["content_checksum"]


class Stop(Exception):
    """Raised by a hook to stop a run in process, as a kill would (nothing is cleaned)."""


def stop_after(n: int):
    seen = []

    def hook(i: int) -> None:
        seen.append(i)
        if len(seen) >= n:
            raise Stop

    return hook


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    d = tmp_path_factory.mktemp("ref")
    run_survey(parse_survey(SURVEY), d / "ref.zarr", block_points=BLOCK)
    return d / "ref.zarr"


@pytest.fixture(scope="module")
def partial(tmp_path_factory):
    """An unfinished run: 3 of 8 blocks stored (the run stopped as a kill would)."""
    d = tmp_path_factory.mktemp("partial")
    with pytest.raises(Stop):
        run_survey(parse_survey(SURVEY), d / "out.zarr", block_points=BLOCK, on_block=stop_after(3))
    return d / "out.zarr.parts"


@pytest.fixture
def work(tmp_path, monkeypatch):
    (tmp_path / "s.toml").write_text(SURVEY)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def resumed(work: Path, capsys, reference: Path) -> None:
    """The same command finishes the run: the store equals the uninterrupted one."""
    status, _, err = cli(capsys, *ARGS)
    assert status == 0, err
    assert runs.listing(work) == ["out.zarr", "s.toml"]
    assert checksum(work / "out.zarr") == checksum(reference)
    status, out, _ = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 0 and "complete, verified" in out, out


# --- 1. the final commit: killed, or out of space, inside it -----------------------------------

KILL_AT = """
import os, signal, sys
import engine.io.zarr as z
from engine.cli import main
real = getattr(z, sys.argv[1])
def killed(*args, **kwargs):
    if sys.argv[1] == "put_in_place":  # the root is rewritten: killed before the rename
        os.kill(os.getpid(), signal.SIGKILL)
    real(*args, **kwargs)
    os.kill(os.getpid(), signal.SIGKILL)
setattr(z, sys.argv[1], killed)
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize("where", ["put_in_place"])
def test_killed_inside_the_commit_the_same_command_finishes(work, capsys, reference, where):
    """SIGKILL once the store's root metadata is final, before the rename (the run marker is
    gone): the same command finishes the run (the issue's attack 1)."""
    proc = subprocess.run(
        [sys.executable, "-c", KILL_AT, where, *ARGS], cwd=work, env=runs.env(),
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == -9, proc.stderr
    assert os.path.isdir(work / "out.zarr.parts") and not os.path.lexists(work / "out.zarr")
    resumed(work, capsys, reference)


FULL_AT_COMMIT = """
import errno, os, sys
import engine.io.zarr as z
from engine.cli import main
real = z.commit_store
def full(*args, **kwargs):  # the disk fills up just as the commit begins
    with open(sys.argv[1], "wb") as f:
        try:
            while True:
                f.write(b"x" * 65536)
                f.flush()
        except OSError as exc:
            assert exc.errno == errno.ENOSPC, exc
        f.truncate(max(0, f.tell() - 8192))  # room for a page or two, not for the commit
    return real(*args, **kwargs)
z.commit_store = full
sys.exit(main(sys.argv[2:]))
"""

SCRIPT = """
set -e
mount -t tmpfs -o size=32m tmpfs {mnt} || exit 97
cp {work}/s.toml {mnt}/
cd {mnt}
set +e
{python} -c '{hook}' {mnt}/filler {args} > {work}/first.out 2> {work}/first.err
echo $? > {work}/first.rc
ls -a {mnt}/out.zarr.parts > {work}/first.parts
rm {mnt}/filler
{python} -m engine.cli {args} > {work}/second.out 2> {work}/second.err; echo $? > {work}/second.rc
{python} -m engine.cli info out.zarr --verify > {work}/info.out 2>&1; echo $? >> {work}/second.rc
ls {mnt} > {work}/second.ls
cd /
umount {mnt}
"""


def test_out_of_space_inside_the_commit_the_same_command_finishes(work):
    """A real full tmpfs when the commit begins: exit 1, one line, resumable; the same command
    then finishes and the store verifies."""
    mnt = work / "mnt"
    mnt.mkdir()
    script = SCRIPT.format(
        mnt=mnt, work=work, python=sys.executable, hook=FULL_AT_COMMIT.replace("'", '"'),
        args=" ".join(ARGS),
    )  # fmt: skip
    unshare = ["unshare", "--mount"] if os.geteuid() == 0 else ["unshare", "-r", "--mount"]
    proc = subprocess.run(
        [*unshare, "sh", "-c", script], env=runs.env(), capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    names = ("first.rc", "first.err", "first.parts", "second.rc", "info.out", "second.ls")
    r = {n: (work / n).read_text() for n in names}
    assert r["first.rc"].strip() == "1", r
    err = r["first.err"]
    assert "No space left on device" in err and err.count("\n") == 1, err
    assert "the run is resumable" in err and "Traceback" not in err, err
    assert r["second.rc"].split() == ["0", "0"], r
    assert "complete, verified" in r["info.out"], r
    assert r["second.ls"].split() == ["out.zarr", "s.toml"], r


# --- 2. info --verify covers what a reader without consolidated metadata reads ----------------


def _endian(store: Path) -> None:
    p = store / "r_min" / "zarr.json"
    p.write_text(p.read_text().replace('"endian": "little"', '"endian": "big"'))


def _units(store: Path) -> None:
    p = store / "r_min" / "zarr.json"
    p.write_text(p.read_text().replace('"units": "m"', '"units": "km"'))


def _extra(store: Path) -> None:
    shutil.copytree(store / "r_min", store / "r_extra")


def _missing(store: Path) -> None:
    shutil.rmtree(store / "r_min")


def _no_meta(store: Path) -> None:
    (store / "r_min" / "zarr.json").unlink()


@pytest.mark.parametrize("edit", [_endian, _units, _extra, _missing, _no_meta])
def test_verify_covers_every_arrays_own_metadata(work, capsys, reference, edit):
    shutil.copytree(reference, work / "out.zarr")
    edit(work / "out.zarr")
    status, out, err = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 1 and "DAMAGED" in out and "verified" not in out.replace("DAMAGED", ""), (
        out + err
    )


# --- 3. a chunk of a verified block changed while the rerun computes -------------------------


def _saved_over(chunk: Path) -> None:
    """``chunk`` replaced as an editor saves: a new file, last byte changed, renamed over it
    (the run holds the old one: engine/io/hold.py)."""
    data = bytearray(chunk.read_bytes())
    data[-1] ^= 0xFF
    new = chunk.with_name(chunk.name + ".new")
    new.write_bytes(bytes(data))
    os.replace(new, chunk)


def test_a_verified_chunk_changed_during_the_rerun_is_caught(work, capsys, reference, partial):
    shutil.copytree(partial, work / "out.zarr.parts")
    chunk = next((work / "out.zarr.parts/store.zarr/period").glob("c.*"))

    done = []

    def flip(i: int) -> None:  # after the resume scan, while the missing blocks are computed
        if not done:
            _saved_over(chunk)
            done.append(i)

    with pytest.raises(RunFailed, match="changed since they were written"):
        run_survey(parse_survey(SURVEY), work / "out.zarr", block_points=BLOCK, on_block=flip)
    assert not (work / "out.zarr").exists()
    resumed(work, capsys, reference)


def test_a_chunk_this_run_wrote_and_then_changed_is_caught(work, capsys, reference):
    """A chunk of block 0, written by this very run, replaced (same size) while its last block
    is computed: the commit sees that its name no longer leads to the file it holds, hashes
    the new one and refuses; the next run recomputes the block."""
    flipped = []

    def flip(i: int) -> None:  # block 7's chunks are written: block 0's long before
        if i == 7:
            chunk = next((work / "out.zarr.parts/store.zarr/period").glob("c.*"))
            _saved_over(chunk)
            flipped.append(chunk)

    with pytest.raises(RunFailed, match="changed since they were written"):
        run_survey(parse_survey(SURVEY), work / "out.zarr", block_points=BLOCK, on_block=flip)
    assert flipped and not (work / "out.zarr").exists()
    resumed(work, capsys, reference)


def test_a_held_chunk_cannot_be_opened_for_writing_during_the_run(work, capsys, reference):
    """While the run holds a chunk file, opening it for writing without waiting is refused
    (EWOULDBLOCK) and the file is unchanged; the commit then checks that file again (its lease
    broke) and the store verifies."""
    import errno

    tried = []

    def poke(i: int) -> None:
        if i == 7:
            chunk = next((work / "out.zarr.parts/store.zarr/period").glob("c.*"))
            with pytest.raises(OSError) as exc:
                os.open(chunk, os.O_WRONLY | os.O_NONBLOCK)
            tried.append(exc.value.errno)

    run_survey(parse_survey(SURVEY), work / "out.zarr", block_points=BLOCK, on_block=poke)
    assert tried == [errno.EWOULDBLOCK]
    assert checksum(work / "out.zarr") == checksum(reference)
    status, out, _ = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 0 and "complete, verified" in out, out


def test_the_commit_reads_no_chunk_this_process_wrote_or_verified(work, partial, monkeypatch):
    """Resumed from 3 stored blocks: the scan reads those 3 once, the 5 blocks computed here
    were read back once written and are held; the commit reads no chunk file again."""
    from engine.io import zarrverify

    shutil.copytree(partial, work / "out.zarr.parts")
    real, read = zarrverify.block_digest, []

    def counted(store, keys, *args):
        read.append(keys[0])
        return real(store, keys, *args)

    monkeypatch.setattr(zarrverify, "block_digest", counted)
    run_survey(parse_survey(SURVEY), work / "out.zarr", block_points=BLOCK)
    assert len(read) == 3, read


def test_a_writer_sent_to_another_process_holds_nothing():
    """A dask worker's writer (pickled) holds no file and leaves its files in the cache: the
    commit hashes those blocks again (a worker's files are not this process's)."""
    import pickle

    from engine.io.hold import HeldFiles
    from engine.io.zarrlayout import ChunkWriter

    held = HeldFiles(4)
    writer = ChunkWriter("/s.zarr", "run", (2, 2), (1, 2), (("r_min", "<f8"),), 1, ".", held)
    sent = pickle.loads(pickle.dumps(writer))
    assert writer.held is held and sent.held is None
    assert (sent.root, sent.run_id, sent.shape, sent.chunk, sent.arrays, sent.complevel) == (
        "/s.zarr", "run", (2, 2), (1, 2), (("r_min", "<f8"),), 1,
    )  # fmt: skip
    assert sent.separator == "."


# --- 4. links, FIFOs and devices in a store -----------------------------------------------------


def test_a_symlinked_unfinished_store_is_never_followed(work, capsys, partial, tmp_path_factory):
    shutil.copytree(partial, work / "out.zarr.parts")
    elsewhere = tmp_path_factory.mktemp("elsewhere") / "store.zarr"
    (work / "out.zarr.parts/store.zarr").rename(elsewhere)
    (work / "out.zarr.parts/store.zarr").symlink_to(elsewhere)
    before = sorted(str(p) for p in elsewhere.rglob("*"))
    status, _, err = cli(capsys, *ARGS)
    assert status == 2 and "symbolic link" in err, err
    assert not os.path.lexists(work / "out.zarr")
    assert sorted(str(p) for p in elsewhere.rglob("*")) == before


def test_a_symlinked_array_metadata_is_replaced_never_followed(work, capsys, partial, reference):
    """The link is removed (not followed: the file it names is left as it was) and the array's
    metadata written again from the plan; the store equals the uninterrupted one."""
    shutil.copytree(partial, work / "out.zarr.parts")
    meta = work / "out.zarr.parts/store.zarr/r_min/zarr.json"
    (work / "planted.json").write_bytes(b'{"planted": true}')
    meta.unlink()
    meta.symlink_to(work / "planted.json")
    status, _, err = cli(capsys, *ARGS)
    assert status == 0 and "removed r_min/zarr.json" in err, err
    assert (work / "planted.json").read_bytes() == b'{"planted": true}'
    assert checksum(work / "out.zarr") == checksum(reference)


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))


def _fifo(p: Path) -> None:
    os.mkfifo(p)


def _dev_zero(p: Path) -> None:
    p.symlink_to("/dev/zero")


@pytest.mark.parametrize("plant", [_fifo, _dev_zero])
def test_info_never_follows_a_chunk_to_a_fifo_or_a_device(work, reference, plant):
    shutil.copytree(reference, work / "out.zarr")
    chunk = next((work / "out.zarr/orbit_class").glob("c.*"))
    chunk.unlink()
    plant(chunk)
    for args in (("info", "out.zarr"), ("info", "out.zarr", "--verify")):
        try:
            proc = subprocess.run(
                runs.cli(*args), cwd=work, env=runs.env(), capture_output=True, text=True,
                timeout=60, preexec_fn=_limited,
            )  # fmt: skip
        except subprocess.TimeoutExpired:
            pytest.fail(f"{' '.join(args)} blocked on a planted chunk")
        assert proc.returncode == 2, proc
        assert "refusing to read the store" in proc.stderr and "Traceback" not in proc.stderr

"""The Zarr commit against writers it cannot see coming: another process changes a chunk file of
the run (same size) where file stamps cannot show it, on a real file system, through a real
mapping, in a real race. Whatever the attacker does, the run never ends ``complete`` (exit 0)
with a store that ``info --verify`` calls DAMAGED: either the change is kept out (the run holds
its files: engine/io/hold.py) or it is caught (exit 1, and the same command then finishes).

1. coarse clock ticks: a loop-mounted ext2 image with 128-byte inodes (whole-second times) in
   a private mount namespace; a writer acts right after each of three blocks is stored;
2. a write through a shared writable mapping whose page is already dirty (no time changes),
   on the disk the tests run on, against a block a resume verified;
3. a change after the run wrote a chunk file and before it checked it: at the rename of the
   file, and (inside the run's own check) between the write and the lease.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest
import runs

from engine.cli import main
from engine.runner import RunFailed, run_survey
from engine.surveyfile import parse_survey

pytest.importorskip("zarr")

# 4 x 20 x 33 x 100 = 264,000 points in 8 blocks of one storage chunk
SURVEY = runs.gravity_survey("zarr commit attacks", energy=20)
BLOCK = 65536
ARGS = ("run", "s.toml", "-o", "out.zarr", "-q", "--block-points", str(BLOCK))

#: The attacker: another process that changes the last byte of each file it is given (same
#: size), opening it without waiting for a lease. With "silent", a change whose file times did
#: not move is kept and any other put back (a stamp would show it); with "keep", every change
#: is kept. A JSON tally (added to what is there) goes to argv[1].
ATTACKER = """
import errno, json, os, sys
tally = {"refused": 0, "silent": 0, "seen": 0}
for path in sys.argv[3:]:
    before = os.stat(path)
    try:
        fd = os.open(path, os.O_RDWR | os.O_NONBLOCK)
    except OSError as exc:
        if exc.errno not in (errno.EAGAIN, errno.EWOULDBLOCK):
            raise
        tally["refused"] += 1
        continue
    try:
        size = os.fstat(fd).st_size
        last = os.pread(fd, 1, size - 1)
        os.pwrite(fd, bytes([last[0] ^ 0xFF]), size - 1)
        after = os.fstat(fd)
        if (after.st_mtime_ns, after.st_ctime_ns) == (before.st_mtime_ns, before.st_ctime_ns):
            tally["silent"] += 1
        elif sys.argv[2] == "keep":
            tally["seen"] += 1
        else:
            os.pwrite(fd, last, size - 1)
            tally["seen"] += 1
    finally:
        os.close(fd)
old = json.load(open(sys.argv[1])) if os.path.exists(sys.argv[1]) else {}
json.dump({k: v + old.get(k, 0) for k, v in tally.items()}, open(sys.argv[1], "w"))
"""

#: The run, with the attacker started (and awaited) right after blocks 1, 3 and 5 are written
#: into the store, on that block's chunk files.
AFTER_WRITE = """
import subprocess, sys
import engine.io.zarrlayout as zl
from engine.cli import main
from engine.io.zarrchunks import chunk_keys
attacker, tally = sys.argv[1], sys.argv[2]
real = zl.ChunkWriter.write
def write(self, index, slab, values):
    receipt = real(self, index, slab, values)
    if index in (1, 3, 5):
        keys = [k for n, _ in self.arrays for k in chunk_keys(n, slab, self.chunk, self.separator)]
        where = [self.root + "/" + k for k in keys]
        subprocess.run([sys.executable, attacker, tally, "silent", *where], check=True)
    return receipt
zl.ChunkWriter.write = write
sys.exit(main(sys.argv[3:]))
"""


def cli(capsys, *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    status = main(list(args))
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture
def work(tmp_path, monkeypatch):
    (tmp_path / "s.toml").write_text(SURVEY)
    (tmp_path / "attacker.py").write_text(ATTACKER)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def never_silently_wrong(rc: int, err: str, verify: str) -> None:
    """Exit 0 only with a store that verifies; otherwise exit 1, one line, resumable."""
    if rc == 0:
        assert "complete, verified" in verify, f"the run ended complete; info: {verify}"
    else:
        assert rc == 1 and err.count("\n") == 1 and "Traceback" not in err, err
        assert "the run is resumable" in err, err


# --- 1. coarse clock ticks: ext2 on a loop device ---------------------------------------------

EXT2 = """
set -u
mount -o loop {img} {mnt} || exit 97
cp {work}/s.toml {mnt}/
cd {mnt}
{python} -c '{hook}' {work}/attacker.py {work}/tally.json {args} > {work}/run.out 2> {work}/run.err
echo $? > {work}/run.rc
{python} -m engine.cli info out.zarr --verify > {work}/info.out 2>&1
{python} -m engine.cli {args} > {work}/again.out 2> {work}/again.err; echo $? > {work}/again.rc
{python} -m engine.cli info out.zarr --verify > {work}/again.info 2>&1
cd /
umount {mnt}
"""


def test_a_write_in_the_same_clock_tick_on_ext2_never_ends_complete_and_damaged(work):
    """ext2 with 128-byte inodes keeps whole seconds: a same-size write right after the run
    stored a block leaves its modification and change times as they were (the attacker keeps
    only such writes). The run either kept the attacker out or caught the change."""
    assert shutil.which("mke2fs") and shutil.which("unshare"), "needs e2fsprogs and util-linux"
    assert os.geteuid() == 0, "a loop device in a private mount namespace needs root"
    img, mnt = work / "ext2.img", work / "mnt"
    mnt.mkdir()
    with open(img, "wb") as f:
        f.truncate(64 << 20)
    subprocess.run(["mke2fs", "-q", "-F", "-t", "ext2", "-I", "128", str(img)], check=True,
                   capture_output=True)  # fmt: skip
    script = EXT2.format(img=img, mnt=mnt, work=work, python=sys.executable,
                         hook=AFTER_WRITE.replace("'", '"'), args=" ".join(ARGS))  # fmt: skip
    proc = subprocess.run(["unshare", "--mount", "sh", "-c", script], env=runs.env(),
                          capture_output=True, text=True, timeout=600)  # fmt: skip
    assert proc.returncode != 97, f"cannot mount a loop device here: {proc.stderr}"
    tally = json.loads((work / "tally.json").read_text())
    assert sum(tally.values()) == 21, tally  # 3 blocks x 7 variables, one chunk file each
    rc = int((work / "run.rc").read_text())
    never_silently_wrong(rc, (work / "run.err").read_text(), (work / "info.out").read_text())
    assert int((work / "again.rc").read_text()) == 0, (work / "again.err").read_text()
    assert "complete, verified" in (work / "again.info").read_text()


# --- 2. a write through a mapping whose page is already dirty ---------------------------------

MAPPER = """
import mmap, os, sys
fd = os.open(sys.argv[1], os.O_RDWR)
m = mmap.mmap(fd, os.fstat(fd).st_size)
os.close(fd)
m[-1] = m[-1]  # the last page is dirty now (its times move once), its bytes unchanged
print("mapped", flush=True)
sys.stdin.readline()
m[-1] ^= 0xFF  # an already dirty page: no page fault, no time moves
print("changed", flush=True)
sys.stdin.readline()
"""


@pytest.fixture(scope="module")
def partial(tmp_path_factory):
    """An unfinished run: 3 of 8 blocks stored (stopped as a kill would)."""
    d = tmp_path_factory.mktemp("partial")

    class Stop(Exception):
        pass

    def stop(i: int) -> None:
        if i >= 2:
            raise Stop

    with pytest.raises(Stop):
        run_survey(parse_survey(SURVEY), d / "out.zarr", block_points=BLOCK, on_block=stop)
    return d / "out.zarr.parts"


def test_a_write_through_a_dirty_mapping_during_a_resume(work, capsys, partial):
    """Another process maps a chunk file of a stored block and dirties its page (same bytes)
    before the resume; once the resume has verified the block, it changes a byte through the
    mapping, which moves no file time. The store the run commits verifies."""
    shutil.copytree(partial, work / "out.zarr.parts")
    chunk = next((work / "out.zarr.parts/store.zarr/period").glob("c.*"))
    mapper = subprocess.Popen([sys.executable, "-c", MAPPER, str(chunk)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)  # fmt: skip
    try:
        assert mapper.stdout.readline().strip() == "mapped"
        changed = []

        def after_scan(i: int) -> None:  # the first block this run stores: the scan is done
            if not changed:
                mapper.stdin.write("go\n")
                mapper.stdin.flush()
                changed.append(mapper.stdout.readline().strip())

        try:
            run_survey(parse_survey(SURVEY), work / "out.zarr", block_points=BLOCK,
                       on_block=after_scan)  # fmt: skip
        except RunFailed as exc:  # caught: the same command finishes
            assert "changed since they were written" in str(exc), exc
            assert cli(capsys, *ARGS)[0] == 0
        assert changed == ["changed"]
    finally:
        mapper.stdin.close()
        mapper.wait(timeout=60)
    status, out, _ = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 0 and "complete, verified" in out, out


# --- 3. a change between the write and the check ------------------------------------------------

AT_RENAME = """
import os, subprocess, sys
from engine.cli import main
attacker, tally = sys.argv[1], sys.argv[2]
real = os.rename
def rename(src, dst, *, src_dir_fd=None, dst_dir_fd=None):
    if src_dir_fd is not None and "/period" in os.readlink(f"/proc/self/fd/{src_dir_fd}"):
        where = os.readlink(f"/proc/self/fd/{src_dir_fd}") + "/" + src
        subprocess.run([sys.executable, attacker, tally, "keep", where], check=True)
    return real(src, dst, src_dir_fd=src_dir_fd, dst_dir_fd=dst_dir_fd)
os.rename = rename
sys.exit(main(sys.argv[3:]))
"""


def test_a_change_after_the_write_and_before_the_rename(work):
    """Each period chunk file, written and fsynced under its temporary name, is changed by
    another process just before the run renames it into place (a stamp taken after the rename
    would include the change)."""
    proc = subprocess.run(
        [sys.executable, "-c", AT_RENAME, str(work / "attacker.py"), str(work / "tally.json"),
         *ARGS], cwd=work, env=runs.env(), capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    tally = json.loads((work / "tally.json").read_text())
    assert sum(tally.values()) == 8, tally  # one period chunk file per block
    info = subprocess.run(runs.cli("info", "out.zarr", "--verify"), cwd=work, env=runs.env(),
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    never_silently_wrong(proc.returncode, proc.stderr, info.stdout)


BEFORE_LEASE = """
import subprocess, sys
import engine.io.hold as hold
from engine.cli import main
real, done = hold._lease, []
def lease(fd):
    if not done:  # the first file held: changed by another process just before the lease
        done.append(1)
        path = f"/proc/{__import__('os').getpid()}/fd/{fd}"
        subprocess.run([sys.executable, "-c", "import sys; f = open(sys.argv[1], 'r+b'); "
                        "f.seek(-1, 2); b = f.read(1); f.seek(-1, 2); f.write(bytes([b[0] ^ 255]))",
                        path], check=True)
    return real(fd)
hold._lease = lease
sys.exit(main(sys.argv[1:]))
"""


def test_a_change_between_the_write_and_the_lease_is_caught(work, capsys):
    """The window the run's own check leaves: the file is written and closed, and changed by
    another process before its lease is taken. Reading it back after the lease catches it:
    exit 1, one line; the same command then finishes and the store verifies."""
    proc = subprocess.run([sys.executable, "-c", BEFORE_LEASE, *ARGS], cwd=work, env=runs.env(),
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    err = proc.stderr
    assert "changed while it was written" in err and err.count("\n") == 1, err
    assert not os.path.lexists(work / "out.zarr")
    status, _, err = cli(capsys, *ARGS)
    assert status == 0, err
    status, out, _ = cli(capsys, "info", "out.zarr", "--verify")
    assert status == 0 and "complete, verified" in out, out

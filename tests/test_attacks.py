"""The attacks of issue 11 on streamed runs: the runs that are killed, raced or attacked while
they run are the real command in subprocesses; the runs that finish afterwards, and the
reference, run the command (or the API) in this process (no interpreter start).

Every test ends with one of two outcomes: the final file equals an uninterrupted run (values,
NaN bit patterns, attributes except history), or the run was refused with exit status 2 and
wrote nothing. Disk-full and dask failures: tests/test_enospc.py and tests/test_dask.py.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
import runs

from engine.io import manifest as io_manifest
from engine.io.blocks import BlockStore
from engine.io.chunkfile import StoredBlock, write_block
from engine.io.deflate import compress_pool
from engine.runner import run_survey
from engine.surveyfile import parse_survey

# 4 x 50 x 33 x 100 = 660,000 points in 16 blocks of one storage chunk (42,500 points) each
SURVEY = runs.gravity_survey("attack test", energy=50)
BLOCK = "65536"
ARGS = ("run", "s.toml", "-o", "out.nc", "-q", "--block-points", BLOCK)
#: A command that imports everything, says "ready", and runs when a line arrives on stdin: its
#: lock attempt then comes within milliseconds of the trigger.
READY = (
    "import sys, engine.cli as c; print('ready', flush=True); sys.stdin.readline(); "
    "sys.exit(c.main(sys.argv[1:]))"
)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref") / "out.nc"
    run_survey(parse_survey(SURVEY), out, block_points=int(BLOCK))
    return out


@pytest.fixture
def work(tmp_path):
    (tmp_path / "s.toml").write_text(SURVEY)
    return tmp_path


def parts(work: Path) -> Path:
    return work / "out.nc.parts"


def tree(root: Path) -> dict[str, tuple]:
    """Every path under ``root`` with its type, size, content hash and mtime (a refused run
    must leave all of it as it was)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            st = os.lstat(p)
            data = p.read_bytes() if p.is_file() and not p.is_symlink() else b""
            link = os.readlink(p) if p.is_symlink() else ""
            key = str(p.relative_to(root))
            out[key] = (st.st_mode, len(data), hash(data), st.st_mtime_ns, link)
    return out


def ready_run(work: Path, *args: str) -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-c", READY, *args],
        cwd=work,
        env=runs.env(),
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline().strip() == "ready"
    return proc


def go(proc: subprocess.Popen) -> None:
    proc.stdin.write("\n")
    proc.stdin.flush()


def finish(proc: subprocess.Popen) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=600)
    return proc.returncode, out, err


def killed_after(work: Path, blocks: int) -> int:
    """Run, SIGKILL it once ``blocks`` blocks are stored; the number stored."""
    proc = subprocess.Popen(runs.cli(*ARGS), cwd=work, env=runs.env(), stderr=subprocess.PIPE)
    assert runs.kill_when(proc, lambda: runs.blocks_in(parts(work)) >= blocks), "finished first"
    return runs.blocks_in(parts(work))


def assert_refused_and_untouched(work: Path, capsys, *args: str) -> str:
    """The run exits 2 with one line and changes nothing, except that the lock file a killed
    run left (debris: its flock died with it) is gone, as every run that ends removes it."""
    before = tree(work)
    proc = runs.here(work, capsys, *args)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("conesurvey: error: ") and proc.stderr.count("\n") == 1
    assert "Traceback" not in proc.stderr
    stale_lock_kept = before.get("out.nc.lock", (0,))[0] and os.path.islink(work / "out.nc.lock")
    if not stale_lock_kept:
        before.pop("out.nc.lock", None)
    assert tree(work) == before
    return proc.stderr


def finish_and_compare(work: Path, reference: Path, capsys, *extra: str, kept=()) -> str:
    proc = runs.here(work, capsys, *ARGS, *extra)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    if kept:  # files that are not the run's are left alone, with the directory
        assert sorted(os.listdir(parts(work))) == sorted(kept)
        shutil.rmtree(parts(work))
    assert runs.listing(work) == ["out.nc", "s.toml"]
    runs.same_content(work / "out.nc", reference)
    verified = runs.here(work, capsys, "info", "out.nc", "--verify")
    assert verified.returncode == 0 and "complete, verified" in verified.stdout, verified.stdout
    return proc.stderr


# --- 1. two runs of one output ------------------------------------------------------------------


def test_two_runs_started_together_one_wins(work, reference):
    """The issue's first attack: both runs used one OUT.nc.tmp, and 3 of 19 trials published
    the other run's half-written file. Now exactly one computes; the other is refused naming
    it (or, if it looks after the winner finished, finds nothing to do)."""
    a, b = ready_run(work, *ARGS), ready_run(work, *ARGS)
    go(a)
    go(b)
    results = [finish(a), finish(b)]
    codes = sorted(code for code, _, _ in results)
    assert codes in ([0, 0], [0, 2]), results
    for code, _, err in results:
        assert "Traceback" not in err
        if code == 2:
            other = a.pid if b.returncode == 2 else b.pid
            assert f"another run is writing out.nc (pid {other} on host " in err
    assert runs.listing(work) == ["out.nc", "s.toml"]
    runs.same_content(work / "out.nc", reference)


def test_a_second_run_is_refused_at_every_stage_of_the_first(work, reference, capsys):
    """Started at the first block, half way and during the merge, the second run is refused
    with the holder's pid, host and start time, and writes nothing."""
    waiting = [ready_run(work, *ARGS) for _ in range(3)]  # imported, waiting for a line
    a = subprocess.Popen(runs.cli(*ARGS), cwd=work, env=runs.env(), stderr=subprocess.PIPE)
    stages = [
        lambda: runs.blocks_in(parts(work)) >= 1,
        lambda: runs.blocks_in(parts(work)) >= 8,
        lambda: any(n.startswith("out.nc.") for n in os.listdir(parts(work))),  # merging
    ]
    fired = []
    deadline = time.monotonic() + 600
    for proc, stage in zip(waiting, stages, strict=True):
        while a.poll() is None and time.monotonic() < deadline:
            try:
                if stage():
                    break
            except FileNotFoundError:
                pass
            time.sleep(0.002)
        go(proc)
        fired.append(a.poll() is None)
        if len(fired) == 1:  # info names the run in progress (and does not disturb it)
            shown = runs.here(work, capsys, "info", "out.nc")
            if a.poll() is None:
                assert f"a run is writing it now (pid {a.pid} on host " in shown.stdout
    results = [finish(p) for p in waiting]
    assert a.wait(timeout=600) == 0
    assert fired == [True, True, True], "the first run ended before a stage was reached"
    for code, out, err in results:
        assert code == 2, (code, out, err)
        assert f"another run is writing out.nc (pid {a.pid} on host " in err
        assert ", started 20" in err and err.count("\n") == 1
    assert runs.listing(work) == ["out.nc", "s.toml"]
    runs.same_content(work / "out.nc", reference)


# --- 2. blocks changed behind the run's back ----------------------------------------------------


def _block(work: Path, i: int) -> Path:
    return parts(work) / f"b{i:08d}.chunks"  # the default output is deflated: chunk blocks


def test_swapped_edited_truncated_and_stray_blocks_after_a_kill(work, reference, capsys):
    assert killed_after(work, 8) >= 8
    b = [_block(work, i).read_bytes() for i in range(6)]
    _block(work, 0).write_bytes(b[1])  # a block copied over another
    _block(work, 1).write_bytes(b[0])  # (a swap)
    _block(work, 2).write_bytes(b[2][: len(b[2]) // 2])  # truncated
    store = BlockStore.open(parts(work))  # edited values, a valid file
    edited = store.decode(3, _block(work, 3).read_bytes())
    edited["r_min"][...] = 1.0
    chunks = store.codec.encode(store.tiling.slices(3), store.tiling.chunk, edited, compress_pool())
    with open(_block(work, 3), "wb") as f:
        write_block(f, StoredBlock(edited, chunks, store.codec))
    data = bytearray(b[4])
    data[len(data) // 2] ^= 0x04  # one flipped bit
    _block(work, 4).write_bytes(bytes(data))
    (parts(work) / "b-0000001.npz").write_bytes(b[5])  # a stray name (the IndexError)
    err = finish_and_compare(work, reference, capsys, kept=["b-0000001.npz"])
    for i in range(5):
        assert f"block file b{i:08d}.chunks is corrupt" in err, err
    assert "ignoring files that are not blocks of this run" in err and "b-0000001.npz" in err
    assert "survey" not in err.split("ignoring")[1].split("\n")[0]  # not blamed on the survey
    assert "left out.nc.parts with the files you put there: b-0000001.npz" in err


MANIFEST_EDITS = [
    (lambda d: d.update(shape=[4, 50, 33, 99]), False, "checksum does not match"),
    (lambda d: d.update(block=[0, 0, 0, 0]), True, "block must be 4 positive integers"),
    (lambda d: d.update(shape=[4, 50, 33, 99]), True, "is not the survey's"),
    (lambda d: d.update(chunk=[8, 25, 17, 25]), True, "exceeds the grid"),
    (lambda d: d.update(fingerprint="0" * 64), True, "another survey"),
]


def test_an_edited_manifest_is_refused_without_writing(work, reference, capsys):
    """The issue: a changed shape was accepted and block = [0,0,0,0] raised ZeroDivisionError.
    Hand edits fail the manifest's own checksum; consistent forgeries fail its validation as
    data or the comparison with the survey. Each run refuses (exit 2, nothing written), info
    says why; --overwrite starts over."""
    killed_after(work, 3)
    saved = work.parent / (work.name + "-saved")
    shutil.copytree(parts(work), saved, symlinks=True)
    for edit, recheck, why in MANIFEST_EDITS:
        shutil.rmtree(parts(work))
        shutil.copytree(saved, parts(work), symlinks=True)
        path = parts(work) / "manifest.json"
        doc = json.loads(path.read_text())
        edit(doc)
        if recheck:
            doc["check"] = io_manifest._self_check(doc)
        path.write_text(json.dumps(doc))
        err = assert_refused_and_untouched(work, capsys, *ARGS)
        assert why in err and "--overwrite" in err and "ZeroDivision" not in err, err
        info = runs.here(work, capsys, "info", "out.nc")
        assert info.returncode == 0
        assert "cannot be resumed" in info.stdout or why == "another survey", info.stdout
    finish_and_compare(work, reference, capsys, "--overwrite")


# --- 3. planted links ---------------------------------------------------------------------------


def test_a_parts_directory_that_is_a_link_is_refused(work, capsys):
    elsewhere = work / "elsewhere"
    elsewhere.mkdir()
    (work / "out.nc.parts").symlink_to(elsewhere)
    err = assert_refused_and_untouched(work, capsys, *ARGS)
    assert "out.nc.parts is a symbolic link; refusing to use it" in err
    assert os.listdir(elsewhere) == []


def test_a_lock_file_that_is_a_link_is_refused(work, capsys):
    victim = work / "victim"
    victim.write_text("precious")
    (work / "out.nc.lock").symlink_to(victim)
    err = assert_refused_and_untouched(work, capsys, *ARGS)
    assert "out.nc.lock is a symbolic link" in err
    assert victim.read_text() == "precious"


def test_links_planted_in_the_parts_directory_are_never_followed(work, reference, capsys):
    """Links at the old fixed temporary names and at a block's own name: their targets keep
    their contents; the link in a block's place is reported, removed and recomputed."""
    killed_after(work, 6)
    victim = work / "victim"
    victim.write_text("precious")
    for name in ("manifest.json.tmp", "b00000003.chunks.tmp", "b00000007.npz.tmp", "journal.tmp"):
        (parts(work) / name).symlink_to(victim)
    good = work / "copy.npz"
    original = _block(work, 2).read_bytes()
    good.write_bytes(original)
    _block(work, 2).unlink()
    _block(work, 2).symlink_to(good)  # same bytes, but a link
    (work / "out.nc.tmp").symlink_to(victim)  # the output's old temporary name
    proc = runs.here(work, capsys, *ARGS)
    assert proc.returncode == 0, proc.stderr
    assert "block file b00000002.chunks is corrupt (not a regular file" in proc.stderr
    assert victim.read_text() == "precious"
    assert good.read_bytes() == original  # the link's target is untouched
    assert runs.listing(work) == ["copy.npz", "out.nc", "out.nc.tmp", "s.toml", "victim"]
    runs.same_content(work / "out.nc", reference)


# --- 4. debris ----------------------------------------------------------------------------------


def test_leftover_blocks_of_a_finished_run_are_removed(work, reference, capsys):
    """A SIGKILL during the removal of OUT.parts (the manifest goes first) or just before it
    began: the next run (nothing to do) or info recognises the debris and removes it."""
    killed_after(work, 4)
    saved = work.parent / (work.name + "-saved")
    parts(work).rename(saved)
    assert runs.here(work, capsys, *ARGS).returncode == 0
    for manifest in (False, True):
        for who in ("run", "info"):
            shutil.copytree(saved, parts(work), symlinks=True)
            if not manifest:
                (parts(work) / "manifest.json").unlink()
            args = ARGS if who == "run" else ("info", "out.nc")
            proc = runs.here(work, capsys, *args)
            assert proc.returncode == 0, proc.stderr
            text = proc.stdout + proc.stderr
            assert "removed" in text and "out.nc.parts" in text, (manifest, who, text)
            assert runs.listing(work) == ["out.nc", "s.toml"]
    runs.same_content(work / "out.nc", reference)


def test_a_parts_directory_without_manifest_is_started_over(work, reference, capsys):
    """A run killed before its manifest was written (or whose manifest went first in a killed
    cleanup, output since deleted): nothing in it can be verified, so it is removed."""
    killed_after(work, 4)
    (parts(work) / "manifest.json").unlink()
    info = runs.here(work, capsys, "info", "out.nc")
    assert info.returncode == 0 and "the next run removes it and starts over" in info.stdout
    err = finish_and_compare(work, reference, capsys)
    assert "has no manifest" in err

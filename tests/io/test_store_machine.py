"""A hypothesis state machine of the block store: random interleavings of writes, kills (left
temporary files, torn writes, a block renamed but not journaled, a torn journal line, a killed
merge), corruptions (flipped bits, truncation, swaps, copies, links, deletions, strays, bogus
journal lines, a damaged output), resumes and merges never produce a file that ``info
--verify`` (:func:`engine.io.netcdf.read_info` with ``verify``) calls complete and verified and
that differs from the reference; and every block a resume verifies is the right one.
"""

from __future__ import annotations

import functools
import hashlib
import os
import secrets
import shutil
import tempfile
from pathlib import Path

import netCDF4
import numpy as np
import runs
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from engine.backends import compute_block
from engine.grid import Tiling
from engine.io import OutputError, netcdf
from engine.io.blocks import BlockStore
from engine.io.journal import JOURNAL, journal_line
from engine.io.manifest import Manifest, fingerprint, parts_dir
from engine.plan import plan_from_survey
from engine.surveyfile import parse_survey

SURVEY = parse_survey(runs.free_fall_survey("store machine", energy=5, lz=(-0.5, 0.2, 0.5)))
TILING = Tiling(SURVEY.shape, (1, 1, 2, 3), (1, 1, 2, 3))  # 60 points in 10 blocks
N = TILING.nblocks
_SPEC = plan_from_survey(SURVEY)
FP = fingerprint(_SPEC)
MANIFEST = Manifest.new(_SPEC, TILING)


def _ref_blocks() -> list:
    blocks = [compute_block(_SPEC, TILING, i)[1] for i in range(N)]
    assert len({b["r_min"].tobytes() for b in blocks}) > N // 2  # blocks differ
    return blocks


#: Computed on first use (runs.Computed: not while both xdist workers collect this file).
REF_BLOCKS = runs.Computed(_ref_blocks)


@functools.cache
def _reference_file() -> tuple[bytes, dict]:
    """The bytes and the contents of the reference output (its directory removed at once: a
    module-level temporary directory would outlive the test run). Made on first use, not
    while both xdist workers collect this file."""
    d = Path(tempfile.mkdtemp(prefix="store-machine-ref-"))
    try:
        store = BlockStore.create(parts_dir(d / "ref.nc"), MANIFEST)
        for i in range(N):
            store.commit(i, REF_BLOCKS[i])
        netcdf.merge(store, _SPEC, d / "ref.nc", fingerprint=FP)
        return (d / "ref.nc").read_bytes(), _contents(d / "ref.nc")
    finally:
        shutil.rmtree(d, ignore_errors=True)


def _contents(path: Path) -> dict:
    """Values (raw, NaN bits included) and attributes, except the global history."""
    with netCDF4.Dataset(path) as nc:
        nc.set_auto_maskandscale(False)
        out = {k: repr(nc.getncattr(k)) for k in nc.ncattrs() if k != "history"}
        for name, v in nc.variables.items():
            out[name] = (
                np.asarray(v[...]).tobytes(),
                repr({k: v.getncattr(k) for k in v.ncattrs()}),
            )
    return out


class StoreMachine(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.dir = Path(tempfile.mkdtemp(prefix="store-machine-"))
        self.out = self.dir / "out.nc"
        self.root = parts_dir(self.out)
        self.store = BlockStore.create(self.root, MANIFEST)
        self.checked: tuple | None = None
        self.verified_files = 0

    def teardown(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)

    def block(self, i: int) -> Path:
        return self.store.path(i)

    # -- writes and kills --

    @rule(i=st.integers(0, N - 1))
    def write(self, i: int) -> None:
        self.store.commit(i, REF_BLOCKS[i])

    @rule(
        i=st.integers(0, N - 1),
        how=st.sampled_from(["tmp", "torn tmp", "unjournaled", "torn line"]),
    )
    def kill_during_a_write(self, i: int, how: str) -> None:
        """What SIGKILL leaves at each step of a commit."""
        scratch = self.dir / "scratch.npz"
        with open(scratch, "wb") as f:
            np.savez(f, **REF_BLOCKS[i])
        data = scratch.read_bytes()
        scratch.unlink()
        tmp = self.root / f"{self.block(i).name}.{secrets.token_hex(6)}.tmp"
        if how == "tmp":
            tmp.write_bytes(data)
        elif how == "torn tmp":
            tmp.write_bytes(data[: len(data) // 3])
        elif how == "unjournaled":
            self.block(i).write_bytes(data)  # renamed into place, the journal line not written
        else:
            line = journal_line(i, len(data), hashlib.sha256(data).hexdigest())
            with open(self.root / JOURNAL, "ab") as f:
                f.write(line[: len(line) // 2])

    @rule()
    def kill_during_the_merge(self) -> None:
        """A killed merge leaves its temporary netCDF file in the store."""
        data = _reference_file()[0]
        (self.root / f"out.nc.{secrets.token_hex(6)}.tmp").write_bytes(data[: len(data) // 2])

    # -- corruption behind the store's back --

    @rule(
        i=st.integers(0, N - 1),
        j=st.integers(0, N - 1),
        how=st.sampled_from(
            ["flip", "truncate", "swap", "copy", "link", "delete", "stray", "bogus line"]
        ),
        where=st.floats(0.0, 1.0),
    )
    def corrupt(self, i: int, j: int, how: str, where: float) -> None:
        p, q = self.block(i), self.block(j)
        if how == "stray":
            (self.root / "b-0000001.npz").write_bytes(b"stray")
            return
        if how == "bogus line":
            with open(self.root / JOURNAL, "ab") as f:
                f.write(journal_line(i, 1234, "ab" * 32))
            return
        if not p.is_file() or p.is_symlink():
            return
        data = p.read_bytes()
        if how == "flip":
            b = bytearray(data)
            b[min(int(where * len(b)), len(b) - 1)] ^= 1 << (i % 8)
            p.write_bytes(bytes(b))
        elif how == "truncate":
            p.write_bytes(data[: int(where * len(data))])
        elif how == "delete":
            p.unlink()
        elif how in ("swap", "copy") and q.is_file() and not q.is_symlink():
            other = q.read_bytes()
            p.write_bytes(other)
            if how == "swap":
                q.write_bytes(data)
        elif how == "link" and q.exists():
            target = self.dir / f"target-{j}.npz"
            target.write_bytes(q.read_bytes())
            p.unlink()
            p.symlink_to(target)

    @precondition(lambda self: self.out.exists())
    @rule(where=st.floats(0.0, 1.0), bit=st.integers(0, 7))
    def damage_the_output(self, where: float, bit: int) -> None:
        b = bytearray(self.out.read_bytes())
        b[min(int(where * len(b)), len(b) - 1)] ^= 1 << bit
        self.out.write_bytes(bytes(b))

    # -- what a run does --

    @rule()
    def resume(self) -> None:
        store = BlockStore.open(self.root)
        found = store.scan()
        for i in found.good:  # a verified block is the right block
            loaded = store.load(i)
            for name, ref in REF_BLOCKS[i].items():
                assert loaded[name].tobytes() == ref.tobytes(), (i, name)
        store.discard(found)
        self.store = store

    @rule()
    def merge(self) -> None:
        try:
            netcdf.merge(self.store, _SPEC, self.out, fingerprint=FP, overwrite=True)
        except OutputError:
            pass  # a block missing or changed: refused (and that block deleted)

    @rule()
    def run_to_the_end(self) -> None:
        """What a rerun of the command does: resume, compute what is missing, merge."""
        self.resume()
        for i in sorted(set(range(N)) - self.store.scan().good):
            self.store.commit(i, REF_BLOCKS[i])
        self.merge()

    @invariant()
    def a_verified_file_is_the_reference(self) -> None:
        try:
            st_ = os.stat(self.out)
        except FileNotFoundError:
            return
        key = (st_.st_ino, st_.st_size, st_.st_mtime_ns)
        if key == self.checked:
            return
        self.checked = key
        try:
            info = netcdf.read_info(self.out, verify=True)
        except OutputError:
            return  # not readable: nobody calls it complete
        if info.get("complete") and info["verified"][0]:
            assert _contents(self.out) == _reference_file()[1]
            self.verified_files += 1


# 16 programs of 30 steps (the same every run): a merge writes a netCDF file (0.1 s), so the
# suite's budget pays for about 500 steps
StoreMachine.TestCase.settings = settings(
    max_examples=16, stateful_step_count=30, deadline=None, derandomize=True
)
TestStoreMachine = StoreMachine.TestCase


def test_the_machine_reaches_verified_files():
    """Guard: the interleavings above do produce complete, verified files (so the invariant is
    exercised), and a clean run of the machine's steps yields the reference."""
    m = StoreMachine()
    try:
        for i in range(N):
            m.write(i)
        m.merge()
        m.a_verified_file_is_the_reference()
        assert m.verified_files == 1
        i, j = next(
            (i, j)
            for i in range(N)
            for j in range(N)
            if REF_BLOCKS[i]["r_min"].tobytes() != REF_BLOCKS[j]["r_min"].tobytes()
        )
        m.corrupt(i, j, "swap", 0.5)
        before = m.out.stat().st_mtime_ns
        m.merge()  # refused: block i or j changed
        assert m.out.stat().st_mtime_ns == before
        m.resume()
        for i in range(N):
            if i not in m.store.scan().good:
                m.write(i)
        m.merge()
        m.a_verified_file_is_the_reference()
        assert m.verified_files == 2
    finally:
        m.teardown()

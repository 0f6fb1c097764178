"""A hypothesis state machine of the Zarr run store (as ``test_store_machine.py`` is of the block
store): random interleavings of block writes, kills (a writer's temporary file left, chunks
written but not journaled, a torn journal line, a commit killed after its record or before the
rename), corruptions of the unfinished store (flipped, truncated, deleted, linked chunks, a
chunk made a FIFO, an array's metadata edited), damage to the finished store (a chunk, an
array's own metadata, an extra array), resumes and commits never produce a store that ``info
--verify`` calls complete and verified and that a reader, with or without consolidated
metadata, sees differently from the reference.
"""

from __future__ import annotations

import contextlib
import functools
import os
import secrets
import shutil
import tempfile
import warnings
from pathlib import Path

import pytest
import runs
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

pytest.importorskip("zarr")

import xarray as xr  # noqa: E402

from engine.backends import compute_block
from engine.grid import Tiling  # noqa: E402
from engine.io import OutputError  # noqa: E402
from engine.io import zarr as zarr_io  # noqa: E402
from engine.io.blocks import remove_store  # noqa: E402
from engine.io.manifest import fingerprint, parts_dir  # noqa: E402
from engine.io.zarrstore import JOURNAL, RunStore  # noqa: E402
from engine.plan import plan_from_survey  # noqa: E402
from engine.surveyfile import parse_survey  # noqa: E402

SURVEY = parse_survey(runs.free_fall_survey("zarr machine", energy=5, lz=(-0.5, 0.2, 0.5)))
TILING = Tiling(SURVEY.shape, (1, 1, 2, 3), (1, 1, 2, 3))  # 60 points in 10 blocks
N = TILING.nblocks
_SPEC = plan_from_survey(SURVEY)
FP = fingerprint(_SPEC)
#: Computed on first use (runs.Computed: not while both xdist workers collect this file).
REF_BLOCKS = runs.Computed(lambda: [compute_block(_SPEC, TILING, i)[1] for i in range(N)])


class Killed(BaseException):
    """A kill, simulated: raised where SIGKILL would stop the commit (nothing is cleaned)."""


def _new_store(out: Path) -> RunStore:
    return zarr_io.create(parts_dir(out), _SPEC, TILING, 1, lambda msg: None)


def _write(store: RunStore, i: int) -> dict:
    return store.writer.write(i, TILING.slices(i), REF_BLOCKS[i])


def _contents(path: Path) -> dict:
    """What readers see, with and without consolidated metadata (values as raw bits)."""
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for consolidated in (True, False):
            ds = xr.open_zarr(path, consolidated=consolidated, chunks=None).load()
            out[consolidated] = {
                n: (v.dtype.str, v.values.tobytes(), repr(v.attrs)) for n, v in ds.variables.items()
            } | {"attrs": repr({k: v for k, v in ds.attrs.items() if k != "history"})}
    return out


@functools.cache
def _reference() -> dict:
    """The reference output's contents, made on first use (not while both xdist workers
    collect this file)."""
    d = Path(tempfile.mkdtemp(prefix="zarr-machine-ref-"))
    store = _new_store(d / "ref.zarr")
    for i in range(N):
        store.commit(i, _write(store, i))
    zarr_io.merge(store, _SPEC, d / "ref.zarr", fingerprint=FP)
    store.remove()
    return _contents(d / "ref.zarr")


class ZarrMachine(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.dir = Path(tempfile.mkdtemp(prefix="zarr-machine-"))
        self.out = self.dir / "out.zarr"
        self.root = parts_dir(self.out)
        self.store: RunStore | None = _new_store(self.out)
        self.checked: tuple | None = None
        self.verified = 0

    def teardown(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)

    def chunks(self, i: int) -> list[Path]:
        if self.store is None:
            return []
        return [self.store.store / k for k in self.store.keys(i)]

    # -- writes and kills --

    @rule(i=st.integers(0, N - 1))
    def write(self, i: int) -> None:
        if self.store is not None:
            with contextlib.suppress(OSError):
                self.store.commit(i, _write(self.store, i))

    @rule(i=st.integers(0, N - 1), how=st.sampled_from(["tmp", "unjournaled", "torn line"]))
    def kill_during_a_write(self, i: int, how: str) -> None:
        if self.store is None or not self.root.exists():
            return
        if how == "tmp":
            c = self.chunks(i)[0]
            if c.parent.is_dir():
                (c.parent / f".{c.name}.{secrets.token_hex(6)}.tmp").write_bytes(b"torn")
        elif how == "unjournaled":
            with contextlib.suppress(OSError):
                _write(self.store, i)
        else:
            with open(self.root / JOURNAL, "ab") as f:
                f.write(b'{"i": ' + str(i).encode())

    @rule(stage=st.sampled_from(["after the record", "before the rename"]))
    def kill_inside_the_commit(self, stage: str) -> None:
        if self.store is None:
            return
        from engine.io import zarrcommit

        target, name = (
            (zarrcommit, "write_atomic")
            if stage == "after the record"
            else (zarr_io, "put_in_place")
        )
        real = getattr(target, name)
        calls = []

        def patched(*args, **kwargs):
            calls.append(1)
            if stage == "after the record" and len(calls) == 1:
                return real(*args, **kwargs)  # the record is written; the root is not
            raise Killed

        setattr(target, name, patched)
        try:
            zarr_io.merge(self.store, _SPEC, self.out, fingerprint=FP, overwrite=True)
        except (Killed, OutputError, OSError):
            pass
        finally:
            setattr(target, name, real)

    # -- corruption of the unfinished store --

    @rule(
        i=st.integers(0, N - 1),
        how=st.sampled_from(["flip", "truncate", "delete", "link", "fifo", "meta"]),
    )
    def corrupt(self, i: int, how: str) -> None:
        if self.store is None or not self.root.exists():
            return
        # Another process writing in place would wait for the files this run holds
        # (engine/io/hold.py): the model lets go of them first, as a run that goes on without
        # them; those files are then hashed again at the commit.
        self.store.release()
        if how == "meta":
            p = self.store.store / "r_min" / "zarr.json"
            if p.is_file() and not p.is_symlink():
                p.write_text(p.read_text().replace('"little"', '"big"'))
            return
        c = self.chunks(i)[i % len(self.chunks(i))]
        if not c.is_file() or c.is_symlink():
            return
        data = c.read_bytes()
        if how == "flip":
            b = bytearray(data)
            b[len(b) // 2] ^= 0x10
            c.write_bytes(bytes(b))
        elif how == "truncate":
            c.write_bytes(data[: len(data) // 2])
        elif how == "delete":
            c.unlink()
        elif how == "link":
            target = self.dir / f"target-{secrets.token_hex(4)}"
            target.write_bytes(data)
            c.unlink()
            c.symlink_to(target)
        else:
            c.unlink()
            os.mkfifo(c)

    # -- damage to the finished store --

    @rule(how=st.sampled_from(["chunk", "meta", "extra"]))
    def damage_the_output(self, how: str) -> None:
        if not self.out.is_dir():
            return
        if how == "chunk":
            c = next((p for p in (self.out / "period").rglob("*") if p.is_file()), None)
            if c is not None:
                b = bytearray(c.read_bytes())
                b[-1] ^= 0x01
                c.write_bytes(bytes(b))
        elif how == "meta":
            p = self.out / "r_min" / "zarr.json"
            if p.is_file():
                p.write_text(p.read_text().replace('"little"', '"big"'))
        elif (self.out / "r_min").is_dir() and not (self.out / "r_extra").exists():
            shutil.copytree(self.out / "r_min", self.out / "r_extra")

    # -- what a run does --

    @rule()
    def resume(self) -> None:
        """Open (refused: the run is started over, as --overwrite does), scan, tidy."""
        if self.store is not None:
            self.store.release()  # the run before was killed: the kernel let go of its files
        if not self.root.exists():
            self.store = _new_store(self.out) if not self.out.exists() else None
            return
        try:
            store = RunStore.open(self.root)
        except OutputError:
            remove_store(self.root)
            self.store = _new_store(self.out)
            return
        store.expect(_SPEC)  # as the runner does: what the store must hold besides its blocks
        found = store.scan()
        store.discard(found)
        for name in found.bad:  # as the runner does: recompute the bad blocks
            i = int(name.split()[1])
            with contextlib.suppress(OSError):
                store.commit(i, _write(store, i))
        self.store = store

    @rule()
    def commit(self) -> None:
        if self.store is None:
            return
        try:
            zarr_io.merge(self.store, _SPEC, self.out, fingerprint=FP, overwrite=True)
        except (OutputError, OSError):
            return
        self.store.remove()
        self.store = None

    @invariant()
    def a_verified_store_is_the_reference(self) -> None:
        if not self.out.is_dir():
            return
        meta = self.out / "zarr.json"
        st_ = os.stat(meta)
        key = (st_.st_ino, st_.st_mtime_ns, tuple(sorted(os.listdir(self.out))))
        if key == self.checked:
            return
        self.checked = key
        try:
            info = zarr_io.read_info(self.out, verify=True)
        except OutputError:
            return  # refused: nobody calls it complete
        if info.get("complete") and info["verified"][0]:
            assert _contents(self.out) == _reference()
            self.verified += 1


ZarrMachine.TestCase.settings = settings(
    max_examples=12, stateful_step_count=20, deadline=None, derandomize=True
)
TestZarrMachine = ZarrMachine.TestCase


def test_the_machine_reaches_verified_stores():
    """Guard: the steps above do produce verified stores (the invariant is exercised), after a
    commit killed before the rename and one killed after its record."""
    m = ZarrMachine()
    try:
        for i in range(N):
            m.write(i)
        m.kill_inside_the_commit("before the rename")
        m.resume()
        m.kill_inside_the_commit("after the record")
        m.resume()
        m.commit()
        m.a_verified_store_is_the_reference()
        assert m.verified == 1
        m.damage_the_output("meta")
        m.a_verified_store_is_the_reference()
        assert m.verified == 1
    finally:
        m.teardown()

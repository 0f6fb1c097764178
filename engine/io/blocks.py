"""The block store of a streamed run, its manifest, and the survey fingerprint.

Layout while a run is under way, next to the output ``OUT``::

    OUT.parts/manifest.json     fingerprint of the survey, engine version, tiling, definition
    OUT.parts/b00000042.npz     results of block 42 (written through engine.io.atomic)

A block is done when its file exists; :meth:`BlockStore.verify` loads every stored block and
removes (after a warning) the ones that are corrupt or have the wrong layout. Nothing here
depends on the output format: a backend's ``merge`` reads the blocks with
:meth:`BlockStore.blocks` and gathers the run's statistics with :class:`Summary`. The streamed
run itself is described in the README ("Large surveys: streaming, resume, dask").
"""

from __future__ import annotations

import contextlib
import hashlib
import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._version import __version__
from ..grid import Tiling
from ..kernels.geometry import CLASS_NAMES
from ..schema import DIMS, FINGERPRINT_ATTR, result_variables, variable_attrs
from . import OutputError
from .atomic import write_atomic

if TYPE_CHECKING:
    from ..surveyfile import Survey

__all__ = [
    "FINGERPRINT_ATTR",
    "MANIFEST",
    "BlockStore",
    "Manifest",
    "Summary",
    "estimate_bytes",
    "fingerprint",
    "parts_dir",
    "parts_info",
    "read_manifest",
    "survey_variables",
    "write_manifest",
]

MANIFEST = "manifest.json"


def parts_dir(out: Path) -> Path:
    """The block store of the output ``out``: ``OUT.parts`` next to it."""
    return out.with_name(out.name + ".parts")


def survey_variables(survey: Survey) -> dict[str, np.dtype]:
    """Names and dtypes of the result variables of ``survey``, in file order."""
    return result_variables(survey.method, survey.scene, survey.energy_relative)


def estimate_bytes(survey: Survey) -> int:
    """Uncompressed size [bytes] of the results (the block files hold this much)."""
    per_point = sum(dt.itemsize for dt in survey_variables(survey).values())
    return per_point * survey.size


def fingerprint(survey: Survey) -> str:
    """SHA-256 of everything that determines the results: axes, scene, method, tolerances,
    title and the engine version."""
    doc = {
        "engine": __version__,
        "title": survey.title,
        "method": survey.method,
        "rtol": survey.rtol.hex(),
        "circular_tol": survey.circular_tol.hex(),
        "energy_relative": survey.energy_relative,
        "scene": {k: str(v) for k, v in survey.scene.as_attrs().items()},
        "axes": {d: [float(x).hex() for x in getattr(survey, d)] for d in DIMS},
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


# --- the manifest -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Manifest:
    """What a block store holds: the survey's fingerprint, the engine that wrote it, the tiling
    and the survey definition (TOML text)."""

    fingerprint: str
    engine: str | None
    tiling: Tiling
    survey_definition: str = ""

    @classmethod
    def new(cls, survey: Survey, tiling: Tiling) -> Manifest:
        """The manifest of a run of ``survey`` by this engine, in blocks of ``tiling``."""
        return cls(fingerprint(survey), __version__, tiling, survey.source_text)


def read_manifest(root: Path) -> Manifest:
    """The manifest of the block store ``root``; OutputError if it is missing or unreadable."""
    path = root / MANIFEST
    try:
        m = json.loads(path.read_text())
        tiling = Tiling(tuple(m["shape"]), tuple(m["chunk"]), tuple(m["block"]))
        return Manifest(m["fingerprint"], m.get("engine"), tiling, m.get("survey_definition", ""))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise OutputError(f"{path} is unreadable ({exc})") from None


def write_manifest(root: Path, manifest: Manifest) -> None:
    """Write the manifest of the block store ``root`` (atomically)."""
    doc = {
        "fingerprint": manifest.fingerprint,
        "engine": manifest.engine,
        "shape": list(manifest.tiling.shape),
        "chunk": list(manifest.tiling.chunk),
        "block": list(manifest.tiling.block),
        "survey_definition": manifest.survey_definition,
    }
    write_atomic(root / MANIFEST, lambda f: f.write(json.dumps(doc, indent=1).encode()))


# --- the blocks -------------------------------------------------------------------------------


@dataclass
class BlockStore:
    """Finished blocks of one run, one ``.npz`` file each (the manifest is written apart)."""

    root: Path
    tiling: Tiling
    names: dict[str, np.dtype]
    warn: Callable[[str], None] = field(default=lambda msg: None)

    def path(self, index: int) -> Path:
        return self.root / f"b{index:08d}.npz"

    def save(self, index: int, arrays: dict[str, np.ndarray]) -> None:
        """Store block ``index`` (atomically: a block file is complete or absent)."""
        clean = {n: np.ascontiguousarray(arrays[n], dtype=dt) for n, dt in self.names.items()}
        write_atomic(self.path(index), lambda f: np.savez(f, **clean))

    def load(self, index: int) -> dict[str, np.ndarray] | None:
        """The block's arrays, or None (after a warning) if its file is missing or corrupt."""
        p = self.path(index)
        shape = tuple(s.stop - s.start for s in self.tiling.slices(index))
        try:
            with np.load(p, allow_pickle=False) as z:
                out = {n: z[n] for n in self.names}
        except FileNotFoundError:
            return None
        except Exception as exc:  # truncated zip, bad CRC, missing member ...
            self.warn(f"block file {p.name} is corrupt ({exc.__class__.__name__}); recomputing")
            p.unlink(missing_ok=True)
            return None
        for n, dt in self.names.items():
            if out[n].shape != shape or out[n].dtype != dt:
                self.warn(f"block file {p.name} has the wrong {n} layout; recomputing")
                p.unlink(missing_ok=True)
                return None
        return out

    def done(self) -> set[int]:
        """Indices of blocks whose file exists (not yet verified)."""
        found = set()
        for p in self.root.glob("b*.npz"):
            with contextlib.suppress(ValueError):
                found.add(int(p.stem[1:]))
        return {i for i in found if i < self.tiling.nblocks}

    def verify(self) -> set[int]:
        """Indices of stored blocks that load and have the right layout."""
        return {i for i in sorted(self.done()) if self.load(i) is not None}

    def remove_stale_tmp(self) -> None:
        """Delete the ``.tmp`` files a killed run left behind."""
        for tmp in self.root.glob("*.tmp"):
            tmp.unlink(missing_ok=True)

    def blocks(self) -> Iterator[tuple[tuple[slice, ...], dict[str, np.ndarray]]]:
        """(hyperslab, arrays) of every block in order; OutputError if one is missing."""
        for i in range(self.tiling.nblocks):
            block = self.load(i)
            if block is None:
                raise OutputError(f"block {i} vanished or is corrupt during the merge; rerun")
            yield self.tiling.slices(i), block


def parts_info(root: Path) -> dict[str, Any]:
    """What an unfinished run's block store says about it (``read_info`` of a backend)."""
    m = read_manifest(root)
    return {
        "complete": False,
        "attrs": {"survey_definition": m.survey_definition, "engine": m.engine},
        "dims": dict(zip(DIMS, m.tiling.shape, strict=True)),
        "blocks_done": len(BlockStore(root, m.tiling, {}).done()),
        "blocks_total": m.tiling.nblocks,
    }


class Summary:
    """Class counts and finite value ranges of the results, gathered block by block."""

    def __init__(self) -> None:
        self.counts = np.zeros(len(CLASS_NAMES), np.int64)
        self._lo: dict[str, float] = {}
        self._hi: dict[str, float] = {}

    def add(self, block: dict[str, np.ndarray]) -> None:
        """Count the classes of ``block`` and widen the ranges of its float variables."""
        for name, arr in block.items():
            if name == "orbit_class":
                self.counts += np.bincount(arr.ravel(), minlength=len(CLASS_NAMES))
            elif arr.dtype.kind == "f":
                fin = arr[np.isfinite(arr)]
                if fin.size:
                    self._lo[name] = min(self._lo.get(name, np.inf), float(fin.min()))
                    self._hi[name] = max(self._hi.get(name, -np.inf), float(fin.max()))

    @property
    def ranges(self) -> dict[str, tuple[float, float, str]]:
        """(min, max, units) of each float variable over its finite values."""
        return {
            n: (lo, self._hi[n], variable_attrs(n).get("units", "")) for n, lo in self._lo.items()
        }

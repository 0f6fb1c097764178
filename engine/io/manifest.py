"""The manifest of a streamed run's block store, and the survey fingerprint it records.

``OUT.parts/manifest.json`` is written once, atomically, when the store is created. It is data
from disk, so nothing trusts it before :meth:`Manifest.from_doc` has checked it: the format tag,
a checksum over its own fields (a hand edit, a flipped bit or a torn copy is reported as
unreadable), the types and ranges of every field, a tiling consistent with itself (blocks are
whole multiples of the storage chunk, within the grid) and variables the engine knows with the
dtypes it writes. :meth:`Manifest.mismatch` then compares it with the survey being run.

The fingerprint (:func:`fingerprint`) hashes everything that determines the results. The axes
enter as their float64 bytes, fed to SHA-256 without a copy, so a 10^7-point axis costs ~50 ms
and no extra memory.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._version import __version__
from ..families import family_values
from ..grid import Tiling
from ..schema import GRID_DIMS, RESULTS, variable_dims
from . import OutputError
from .atomic import NotRegularFile, read_regular, write_atomic
from .chunkfile import ChunkCodec

if TYPE_CHECKING:
    from .planshape import RunPlan

__all__ = [
    "FORMAT",
    "MANIFEST",
    "Manifest",
    "fingerprint",
    "parts_dir",
    "read_manifest",
    "survey_families",
    "survey_variables",
    "write_manifest",
]

MANIFEST = "manifest.json"
#: Format tag of the block store (a store of another format is not resumed).
FORMAT = "conesurvey-blocks/2"
#: Largest manifest read (the survey definition is in it).
MAX_MANIFEST_BYTES = 64 << 20


def parts_dir(out: Path) -> Path:
    """The block store of the output ``out``: ``OUT.parts`` next to it."""
    return out.with_name(out.name + ".parts")


def survey_variables(plan: RunPlan) -> dict[str, np.dtype]:
    """Names and dtypes of the result variables of ``plan`` that its blocks hold, in file
    order: those stored on every axis (r_circ and V_min, on fewer dims, are written whole by
    the writers: :func:`engine.schema.variable_dims`, :func:`survey_families`)."""
    dims = tuple(plan.dims)
    return {n: dt for n, dt in plan.variables.items() if variable_dims(n, dims) == dims}


def survey_families(plan: RunPlan) -> dict[str, np.ndarray]:
    """The variables of ``plan`` stored on fewer dims, computed whole
    (:func:`engine.families.family_values`), name -> values shaped as their dims."""
    axes = {d: np.asarray(plan.axis(d), np.float64) for d in plan.dims}
    return family_values(plan.dims, axes, plan.scene, plan.map_kind, plan.variables)


def fingerprint(plan: RunPlan) -> str:
    """SHA-256 of everything that determines the results: axes (their names and float64
    bytes), scene, method, tolerances, the horizon of a fate map, title and the engine
    version."""
    doc = {
        "engine": __version__,
        "title": plan.title,
        "method": plan.method.name,
        "rtol": plan.rtol.hex(),
        "circular_tol": plan.circular_tol.hex(),
        "energy_relative": plan.energy_relative,
        "scene": {k: str(v) for k, v in plan.scene.as_attrs().items()},
        "axes": {d: int(np.size(plan.axis(d))) for d in plan.dims},
    }
    if plan.output.precision != "double":  # float32 (absent: the fingerprints of before)
        doc["precision"] = plan.output.precision
    if plan.horizon is not None:  # fate maps: how long each orbit is followed
        doc["horizon"] = {k: str(v) for k, v in plan.horizon.as_attrs().items()}
    h = hashlib.sha256(json.dumps(doc, sort_keys=True).encode())
    for d in plan.dims:
        h.update(d.encode())
        h.update(np.ascontiguousarray(plan.axis(d), dtype="<f8"))  # no copy
    return h.hexdigest()


def _self_check(doc: dict[str, Any]) -> str:
    body = {k: v for k, v in doc.items() if k != "check"}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


#: How many axes a survey grid may have (engine.schema.GRID_DIMS).
_RANKS = sorted({len(d) for d in GRID_DIMS})


def _ints(doc: dict[str, Any], key: str) -> tuple[int, ...]:
    value = doc.get(key)
    if not (
        isinstance(value, list)
        and len(value) in _RANKS
        and all(isinstance(x, int) and not isinstance(x, bool) and x >= 1 for x in value)
    ):
        raise ValueError(
            f"{key} must be {_RANKS[0]} positive integers ({_RANKS[-1]} on a grid of launches "
            f"that may slide), got {value!r}"
        )
    return tuple(value)


def _tiling(doc: dict[str, Any]) -> Tiling:
    shape, chunk, block = _ints(doc, "shape"), _ints(doc, "chunk"), _ints(doc, "block")
    for d, n, c, b in zip(range(len(shape)), shape, chunk, block, strict=True):
        if c > n or b > n:
            raise ValueError(f"chunk {c} or block {b} of axis {d} exceeds the grid's {n}")
        if b % c and b != n:
            raise ValueError(f"block {b} of axis {d} is not a whole number of chunks of {c}")
    if math.prod(shape) > 2**62:
        raise ValueError(f"shape {list(shape)} is beyond any grid")
    return Tiling(shape, chunk, block)


def _zarr(doc: Any) -> tuple[int, str]:
    """A Zarr store's (compression level, chunk key separator) from the manifest."""
    level = doc.get("complevel") if isinstance(doc, dict) else None
    sep = doc.get("separator") if isinstance(doc, dict) else None
    if level not in (0, 1) or isinstance(level, bool) or sep not in (".", "/"):
        raise ValueError(f"zarr must say a complevel 0 or 1 and a separator . or /, got {doc!r}")
    return level, sep


@dataclass(frozen=True)
class Manifest:
    """What a block store holds: the survey's fingerprint, the engine that wrote it, the tiling,
    the variables with their dtypes and the survey definition (TOML text)."""

    fingerprint: str
    engine: str
    tiling: Tiling
    variables: tuple[tuple[str, str], ...]
    survey_definition: str = ""
    #: How the block files hold a block: compressed chunks by this codec
    #: (:mod:`engine.io.chunkfile`), or None: ``.npz`` files of the values.
    codec: ChunkCodec | None = None
    #: A Zarr run's store: its compression level (0 or 1) and chunk key separator, what its
    #: metadata is made again from on resume (None: a netCDF run, or a store made before).
    zarr: tuple[int, str] | None = None

    @classmethod
    def new(cls, plan: RunPlan, tiling: Tiling, codec: ChunkCodec | None = None) -> Manifest:
        """The manifest of a run of ``survey`` by this engine, in blocks of ``tiling``."""
        names = tuple((n, dt.name) for n, dt in survey_variables(plan).items())
        return cls(fingerprint(plan), __version__, tiling, names, plan.source_text, codec)

    def to_doc(self) -> dict[str, Any]:
        """The JSON document, with the format tag and the checksum of its fields."""
        doc: dict[str, Any] = {
            "format": FORMAT,
            "fingerprint": self.fingerprint,
            "engine": self.engine,
            "shape": list(self.tiling.shape),
            "chunk": list(self.tiling.chunk),
            "block": list(self.tiling.block),
            "variables": dict(self.variables),
            "survey_definition": self.survey_definition,
        }
        if self.codec is not None:  # absent: .npz blocks (the manifests of before)
            doc["blocks"] = self.codec.to_doc()
        if self.zarr is not None:
            doc["zarr"] = {"complevel": self.zarr[0], "separator": self.zarr[1]}
        doc["check"] = _self_check(doc)
        return doc

    @classmethod
    def from_doc(cls, doc: Any) -> Manifest:
        """The manifest a JSON document describes; ValueError saying what is wrong with it."""
        if not isinstance(doc, dict):
            raise ValueError("not a JSON object")
        if doc.get("format") != FORMAT:
            raise ValueError(f"format {doc.get('format')!r} is not {FORMAT!r}")
        if doc.get("check") != _self_check(doc):
            raise ValueError("its checksum does not match its contents (edited or damaged)")
        fp, engine, text = doc.get("fingerprint"), doc.get("engine"), doc.get("survey_definition")
        if not (isinstance(fp, str) and len(fp) == 64 and all(c in "0123456789abcdef" for c in fp)):
            raise ValueError(f"fingerprint {fp!r} is not a SHA-256 hex digest")
        if not isinstance(engine, str) or not isinstance(text, str):
            raise ValueError("engine and survey_definition must be strings")
        variables = doc.get("variables")
        if not isinstance(variables, dict) or not variables:
            raise ValueError("variables must be a non-empty object")
        for name, dtype in variables.items():
            if name not in RESULTS or dtype != np.dtype(RESULTS[name].dtype).name:
                raise ValueError(f"variable {name!r} of dtype {dtype!r} is not a result variable")
        codec = ChunkCodec.from_doc(doc["blocks"]) if "blocks" in doc else None
        zarr = _zarr(doc["zarr"]) if "zarr" in doc else None
        return cls(fp, engine, _tiling(doc), tuple(variables.items()), text, codec, zarr)

    def mismatch(self, plan: RunPlan) -> str | None:
        """Why this store cannot hold ``survey``'s results (None if it can)."""
        current = Manifest.new(plan, self.tiling)
        if self.fingerprint != current.fingerprint:
            if self.engine != current.engine:
                return f"engine version {self.engine} != {current.engine}"
            return "the survey definition or scene differs"
        if self.tiling.shape != tuple(plan.shape):
            return f"its grid {list(self.tiling.shape)} is not the survey's {list(plan.shape)}"
        if self.variables != current.variables:
            return "its variables are not the survey's"
        return None

    @property
    def names(self) -> dict[str, np.dtype]:
        """Variable names and dtypes, in file order."""
        return {n: np.dtype(dt) for n, dt in self.variables}


def read_manifest(root: Path) -> Manifest:
    """The manifest of the block store ``root``; OutputError if it is missing, is not a regular
    file (a link is not followed), or is not a valid manifest."""
    path = root / MANIFEST
    try:
        doc = json.loads(read_regular(path, MAX_MANIFEST_BYTES, follow_links=False))
        return Manifest.from_doc(doc)
    except FileNotFoundError:
        raise OutputError(f"{path} is unreadable (missing)") from None
    except NotRegularFile as exc:
        raise OutputError(f"{path} is unreadable ({exc.strerror})") from None
    except (OSError, ValueError, RecursionError) as exc:  # JSONDecodeError is a ValueError
        raise OutputError(f"{path} is unreadable ({exc})") from None


def write_manifest(root: Path, manifest: Manifest) -> None:
    """Write the manifest of the block store ``root`` (atomically, never through a link)."""
    text = json.dumps(manifest.to_doc(), indent=1).encode()
    write_atomic(root / MANIFEST, lambda f: f.write(text), mode=0o600)

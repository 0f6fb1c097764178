"""The output formats: one protocol, one registry (as xarray's backends are), one lookup.

Every place that needs to know how a result is stored asks its row, :func:`format_for`
(``format_for(path)``: the row of the path's suffix, netCDF-4 for any other name;
``format_for(path, "zarr")``: a named row). Nothing else tests a file's suffix.

A row (:class:`OutputFormat`) is the whole contract of a format:

- ``create(root, plan, tiling, complevel, warn)``: the private directory of a new streamed
  run (``OUT.parts/``, a :class:`engine.io.blocks.BlockStore` or a Zarr
  :class:`engine.io.zarrstore.RunStore`); ``open_run(root, warn)`` reopens it to resume;
  each computed block is written through it (``store.commit(index, block)``; a store with a
  ``writer`` has the workers write their own chunks);
- ``commit(store, plan, out, *, fingerprint, command, overwrite, compression, complevel,
  pending, incoming, warn) -> Summary``: the output from the run's store, taking each block
  from ``incoming`` as it is committed (netCDF writes while blocks are computed; Zarr drains
  it and commits the store the workers wrote), renamed into place complete;
- ``read_fingerprint(path)``: the survey fingerprint a finished result records (resume, and
  "already complete"); ``read_info(path, verify=)``: provenance for ``conesurvey info``, and
  with ``verify`` every value checked against the content checksum;
- ``open_result(path)``: a finished result for reading (:mod:`engine.io.results`);
- ``open_view(path)``: a finished result through the netCDF4 ``Dataset`` interface (variables
  with ``dimensions``, ``chunking()``, slicing; ``ncattrs``/``getncattr``), which a conversion
  reads;
- ``write_copy(src, out, attrs, hasher, recorded, overwrite)``: a converted copy
  (:mod:`engine.io.convert`), ``write_survey(ds, path, plan, ...)``: an in-memory Dataset;
- ``run_bytes(plan, tiling, pending, directory)``: (blocks, output) bytes a run still needs
  in ``directory``, from the layout it stores (:mod:`engine.io.space`);
  ``output_bytes(names, shape)``: an upper bound of a result's size;
- ``compressions`` (the first is the default), ``directory`` (the output is a directory),
  ``unavailable()`` (why it cannot be written here: "" if it can).

A new format is one more row passed to :func:`register` (docs/architecture.md, "A new output
format"; ``tests/io/test_format_recipe.py`` applies the recipe).
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import netCDF4

from . import zarr as zarr_io
from .blocks import BlockStore
from .chunkfile import block_codec
from .codecs import COMPRESSIONS, DEFAULT_COMPRESSION, level
from .manifest import Manifest
from .space import (
    allocation_unit,
    block_files_bytes,
    netcdf_bytes,
    output_bytes,
    store_bytes,
)
from .zarrstore import RunStore

__all__ = ["FORMATS", "OutputFormat", "format_for", "formats_text", "register", "unregister"]


def _nothing_missing() -> str:
    return ""


def _block_run_bytes(plan: Any, tiling: Any, pending: list[int], directory: Path):
    """Block files for every pending block, and the output merged beside all of them."""
    unit = allocation_unit(directory)
    return block_files_bytes(plan, tiling, pending, unit), netcdf_bytes(plan, tiling, unit)


def _create_blocks(root: Path, plan: Any, tiling: Any, complevel: int, warn: Callable):
    """A block store whose files hold the chunks the output gets where it is deflated."""
    codec = block_codec(plan.output.compression, plan.output.complevel)
    return BlockStore.create(root, Manifest.new(plan, tiling, codec), warn)


def _refuse(what: str, name: str) -> Callable[..., Any]:
    def refuse(*args: Any, **kwargs: Any) -> Any:
        raise NotImplementedError(f"the {name} format has no {what}")

    return refuse


@dataclass(frozen=True)
class OutputFormat:
    """One output format (see the module docstring for each entry's contract)."""

    name: str
    label: str
    suffixes: tuple[str, ...]
    create: Callable[..., Any]
    open_run: Callable[..., Any]
    commit: Callable[..., Any]
    read_fingerprint: Callable[[Path], str | None]
    read_info: Callable[..., dict[str, Any]]
    compressions: tuple[str, ...] = ("none",)
    directory: bool = False
    unavailable: Callable[[], str] = _nothing_missing
    run_bytes: Callable[..., tuple[int, int]] = _block_run_bytes
    output_bytes: Callable[..., int] = output_bytes
    open_result: Callable[[Path], Any] | None = None
    open_view: Callable[[Path], Any] | None = None
    write_copy: Callable[..., str] | None = None
    write_survey: Callable[..., Path] | None = None

    @property
    def default_compression(self) -> str:
        return self.compressions[0]

    def owns(self, path: str | os.PathLike[str]) -> bool:
        """Whether ``path``'s name ends in one of this format's suffixes."""
        return Path(path).suffix.lower() in self.suffixes

    def check_compression(self, compression: str) -> None:
        """ValueError unless this format writes ``compression``."""
        if compression not in self.compressions:
            raise ValueError(
                f"compression {compression!r} is not written to {self.label} output; "
                f"use {' or '.join(self.compressions)}"
            )


def _lazy(module: str, name: str) -> Callable[..., Any]:
    """``module.name``, looked up at each call: the reader and the converter import this
    registry (their functions are found when called), and a function replaced in its module
    (a test's monkeypatch, a hook) is the one a row calls."""

    def call(*args: Any, **kwargs: Any) -> Any:
        return getattr(importlib.import_module(module, __package__), name)(*args, **kwargs)

    call.__name__ = name
    return call


def _zarr_commit(store: RunStore, plan: Any, out: Path, *, incoming: Any, **options: Any):
    """Zarr: the workers wrote their chunks; every block is awaited, then the store committed."""
    for _ in incoming:
        pass
    keep = {k: options[k] for k in ("fingerprint", "command", "overwrite") if k in options}
    complevel = level(options.get("compression", "blosc_lz4"), options.get("complevel"))
    return zarr_io.merge(store, plan, out, **keep, complevel=complevel)


def _zarr_run_bytes(plan: Any, tiling: Any, pending: list[int], directory: Path):
    """No block files: the chunks are written into the store, which becomes the output."""
    return store_bytes(plan, tiling, pending, allocation_unit(directory)), 0


NETCDF = OutputFormat(
    name="netcdf",
    label="netCDF",
    suffixes=(".nc", ".nc4", ".netcdf"),
    create=_create_blocks,
    open_run=BlockStore.open,
    commit=_lazy(".netcdf", "merge"),
    read_fingerprint=_lazy(".netcdf", "read_fingerprint"),
    read_info=_lazy(".netcdf", "read_info"),
    compressions=(DEFAULT_COMPRESSION, *(c for c in COMPRESSIONS if c != DEFAULT_COMPRESSION)),
    open_result=_lazy(".results", "open_netcdf"),
    open_view=netCDF4.Dataset,
    write_copy=_lazy(".convert", "to_netcdf"),
    write_survey=_lazy(".netcdf", "write_survey"),
)

ZARR = OutputFormat(
    name="zarr",
    label="Zarr",
    suffixes=(zarr_io.SUFFIX,),
    create=_lazy(".zarr", "create"),
    open_run=RunStore.open,
    commit=_zarr_commit,
    read_fingerprint=_lazy(".zarr", "read_fingerprint"),
    read_info=_lazy(".zarr", "read_info"),
    compressions=("blosc_lz4", "none"),
    directory=True,
    unavailable=_lazy(".zarr", "unavailable"),
    run_bytes=_zarr_run_bytes,
    output_bytes=_lazy(".zarr", "output_bytes"),
    open_result=_lazy(".results", "open_zarr"),
    open_view=_lazy(".zarr", "open_view"),
    write_copy=_lazy(".convert", "to_zarr"),
    write_survey=_lazy(".zarr", "write_survey"),
)

#: The registered formats by name; the first is the default for a name no row claims.
FORMATS: dict[str, OutputFormat] = {"netcdf": NETCDF, "zarr": ZARR}


def register(fmt: OutputFormat) -> None:
    """Add ``fmt`` (or replace the row of its name); its suffixes then select it."""
    if not fmt.suffixes or any(not s.startswith(".") or s != s.lower() for s in fmt.suffixes):
        raise ValueError(f"format {fmt.name!r}: suffixes must be lower-case and start with '.'")
    FORMATS[fmt.name] = fmt


def unregister(name: str) -> None:
    """Remove the row ``name`` (the two built-in rows stay)."""
    if name in ("netcdf", "zarr"):
        raise ValueError(f"the {name} format is built in")
    FORMATS.pop(name, None)


def format_for(path: str | os.PathLike[str] | None = None, name: str | None = None) -> OutputFormat:
    """The row of the format ``name`` if given (ValueError naming it if none is registered),
    else the row whose suffix ``path`` ends in, else netCDF-4."""
    if name is not None:
        try:
            return FORMATS[name.lower()]
        except KeyError:
            raise ValueError(f"format must be one of {formats_text()}; got {name!r}") from None
    if path is not None:
        for fmt in FORMATS.values():
            if fmt.owns(path):
                return fmt
    return NETCDF


def formats_text() -> str:
    """The registered formats for a message: ``netcdf (.nc), zarr (.zarr)``."""
    return ", ".join(f"{f.name} ({'/'.join(f.suffixes)})" for f in FORMATS.values())

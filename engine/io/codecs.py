"""The compressions a result's variables can be written with (``conesurvey run --compression``).

One list for every output format; each backend maps a name to its own library's settings
(:func:`compression_keywords` for netCDF-4, here). What each choice costs (MB/s and ratio on
a shipped survey) and who can read it: docs/output.md.

- ``zlib`` (default): deflate with shuffle, built into every HDF5 and netCDF-4 reader (ncdump,
  h5dump, xarray with either engine, Panoply, MATLAB, R) with no plugin: the portable one. A
  streamed run compresses its chunks on every core and writes them directly
  (:mod:`engine.io.deflate`), at levels 1-3 with ISA-L;
- ``blosc_lz4``: Blosc with LZ4 and byte shuffle (HDF5 filter 32001); read by the netCDF4
  wheels from PyPI (they ship the filter plugins), h5py with ``hdf5plugin``, netCDF-C >= 4.9
  with its filter plugins installed; not by Debian's ncdump nor xarray's h5netcdf engine
  without them. HDF5's blosc filter fails on a chunk it cannot shrink (it has no room for
  blosc's uncompressed fallback), which small chunks often are: a variable whose chunks are
  under :data:`SMALL_CHUNK_BYTES` is written with ``zstd`` instead (:func:`variable_keywords`),
  and the merge rewrites a variable with ``zstd`` if one of its chunks fails all the same
  (:func:`engine.io.netcdf.merge`);
- ``zstd``: Zstandard (HDF5 filter 32015), without shuffle (the netCDF4 package adds the
  shuffle filter to zlib only); read by the same tools as blosc_lz4;
- ``none``: no filter.

A compression this netCDF library cannot write (a filter plugin missing) is never an error:
the variables are written with ``zlib`` and :func:`fallback_notice` says so in one line.
"""

from __future__ import annotations

import functools

import netCDF4
import numpy as np

from . import deflate

__all__ = [
    "COMPRESSIONS",
    "DEFAULT_COMPRESSION",
    "DEFAULT_LEVELS",
    "FALLBACK",
    "check_compression",
    "fallback_notice",
    "written_compression",
    "compression_keywords",
    "SMALL_CHUNK_BYTES",
    "is_blosc",
    "merge_notices",
    "level",
    "variable_keywords",
]

COMPRESSIONS = ("zlib", "blosc_lz4", "zstd", "none")
DEFAULT_COMPRESSION = "zlib"
#: What a compression this netCDF library cannot write is replaced by (always writable).
PORTABLE = "zlib"
#: Default level of each (``--complevel``; 0 = uncompressed whatever the name): blosc's own
#: default; zlib 1 (level 4 compresses < 1 % better for 7-26 % more time); zstd 1 (levels 3 and
#: 9 compress ~6 % better at 0.75x and 0.5x the speed).
DEFAULT_LEVELS = {"blosc_lz4": 5, "zstd": 1, "zlib": 1, "none": 0}
#: Chunks smaller than this [bytes] are not given to blosc (see above); zstd never fails.
SMALL_CHUNK_BYTES = 1 << 16
#: What a variable blosc cannot write is written with.
FALLBACK = "zstd"


def check_compression(name: object, complevel: object = None) -> None:
    """ValueError naming the value unless ``name`` is one of :data:`COMPRESSIONS` and
    ``complevel`` is None (the name's default) or an integer 0..9."""
    if not isinstance(name, str) or name not in COMPRESSIONS:
        raise ValueError(f"compression must be one of {', '.join(COMPRESSIONS)}; got {name!r}")
    if complevel is not None and (
        not isinstance(complevel, int) or isinstance(complevel, bool) or not 0 <= complevel <= 9
    ):
        raise ValueError(f"complevel must be an integer 0..9; got {complevel!r}")


def level(name: str, complevel: int | None) -> int:
    """The level used for compression ``name`` (checked): ``complevel``, or its default."""
    check_compression(name, complevel)
    return DEFAULT_LEVELS[name] if complevel is None else complevel


def compression_keywords(name: str = DEFAULT_COMPRESSION, complevel: int | None = None) -> dict:
    """The netCDF4 ``createVariable`` keywords (xarray's encoding takes the same) of compression
    ``name`` (:mod:`engine.io.codecs`) at ``complevel`` (None: its default; 0: uncompressed).
    ValueError naming the value if it is not a choice. Where this netCDF library cannot write
    it (checked by writing a small in-memory file once), those of ``zlib`` at its default
    level (:func:`fallback_notice` says why)."""
    lvl = level(name, complevel)
    if name == "none" or lvl == 0:
        return {"compression": None}
    if name == "zlib":
        return {"compression": "zlib", "complevel": lvl, "shuffle": True}
    kw = {"compression": name, "complevel": lvl}
    if name == "blosc_lz4":
        kw["blosc_shuffle"] = 1  # byte shuffle
    if _cannot_write(tuple(kw.items())):
        return compression_keywords(PORTABLE)
    return kw  # zstd: netCDF4 adds the shuffle filter to zlib only


def written_compression(name: str) -> str:
    """The compression the variables are written with when ``name`` (checked) is asked for:
    ``name``, or ``zlib`` where this netCDF library cannot write it."""
    check_compression(name)
    return PORTABLE if fallback_notice(name) else name


def fallback_notice(name: str) -> str:
    """One line saying that ``name`` cannot be written here and ``zlib`` is written instead
    ("" if it can be written)."""
    check_compression(name)
    if name in (PORTABLE, "none"):
        return ""
    kw = {"compression": name, "complevel": DEFAULT_LEVELS[name]}
    if name == "blosc_lz4":
        kw["blosc_shuffle"] = 1
    problem = _cannot_write(tuple(kw.items()))
    if not problem:
        return ""
    return (
        f"compression {name!r} cannot be written by this netCDF library (netCDF4 "
        f"{netCDF4.__version__}, netCDF-C {netCDF4.__netcdf4libversion__}: {problem}); "
        f"writing {PORTABLE} (readable by every netCDF-4 tool) instead"
    )


def variable_keywords(name: str, complevel: int | None, chunk_bytes: int) -> dict:
    """:func:`compression_keywords` for a variable whose storage chunks hold ``chunk_bytes``:
    those of :data:`FALLBACK` instead of blosc's for chunks under :data:`SMALL_CHUNK_BYTES`."""
    kw = compression_keywords(name, complevel)
    if is_blosc(kw) and chunk_bytes < SMALL_CHUNK_BYTES:
        return compression_keywords(FALLBACK, complevel)
    return kw


def merge_notices(compression: str, complevel: int | None) -> list[str]:
    """What :func:`engine.io.netcdf.merge` says before writing: a compression written as zlib
    instead (:func:`fallback_notice`), zlib compressed by netCDF4 on one thread."""
    if notice := fallback_notice(compression):
        return [notice]
    if compression_keywords(compression, complevel).get("compression") == "zlib" and (
        why := deflate.unavailable()
    ):
        return [f"zlib is compressed by netCDF4 on one thread here, slower: {why}"]
    return []


def is_blosc(keywords: dict) -> bool:
    """Whether these :func:`compression_keywords` use one of blosc's filters."""
    return str(keywords.get("compression")).startswith("blosc")


@functools.cache
def _cannot_write(kw: tuple) -> str:
    """Why a variable with these keywords cannot be written and read back ("" if it can): the
    filter plugin may be missing (HDF5_PLUGIN_PATH set elsewhere, a library built without)."""
    values = np.arange(64, dtype=np.float64)
    try:
        with netCDF4.Dataset("probe.nc", "w", diskless=True, persist=False) as nc:
            nc.createDimension("x", values.size)
            v = nc.createVariable("v", "f8", ("x",), chunksizes=(values.size,), **dict(kw))
            v[:] = values
            ok = np.array_equal(v[:], values)
    except Exception as exc:  # netCDF4 raises RuntimeError, NetCDF4MissingFeatureException
        return str(exc)
    return "" if ok else "values do not read back"

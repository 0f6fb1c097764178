"""Reading and writing conesurvey results: crash-safe files, the block store, the file formats.

- :mod:`engine.io.atomic`: the one way this package makes a file appear under its name (write
  a fresh ``NAME.<random>.tmp`` created with O_EXCL | O_NOFOLLOW, fsync, rename, fsync the
  directory), and reads regular files only;
- :mod:`engine.io.lock`: the exclusive lock of an output, held for a whole run;
- :mod:`engine.io.manifest`: the manifest of a block store, validated as data, and the survey
  fingerprint;
- :mod:`engine.io.blocks`: the store of finished blocks of a streamed run (``OUT.parts/``), a
  journal of their checksums, and the statistics gathered while blocks are merged;
- :mod:`engine.io.contents`: the content checksum of a result file (``info --verify``);
- :mod:`engine.io.codecs`: the compressions of ``--compression``, for every format;
- :mod:`engine.io.feed`: the writer thread that merges blocks in order while they are computed;
- :mod:`engine.io.netcdf`: the netCDF-4 / CF-1.11 backend: :func:`~engine.io.netcdf.write_survey`
  for an in-memory Dataset, :func:`~engine.io.netcdf.merge` for a block store,
  :func:`~engine.io.netcdf.read_info` (:mod:`engine.io.netcdf_info`) for a finished file or an
  unfinished run.

- :mod:`engine.io.formats`: the output formats, one row each (netCDF-4, Zarr), and
  :func:`~engine.io.formats.format_for`, which every caller asks for the format of a path.

A new format is one more row of :mod:`engine.io.formats` (docs/architecture.md). This module
imports none of the backends, so importing one never imports another (and nothing here can
form an import cycle).
"""

from __future__ import annotations

__all__ = ["OutputError", "WriteError"]


class OutputError(Exception):
    """A result file, a block store or its manifest that cannot be read or is incomplete."""


class WriteError(OutputError):
    """A file that could not be written (a full disk, an I/O error); what was stored before is
    kept, so the run can be resumed."""

"""Reading and writing conesurvey results: crash-safe files, the block store, the file formats.

- :mod:`engine.io.atomic`: the one way this package makes a file appear under its name (write
  ``NAME.tmp`` in the same directory, fsync, rename, fsync the directory);
- :mod:`engine.io.blocks`: the store of finished blocks of a streamed run (``OUT.parts/``), its
  manifest, the survey fingerprint and the statistics gathered while blocks are merged;
- :mod:`engine.io.netcdf`: the netCDF-4 / CF-1.11 backend: :func:`~engine.io.netcdf.write_survey`
  for an in-memory Dataset, :func:`~engine.io.netcdf.merge` for a block store,
  :func:`~engine.io.netcdf.read_info` for a finished file or an unfinished run.

A second format (Zarr, say) is one more module with the functions of :mod:`engine.io.netcdf`'s
backend interface. This module imports none of them, so importing one backend never imports
another (and nothing here can form an import cycle).
"""

from __future__ import annotations

__all__ = ["OutputError"]


class OutputError(Exception):
    """A result file, a block store or its manifest that cannot be read or is incomplete."""

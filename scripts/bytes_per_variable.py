"""Stored bytes of every variable of a conesurvey output, per point of the survey grid.

Usage: .venv/bin/python scripts/bytes_per_variable.py OUT.nc|OUT.zarr
       .venv/bin/python scripts/bytes_per_variable.py --tiny   (a 2,560-point survey run here first)

Prints, for each variable, its dims, its stored (compressed) bytes and those bytes divided by
the number of points of the survey grid (the product of the axes' sizes), then the whole file
or store. docs/output.md ("Where the bytes go") quotes it on the 10^7-point slice of
``surveys/large_1e8.toml``.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path


def _netcdf(path: Path) -> dict[str, tuple[tuple[str, ...], int, tuple[int, ...]]]:
    import h5py

    out = {}
    with h5py.File(path, "r") as f:
        for name, ds in f.items():
            if not isinstance(ds, h5py.Dataset):
                continue
            dims = tuple(
                Path(d[0].name).name for d in (ds.dims[i] for i in range(ds.ndim)) if len(d)
            )
            out[name] = (dims or (name,), ds.id.get_storage_size(), ds.shape)
    return out


def _zarr(path: Path) -> dict[str, tuple[tuple[str, ...], int, tuple[int, ...]]]:
    import json

    out = {}
    for entry in sorted(path.iterdir()):
        meta = entry / "zarr.json"
        if not meta.is_file():
            continue
        doc = json.loads(meta.read_text())
        dims = tuple(doc.get("dimension_names") or ())
        size = sum((Path(d) / f).stat().st_size for d, _, files in os.walk(entry) for f in files)
        out[entry.name] = (dims, size, tuple(doc.get("shape", ())))
    return out


TINY = """title = "tiny"
method = "exact"
[axes.alpha]
values = [0.8]
[axes.energy]
start = 1e-6
stop = 10.0
num = 40
scale = "log"
relative_to = "V_min"
[axes.h]
values = [-1.0, 0.0, 1.0, 2.0]
[axes.Lz]
start = 0.1
stop = 2.0
num = 16
"""


def _tiny() -> Path:
    """A tiny survey run into ./tiny.nc (the scripts' test)."""
    from engine.cli import main as cli

    Path("tiny.toml").write_text(TINY)
    if cli(["run", "tiny.toml", "-o", "tiny.nc", "-q", "--overwrite"]) != 0:
        raise SystemExit("the tiny survey failed")
    return Path("tiny.nc")


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("\n".join(__doc__.strip().splitlines()[2:4]), file=sys.stderr)
        return 2
    path = _tiny() if argv[1] == "--tiny" else Path(argv[1])
    table = _zarr(path) if path.is_dir() else _netcdf(path)
    axes = {n: v for n, v in table.items() if v[0] == (n,)}
    points = math.prod(v[2][0] for v in axes.values())
    total = (
        sum(Path(d, f).stat().st_size for d, _, fs in os.walk(path) for f in fs)
        if path.is_dir()
        else path.stat().st_size
    )
    print(f"{'variable':<18} {'dims':<26} {'bytes':>13} {'bytes/point':>12}")
    for name, (dims, size, _) in table.items():
        if name in axes:
            continue
        print(f"{name:<18} {','.join(dims):<26} {size:>13,} {size / points:>12.3f}")
    print(f"{'(whole output)':<18} {'':<26} {total:>13,} {total / points:>12.3f}")
    print(f"points: {points:,}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

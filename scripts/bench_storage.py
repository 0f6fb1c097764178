"""The write path of a streamed run against its two limits: the compute alone and the disk.

Usage: .venv/bin/python scripts/bench_storage.py [SURVEY.toml] [--alpha A] [--dir DIR] [--zarr]
                                       [--rounds R] [--workers N [N ...]]
       .venv/bin/python scripts/bench_storage.py --page-cache [--rounds R] [--dir DIR]
       .venv/bin/python scripts/bench_storage.py --tiny   (a 10,240-point survey, seconds)

Default survey: ``surveys/large_1e8.toml``; ``--alpha 0.8`` runs its 10^7-point slice (the
alpha axis replaced by that one value). In one process, one after the other:

1. **compute alone**: every block of the survey evaluated as a run evaluates it
   (:func:`engine.backends.compute_block`), nothing stored: wall and CPU time, points/s;
2. **the runs**: ``run_survey`` into ``DIR/bench_R.nc`` (and ``DIR/bench_R.zarr`` with
   ``--zarr``, the two formats interleaved for ``--rounds`` rounds, each round in the other
   order; ``--workers``: on a dask LocalCluster of N workers, one run per N): wall and CPU
   time of this process (dask workers' CPU is not in it), bytes written (Linux:
   ``/proc/self/io``), the output's size, points/s;
3. **the disk**: a plain write of as many bytes (at most 2 GiB) in 64 MiB pieces, fsynced,
   with ``O_DIRECT`` where the file system takes it: MB/s, what the disk here takes.

``--page-cache`` times only the three ways of writing 2 GiB (through the page cache, through it
and given back as written, past it), ``--rounds`` times interleaved (docs/output.md, "The page
cache").

Then the ratios that make the goals reproducible on any machine: each run's points/s over the
compute's (1.0: writing costs the run nothing), its CPU over the compute's, the bytes it
wrote per second of wall time over the disk's MB/s (1.0: the disk is the limit), and with
``--zarr`` the Zarr run's wall time over the netCDF run's of the same round (the goal: <= 1),
their median and range. The outputs are removed only once every run is done: removing a
store of thousands of files just before the next run slows that run's file creations on some
file systems (docs/output.md, "Zarr stores"), and the formats would not be timed alike. The
load average is printed before and after (timings on a shared machine are mostly other
people's work: compare the ratios). docs/output.md quotes it.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

from bench_common import load  # noqa: E402

TINY = """title = "bench_storage --tiny"
method = "exact"

[scene]
g = 9.81
k = 0.4

[axes.alpha]
values = [0.8]

[axes.energy]
start = 1e-6
stop = 10.0
num = 40
scale = "log"
relative_to = "V_min"

[axes.h]
start = -3.0
stop = 3.0
num = 16

[axes.Lz]
start = 0.05
stop = 2.0
num = 16
"""


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _written() -> int:
    """Bytes this process has sent to storage (Linux), else 0."""
    try:
        text = Path("/proc/self/io").read_text()
    except OSError:
        return 0
    m = re.search(r"^write_bytes: (\d+)$", text, re.M)
    return int(m.group(1)) if m else 0


def _size(path: Path) -> int:
    if path.is_dir():
        return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    return path.stat().st_size


def _survey_text(path: Path, alpha: float | None) -> str:
    text = path.read_text()
    if alpha is None:
        return text
    head, sep, rest = text.partition("[axes.alpha]")
    if not sep:
        sys.exit(f"{path} has no [axes.alpha] table to replace")
    tail = rest[rest.find("\n[") :] if "\n[" in rest else "\n"
    return f"{head}[axes.alpha]\nvalues = [{alpha!r}]\n{tail}"


def compute_alone(survey) -> tuple[float, float, int]:
    """(wall s, CPU s, points) of evaluating every block of ``survey``, nothing kept."""
    from engine.backends import compute_block
    from engine.grid import Tiling
    from engine.plan import plan_from_survey

    plan = plan_from_survey(survey, "unused.nc")
    tiling = Tiling.for_grid(plan.shape, plan.output.block_points)
    compute_block(plan, tiling, 0)  # compile or load the kernels first
    w0, c0 = time.perf_counter(), _cpu()
    for i in range(tiling.nblocks):
        compute_block(plan, tiling, i)
    return time.perf_counter() - w0, _cpu() - c0, tiling.size


def run(survey, out: Path, workers: int | None) -> tuple[float, float, int, int]:
    """(wall s, CPU s of this process, bytes written, output bytes) of a run into ``out``."""
    from engine.runner import run_survey

    b0, w0, c0 = _written(), time.perf_counter(), _cpu()
    run_survey(survey, out, workers=workers, warn=lambda msg: None)
    wall, cpu, wrote = time.perf_counter() - w0, _cpu() - c0, _written() - b0
    return wall, cpu, wrote, _size(out)


def disk(where: Path, nbytes: int) -> float:
    """MB/s of a plain write of ``nbytes`` (64 MiB pieces, fsynced) into a file in ``where``,
    past the page cache where the file system takes it (``O_DIRECT``, as the block files are
    written: what the disk takes, not what filling the cache costs)."""
    from engine.io.pagecache import DirectWriter

    piece = os.urandom(1 << 20) * 64
    todo = max(len(piece), nbytes)
    path = where / "bench_storage_disk.tmp"
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        t0 = time.perf_counter()
        sink, done = DirectWriter(fd), 0
        while done < todo:
            done += sink.write(piece[: min(len(piece), todo - done)])
        sink.close()
        os.fsync(fd)
        return done / 1e6 / (time.perf_counter() - t0)
    finally:
        os.close(fd)
        path.unlink()


def _free_mb() -> float:
    """MemFree [MB] (Linux), NaN elsewhere."""
    try:
        text = Path("/proc/meminfo").read_text()
    except OSError:
        return float("nan")
    m = re.search(r"^MemFree:\s+(\d+) kB$", text, re.M)
    return int(m.group(1)) / 1e3 if m else float("nan")


def page_cache(where: Path, rounds: int, nbytes: int = 2 << 30) -> None:
    """Print, for each way of writing ``nbytes`` in 64 MiB pieces (fsynced at the end), its
    wall time, the system time and GB/s, ``rounds`` times interleaved: through the page cache;
    through it, given back every 256 MiB (``fdatasync`` + ``POSIX_FADV_DONTNEED``, as a netCDF
    run's output); past it (``O_DIRECT``, as the block files). The free memory before each says
    what the cache could take (docs/output.md, "The page cache")."""
    from engine.io.pagecache import DirectWriter

    piece = os.urandom(1 << 20) * 64
    for r in range(rounds):
        for how in ("cache", "given back", "O_DIRECT"):
            path = where / f"bench_storage_{r}_{how[0]}.tmp"
            free, t0, s0 = _free_mb(), time.perf_counter(), resource.getrusage(0).ru_stime
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            try:
                sink = DirectWriter(fd) if how == "O_DIRECT" else None
                for i in range(nbytes // len(piece)):
                    sink.write(piece) if sink else os.write(fd, piece)
                    if how == "given back" and i % 4 == 3:
                        os.fdatasync(fd)
                        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
                if sink:
                    sink.close()
                os.fsync(fd)
            finally:
                os.close(fd)
            wall, sys_s = time.perf_counter() - t0, resource.getrusage(0).ru_stime - s0
            print(f"write {nbytes / 1e9:.2f} GB, {how:>10}: {wall:.2f} s wall, {sys_s:.2f} s "
                  f"system, {nbytes / 1e9 / wall:.2f} GB/s (free memory before: "
                  f"{free:,.0f} MB)")  # fmt: skip
    for path in where.glob("bench_storage_*.tmp"):  # kept until all are done, as the runs
        path.unlink()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("survey", nargs="?", type=Path, default=ROOT / "surveys" / "large_1e8.toml")
    ap.add_argument("--alpha", type=float, help="run the slice at this one alpha")
    ap.add_argument("--dir", type=Path, help="where to write (default: a temporary folder)")
    ap.add_argument("--zarr", action="store_true", help="also run into a Zarr store")
    ap.add_argument("--rounds", type=int, default=1, help="runs of each format (interleaved)")
    ap.add_argument("--workers", type=int, nargs="*", default=[], help="dask LocalCluster sizes")
    ap.add_argument("--tiny", action="store_true", help="a 10,240-point survey (a smoke test)")
    ap.add_argument("--page-cache", action="store_true",
                    help="only time 2 GiB written through, given back from and past the page "
                         "cache, --rounds times")  # fmt: skip
    args = ap.parse_args()
    if args.rounds < 1:
        ap.error(f"--rounds must be at least 1, not {args.rounds}")
    args.zarr = args.zarr or args.tiny

    from engine.surveyfile import parse_survey

    text = TINY if args.tiny else _survey_text(args.survey, args.alpha)
    survey = parse_survey(text)
    where = Path(tempfile.mkdtemp(prefix="bench_storage_", dir=args.dir))
    print(f"load average before: {load()}; {os.cpu_count()} cores; writing in {where}")
    if args.page_cache:
        try:
            page_cache(where, args.rounds, (64 << 20) if args.tiny else (2 << 30))
        finally:
            shutil.rmtree(where, ignore_errors=True)
        print(f"load average after: {load()}")
        return
    try:
        wall, cpu, points = compute_alone(survey)
        rate = points / wall
        print(f"compute alone: {points:,} points, {wall:.2f} s wall, {cpu:.2f} s CPU, "
              f"{rate:,.0f} points/s")  # fmt: skip
        fmts = [("netCDF (default)", ".nc")] + ([("Zarr", ".zarr")] if args.zarr else [])
        runs = []
        for r in range(args.rounds):  # each round in the other order
            runs += [(f"{label}, round {r + 1}", where / f"bench_{r + 1}{ext}", None)
                     for label, ext in (fmts if r % 2 == 0 else fmts[::-1])]  # fmt: skip
        runs += [(f"netCDF, --workers {n}", where / f"bench_w{n}.nc", n) for n in args.workers]
        most = 0
        results = {}
        for label, out, workers in runs:  # every output kept until all are done
            results[label] = run(survey, out, workers)
            most = max(most, results[label][2])
        mbs = disk(where, min(most, 2 << 30))
        print(f"disk: a plain write of {min(max(most, 1 << 26), 2 << 30) / 1e6:,.0f} MB, "
              f"fsynced: {mbs:,.0f} MB/s")  # fmt: skip
        for label, (r_wall, r_cpu, wrote, size) in results.items():
            times = wrote / size if size else 0.0
            print(f"run, {label}: {r_wall:.2f} s wall, {r_cpu:.2f} s CPU (this process), "
                  f"{points / r_wall:,.0f} points/s; wrote {wrote / 1e6:,.0f} MB "
                  f"({times:.2f}x the output's {size / 1e6:,.1f} MB)")  # fmt: skip
            print(f"  run / compute alone: {points / r_wall / rate:.2f} of the points/s, "
                  f"{r_cpu / cpu:.2f}x the CPU; bytes written per second / disk: "
                  f"{wrote / 1e6 / r_wall / mbs:.2f}")  # fmt: skip
        if args.zarr:
            ratios = [results[f"Zarr, round {r}"][0] / results[f"netCDF (default), round {r}"][0]
                      for r in range(1, args.rounds + 1)]  # fmt: skip
            rounds = f"{len(ratios)} round{'s' if len(ratios) > 1 else ''}"
            mid = statistics.median(ratios)
            lo, hi = min(ratios), max(ratios)
            print(f"Zarr / netCDF wall time, same round: median {mid:.2f} "
                  f"(min {lo:.2f}, max {hi:.2f}, {rounds}; goal <= 1)")  # fmt: skip
    finally:
        shutil.rmtree(where, ignore_errors=True)
    print(f"load average after: {load()}")


if __name__ == "__main__":
    main()

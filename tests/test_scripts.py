"""Every script in scripts/ runs: each in its --tiny mode (seconds on a warm compile cache), in a
fresh interpreter whose working directory is a temporary folder, where the scripts that draw
figures write them by default (and nowhere in the checkout); the helper modules through their
functions. heyoka and Chromium may be absent: the scripts then say so and run the rest. The
documents run the scripts with the environment's interpreter, and the ``bench`` extra installs
what the benchmarks import."""

from __future__ import annotations

import ast
import importlib.metadata
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "scripts"
sys.path.insert(0, str(SCRIPTS))

import figure_cli  # noqa: E402
import readme_block  # noqa: E402

#: script -> (extra arguments, with {tmp} for the temporary folder; text its output must hold;
#: the files it writes into the working directory, where it runs without --out).
TINY = {
    "bench_effects.py": ([], "generic scalar run kernel / hand-written DP5", ()),
    "bench_estimate.py": ([], "worst estimate/run either way", ()),
    "bench_exact.py": ([], "load average", ()),
    "bench_exact_surfaces.py": ([], "dop853 (lanes) / exact", ()),
    "bench_fates.py": ([], "2-thread speedup of the fate map", ()),
    "bench_integrators.py": ([], "heyoka", ()),
    "bench_slide.py": ([], "2-thread speedup", ()),
    "bench_storage.py": ([], "Zarr / netCDF wall time, same round", ()),
    "bytes_per_variable.py": ([], "bytes/point", ("tiny.toml", "tiny.nc")),
    "energy_drift.py": ([], "wrote", ("energy_drift.png",)),
    "fate_figures.py": ([], "", ("fate_map.png", "fate_time.png", "slip_map.png")),
    "figures.py": ([], "", ("potential.png", "class_map_free_fall.png", "gravity_maps.png",
                            "rosette.png", "free_fall_orbits.png")),
    "integrator_peers.py": ([], "scipy DOP853", ()),
    "look_figures.py": ([], "wrote", ("plot_precession.png",)),
    "slide_figures.py": ([], "launches in", ("slide_and_roll.png",)),
    "work_precision.py": ([], "wrote", ("work_precision.nc", "work_precision.png",
                                        "work_precision_peers.nc", "work_precision_peers.png")),
}  # fmt: skip
#: Where the checkout keeps what the scripts could overwrite: the documents and their figures.
TRACKED = ("README.md", "CONTRIBUTING.md", "docs", "data", "surveys")
#: Modules the scripts import, not scripts themselves (figure_cli and readme_block tested below
#: through their functions; bench_common through the benchmarks' tiny runs above).
HELPERS = {"figure_cli.py", "readme_block.py", "bench_common.py"}


def test_every_script_is_run_here():
    assert {p.name for p in SCRIPTS.glob("*.py")} == set(TINY) | HELPERS


def _stamps() -> dict[str, tuple[int, int]]:
    """Size and modification time of every file of :data:`TRACKED`."""
    out = {}
    for name in TRACKED:
        for p in [ROOT / name, *(ROOT / name).rglob("*")]:
            if p.is_file():
                out[str(p.relative_to(ROOT))] = (p.stat().st_size, p.stat().st_mtime_ns)
    return out


@pytest.mark.parametrize("script", sorted(TINY))
def test_script_runs_in_its_tiny_mode(script, tmp_path):
    """Each script's smoke run, in a fresh interpreter: it succeeds, says what it should,
    writes its files into the working directory (no --out given) and leaves the checkout's
    documents and figures as they were."""
    extra, expect, writes = TINY[script]
    args = [a.format(tmp=tmp_path) for a in extra]
    before = _stamps()
    res = subprocess.run(
        [sys.executable, str(SCRIPTS / script), "--tiny", *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    assert expect in res.stdout, res.stdout[-2000:]
    for name in writes:
        assert (tmp_path / name).stat().st_size > 0, f"{name} not written in the working folder"
    changed = {k for k, v in _stamps().items() ^ before.items()}
    assert not changed, f"{script} wrote into the checkout: {sorted(changed)}"


def test_the_figure_scripts_write_where_out_says(tmp_path):
    """``--out DIR``: the figures go there (here a folder that is not the working one)."""
    out = tmp_path / "figs"
    res = subprocess.run(
        [sys.executable, str(SCRIPTS / "figures.py"), "--tiny", "--only", "potential",
         "--out", str(out)],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-3000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figs"]
    assert (out / "potential.png").read_bytes()[:4] == b"\x89PNG"


#: A command that runs Python by a bare name (``python scripts/x.py``, ``python -m pytest``):
#: in a fresh shell that is the system's interpreter, without conesurvey's dependencies.
BARE_PYTHON = re.compile(r"(^|[^/.\w-])python3? (scripts/|-m (?!venv)|-c )")


def test_documents_run_python_from_the_environment():
    """Every command in the documents (and in the scripts' own usage lines) runs Python as
    ``.venv/bin/python``, the environment the README installs conesurvey into."""
    docs = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md")),
            *sorted(SCRIPTS.glob("*.py"))]  # fmt: skip
    bare = [
        f"{p.relative_to(ROOT)}:{i}: {line.strip()}"
        for p in docs
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if BARE_PYTHON.search(line)
    ]
    assert not bare, "\n".join(bare)


#: The scripts the documents run with the ``bench`` extra installed.
BENCH = (
    "bench_effects.py",
    "bench_exact.py",
    "bench_fates.py",
    "bench_integrators.py",
    "bench_slide.py",
    "energy_drift.py",
    "integrator_peers.py",
    "work_precision.py",
)


def _imports(path: Path, seen: set[Path]) -> set[str]:
    """Top-level names of the modules ``path`` imports, and those its local modules (in
    scripts/ and tests/, which work_precision.py puts on its path) import, anywhere."""
    seen.add(path)
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    for name in list(names):
        for folder in (SCRIPTS, ROOT / "tests"):
            local = folder / f"{name}.py"
            if local.exists():
                names.discard(name)
                if local not in seen:
                    names |= _imports(local, seen)
    return names


def _requirement_names(reqs: list[str]) -> set[str]:
    return {re.split(r"[<>=!~ \[;]", r, maxsplit=1)[0].lower().replace("_", "-") for r in reqs}


def test_the_bench_extra_installs_what_the_benchmarks_import():
    """Every third-party module the benchmark scripts import (mpmath: work_precision.py's
    oracle) is a dependency of conesurvey or of its ``bench`` extra."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    allowed = _requirement_names(project["dependencies"])
    allowed |= _requirement_names(project["optional-dependencies"]["bench"])
    dists = importlib.metadata.packages_distributions()
    missing = {}
    for script in BENCH:
        for name in _imports(SCRIPTS / script, set()):
            if name in sys.stdlib_module_names or name in ("engine", "__future__"):
                continue
            needs = {d.lower().replace("_", "-") for d in dists.get(name, [name])}
            if not needs & allowed:
                missing.setdefault(script, set()).add(name)
    assert not missing, missing


def test_readme_block_replaces_only_its_block(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("a\n<!-- t: start -->\nold\n<!-- t: end -->\nb\n")
    readme_block.update_readme("t", "new", readme)
    assert readme.read_text() == "a\n<!-- t: start -->\nnew\n<!-- t: end -->\nb\n"
    with pytest.raises(SystemExit, match="no <!-- u: start -->"):
        readme_block.update_readme("u", "x", readme)


def test_figure_cli_runs_a_command_and_stops_on_failure(tmp_path, capsys):
    small = figure_cli.shrunk(ROOT / "surveys" / "slip_map.toml", tmp_path)
    assert "num = 3" in small.read_text()
    figure_cli.conesurvey("validate", small)
    assert "valid" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="conesurvey validate failed with status 2"):
        figure_cli.conesurvey("validate", tmp_path / "missing.toml")


def test_the_benchmarks_timing_loop_interleaves_and_keeps_the_best():
    """bench_common.interleaved: each round calls every function once, in turn; the best time
    of each by each clock (a fake clock here: its readings are the test's own numbers)."""
    from bench_common import first_calls, interleaved, verdict

    order = []
    ticks = iter([0.0, 5.0, 5.0, 6.0, 10.0, 12.0, 12.0, 19.0, 20.0, 23.0, 23.0, 24.0])
    fns = {"a": lambda: order.append("a"), "b": lambda: order.append("b")}
    best = interleaved(fns, 3, (lambda: next(ticks),))
    assert order == ["a", "b"] * 3
    assert best == {"a": (2.0,), "b": (1.0,)}  # a: 5, 2, 3; b: 1, 7, 1
    seconds, results = first_calls({"x": lambda: 42})
    assert results == {"x": 42} and seconds["x"] >= 0.0
    assert (verdict(2.0, 2.0), verdict(1.9, 2.0)) == ("met", "MISSED")


def test_bench_storage_times_the_three_ways_through_the_page_cache(tmp_path):
    """``bench_storage.py --page-cache``: the rows docs/output.md ("The page cache") quotes,
    each once in --tiny (64 MiB), the files it wrote removed."""
    args = ["--page-cache", "--tiny", "--dir", str(tmp_path)]
    res = subprocess.run(
        [sys.executable, str(SCRIPTS / "bench_storage.py"), *args],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    for how in ("cache", "given back", "O_DIRECT"):
        assert re.search(rf"{how}: [\d.]+ s wall, [\d.]+ s system, [\d.]+ GB/s", res.stdout), (
            res.stdout
        )
    assert not list(tmp_path.rglob("*.tmp")), "a timed file was left behind"

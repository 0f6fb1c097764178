"""The package writes nothing into its own directory (issue 11, item 9): numba's compile cache
goes to the per-user cache directory (engine/_jit.py), so ``pip uninstall`` leaves nothing
behind that could shadow a later editable install as a namespace package. The same cold
process shows that the API announces its compile on stderr (engine/_compiling.py)."""

from __future__ import annotations

import compileall
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import runs

CODE = """
import engine
print(float(engine.minimum_energy(0.5, 1.0, 0.8)))
"""


def _files(root: Path) -> dict[str, tuple[int, int]]:
    return {
        str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns) for p in root.rglob("*")
    }


def test_evaluating_writes_only_into_the_user_cache(tmp_path):
    """A copy of the package, byte-compiled as pip installs it; a kernel (V_min: the
    circular radius) compiled from a cold cache in a subprocess whose HOME and XDG_CACHE_HOME
    are temporary: every new file is under the cache, none under the package. (Every kernel is
    compiled through the same ``engine._jit.kernel`` and its cache locator.)"""
    pkg = tmp_path / "site" / "engine"
    shutil.copytree(runs.ROOT / "engine", pkg, ignore=shutil.ignore_patterns("__pycache__"))
    assert compileall.compile_dir(pkg, quiet=1)
    before = _files(pkg)
    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("CONESURVEY_")}
    env.update(
        PYTHONPATH=str(pkg.parent),
        HOME=str(home),
        XDG_CACHE_HOME=str(home / ".cache"),
        NUMBA_NUM_THREADS="1",
    )
    proc = subprocess.run(
        [sys.executable, "-c", CODE],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert float(proc.stdout) > 0  # V_min of a spinning sphere under gravity
    # the API says it is compiling (seconds: the closed form's lanes), once, and how long
    notice = "conesurvey: compiling kernels (first run only, cached)"
    assert proc.stderr.count(notice) == 1, proc.stderr
    assert re.search(r"^conesurvey: compiled kernels in \d+:\d\d \(cached for later runs\)$",
                     proc.stderr, re.M), proc.stderr  # fmt: skip
    assert _files(pkg) == before
    cached = [p for p in (home / ".cache" / "conesurvey").rglob("*") if p.is_file()]
    assert any(p.suffix == ".nbi" for p in cached) and any(p.suffix == ".nbc" for p in cached)

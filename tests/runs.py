"""Helpers of the tests that run the ``conesurvey`` command in subprocesses and compare files."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from engine import _jit
from engine import cli as engine_cli

ROOT = Path(__file__).resolve().parent.parent


class Computed(Sequence):
    """A list computed on first use, not when the test module is imported: with ``pytest -n``
    every worker imports (collects) every test file, so a kernel a module-level value compiles
    would be compiled by both workers at once, before any test runs (tens of seconds each on a
    cold compile cache). ``make()`` returns the list."""

    def __init__(self, make: Callable[[], list]) -> None:
        self._make = make
        self._items: list | None = None

    def _list(self) -> list:
        if self._items is None:
            self._items = self._make()
        return self._items

    def __getitem__(self, i):  # type: ignore[override]
        return self._list()[i]

    def __len__(self) -> int:
        return len(self._list())


def copy_cache(tmp_path: Path, recipe: str) -> Path:
    """The compile cache of the package copy a recipe test makes (CONESURVEY_CACHE_DIR of its
    subprocess): a directory per recipe beside the package's own cache, so that the next run of
    the suite loads the copy's kernels instead of compiling them again (minutes). The copy's
    kernels are keyed on their content like any others (a changed source compiles again); it is
    kept apart from the package's cache because numba keeps one key per function and file, and
    the copy's keys would replace the package's. A fresh directory when caching is off."""
    if _jit.CACHE_DIR is None:
        return tmp_path / "cache"
    return _jit.CACHE_DIR.parent / "recipe-copies" / recipe


def gravity_survey(
    title: str,
    *,
    alpha: tuple[float, ...] = (0.3, 0.6, 0.9, 1.2),
    energy: int = 100,
    h: int = 33,
    lz: int = 100,
) -> str:
    """A survey under gravity with energies relative to V_min (log), h and Lz ranges; the
    default is 4 x 100 x 33 x 100 = 1.32e6 points, 32 storage chunks."""
    return f"""\
title = "{title}"

[axes.alpha]
values = [{", ".join(map(repr, alpha))}]

[axes.energy]
start = 1e-6
stop = 10.0
num = {energy}
scale = "log"
relative_to = "V_min"

[axes.h]
start = -2.0
stop = 2.0
num = {h}

[axes.Lz]
start = 0.05
stop = 1.0
num = {lz}
"""


def free_fall_survey(title: str, *, energy: int = 7, lz: tuple[float, ...] = (-0.5, 0.5)) -> str:
    """A small free-fall survey (several classes, NaN fields): 2 x 7 x 2 x 2 = 56 points."""
    return f"""\
title = "{title}"

[scene]
g = 0.0

[axes.alpha]
values = [0.5, 1.0]

[axes.energy]
start = -0.3
stop = 0.3
num = {energy}

[axes.h]
values = [-2.0, 2.0]

[axes.Lz]
values = [{", ".join(map(repr, lz))}]
"""


def env(**extra: str) -> dict[str, str]:
    """The environment of a subprocess that imports this checkout's ``engine``."""
    out = dict(os.environ)
    out["PYTHONPATH"] = str(ROOT) + os.pathsep + out.get("PYTHONPATH", "")
    out.update(extra)
    return out


def cli(*args: str) -> list[str]:
    """The command line of ``conesurvey ARGS`` (this interpreter, this checkout)."""
    return [sys.executable, "-m", "engine.cli", *args]


def as_in_a_terminal() -> None:
    """``preexec_fn`` of a subprocess that must see its own Ctrl-C: SIGINT at its default, as a
    shell gives a command in the foreground. A test run started in the background (``cmd &``
    from a script) has SIGINT ignored, every child inherits that, and Python then keeps
    ignoring it: the child would never see the SIGINT it sends itself."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run(cwd: Path, *args: str, timeout: float = 600, **extra: str) -> subprocess.CompletedProcess:
    """``conesurvey ARGS`` in ``cwd``, to completion (text output captured)."""
    return subprocess.run(
        cli(*args), cwd=cwd, env=env(**extra), capture_output=True, text=True, timeout=timeout
    )


def here(cwd: Path, capsys, *args: str) -> subprocess.CompletedProcess:
    """``conesurvey ARGS`` run in this process, in ``cwd`` (no interpreter start: for the
    checks around an attack, and for inputs that cannot hang)."""
    capsys.readouterr()
    with contextlib.chdir(cwd):
        status = engine_cli.main(list(args))
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(args, status, out, err)


def listing(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


def blocks_in(parts: Path) -> int:
    """Committed block files in a block store (0 if it does not exist)."""
    try:
        names = os.listdir(parts)
        return sum(1 for n in names if n.startswith("b") and n.endswith((".npz", ".chunks")))
    except FileNotFoundError:
        return 0


def kill_when(proc: subprocess.Popen, ready: Callable[[], bool], timeout: float = 300) -> bool:
    """SIGKILL ``proc`` as soon as ``ready()``; False if it ended first."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if ready():
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=60)
            return True
        time.sleep(0.005)
    proc.wait(timeout=60)
    return False


def same_content(a: Path, b: Path) -> None:
    """The files hold the same variables, values (NaN too, bit for bit) and attributes, except
    the global ``history``."""
    with xr.open_dataset(a) as x, xr.open_dataset(b) as y:
        x.load()
        y.load()
    assert set(x.variables) == set(y.variables)
    for name in x.variables:
        np.testing.assert_array_equal(x[name].values, y[name].values, err_msg=name)
        assert x[name].attrs.keys() == y[name].attrs.keys()
        for key, value in x[name].attrs.items():
            np.testing.assert_array_equal(value, y[name].attrs[key])
    keys = set(x.attrs) - {"history"}
    assert keys == set(y.attrs) - {"history"}
    for key in keys:
        np.testing.assert_array_equal(x.attrs[key], y.attrs[key], err_msg=key)

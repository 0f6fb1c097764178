"""Grids no machine holds are refused before anything is allocated: ``validate`` and ``run``
(a subprocess each, bounded in time and memory) say exit 2 within seconds, naming the size and
what a survey may span, and write nothing."""

from __future__ import annotations

import resource
import subprocess
import sys

import pytest
import runs

from engine.runner import RunError, run_survey
from engine.surveyfile import parse_survey


def survey_of(num: int) -> str:
    """4 range axes of ``num`` points each (a few kB of text)."""
    axes = "".join(
        f"\n[axes.{name}]\nstart = {lo}\nstop = {hi}\nnum = {num}\n"
        for name, lo, hi in (("alpha", 0.1, 1.4), ("energy", 0.1, 9.0), ("h", -2, 2),
                             ("Lz", 0.05, 1.0))
    )  # fmt: skip
    return f'title = "huge"\n{axes}'


def _limited() -> None:
    """The child's address space capped at 4 GiB: a run that lists its blocks dies fast."""
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))


@pytest.mark.parametrize(("num", "points"), [(1800, "1.05e+13"), (10**5, "1e+20")])
@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_grid_no_machine_holds_is_refused_at_once(tmp_path, command, num, points):
    (tmp_path / "s.toml").write_text(survey_of(num))
    args = ["validate", "s.toml"] if command == "validate" else ["run", "s.toml", "-o", "o.nc"]
    try:
        proc = subprocess.run(
            runs.cli(*args), cwd=tmp_path, env=runs.env(), capture_output=True, text=True,
            timeout=60, preexec_fn=_limited,
        )  # fmt: skip
    except subprocess.TimeoutExpired:
        pytest.fail(f"{command} of a {points}-point grid still running after 60 s")
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr[-2000:])
    err = proc.stderr
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert f"the grid has {points} points" in err and "1,099,511,627,776" in err, err
    assert "s.toml: axes:" in err, err
    assert runs.listing(tmp_path) == ["s.toml"]


API = """
import dataclasses, sys
import numpy as np
from engine.runner import RunError, run_survey
from engine.surveyfile import parse_survey
small = parse_survey(sys.argv[1])
axis = np.broadcast_to(np.float64(0.5), (10**4,))  # 10^14 points, no memory
huge = dataclasses.replace(small, energy=axis, h=axis, Lz=axis, alpha=axis[:100])
try:
    run_survey(huge, "o.nc")
except RunError as exc:
    print(exc)
"""


def test_the_api_refuses_a_grid_built_in_python(tmp_path):
    """A Survey whose axes were built in Python (no survey file) is refused by the runner
    before the lock is taken (a subprocess, bounded in time and memory)."""
    try:
        proc = subprocess.run(
            [sys.executable, "-c", API, survey_of(2)], cwd=tmp_path, env=runs.env(),
            capture_output=True, text=True, timeout=60, preexec_fn=_limited,
        )  # fmt: skip
    except subprocess.TimeoutExpired:
        pytest.fail("a 1e14-point run still running after 60 s")
    assert proc.returncode == 0 and "the grid has 1e+14 points" in proc.stdout, proc
    assert list(tmp_path.iterdir()) == []


def test_too_many_blocks_are_refused_naming_the_block_size(tmp_path):
    """A grid that fits but cut into more blocks than a run lists: the block size that
    would do is named."""
    survey = parse_survey(survey_of(1000))  # 1e12 points, 2^16-point chunks
    with pytest.raises(RunError, match=r"give --block-points \d+ or more"):
        run_survey(survey, tmp_path / "o.nc", block_points=1)
    assert list(tmp_path.iterdir()) == []

"""A killed ``run --overwrite`` resumes when the same command is run again: the replacement
run's stored blocks are verified and reused, the old output is replaced only at the end."""

from __future__ import annotations

import subprocess

import pytest
import runs

from engine.runner import run_survey
from engine.surveyfile import parse_survey

# 4 x 20 x 33 x 100 = 264,000 points in 8 blocks
SURVEY = runs.gravity_survey("overwrite resume", energy=20)
OLD = runs.gravity_survey("the old output", energy=20)


@pytest.mark.parametrize("out", ["out.nc", "out.zarr"])
def test_a_killed_run_overwrite_resumes_with_the_same_command(tmp_path, out, capsys):
    if out.endswith(".zarr"):
        pytest.importorskip("zarr")
    (tmp_path / "s.toml").write_text(SURVEY)
    run_survey(parse_survey(OLD), tmp_path / out, block_points=65536)  # the output replaced
    args = ("run", "s.toml", "-o", out, "--block-points", "65536", "--overwrite")
    journal = tmp_path / f"{out}.parts" / "journal"

    def stored() -> bool:
        try:
            return journal.read_bytes().count(b"\n") >= 3
        except FileNotFoundError:
            return False

    proc = subprocess.Popen(runs.cli(*args), cwd=tmp_path, env=runs.env(), stderr=subprocess.PIPE)
    assert runs.kill_when(proc, stored, timeout=300), "finished first"
    again = runs.here(tmp_path, capsys, *args)  # the same command, in this process
    assert again.returncode == 0, again.stderr
    assert "blocks from an earlier run" in again.stdout, again.stdout + again.stderr
    assert "discarded" not in again.stderr, again.stderr
    verified = runs.here(tmp_path, capsys, "info", out, "--verify")
    assert verified.returncode == 0 and "the old output" not in verified.stdout, verified.stdout
    assert "overwrite resume" in verified.stdout

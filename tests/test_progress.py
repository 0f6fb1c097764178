"""The progress display of a resumed run: it says that it resumes (how many stored blocks were
verified and kept) and its rates count only the points it computes itself."""

from __future__ import annotations

import io
import re

from look_cases import GRAVITY, unfinished_run

from engine import cli
from engine.progress import Progress


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_a_resumed_run_rates_only_the_points_it_computes():
    """900 of 1,000 points were stored by an earlier run; this run computes 50 in 1 s: 50
    points/s, and the 50 left take 1 s (counting the stored points: 950 points/s)."""
    stream, clock = io.StringIO(), Clock()
    p = Progress(stream, tty=False, clock=clock)
    p.resumed(9, 10, 900, 1000)
    p(900, 1000)
    clock.t = 2.0
    p(950, 1000)
    lines = stream.getvalue().splitlines()
    assert lines[0] == (
        "conesurvey: resuming: 9 of 10 blocks verified and kept (900 of 1,000 points); 1 to compute"
    )
    assert lines[1] == "conesurvey: 900/1,000 points (90.0%), ? points/s, ? left"
    assert lines[2] == "conesurvey: 950/1,000 points (95.0%), 25 points/s, 0:02 left"


def test_run_says_it_resumes_and_its_first_rate_leaves_out_the_stored_blocks(
    tmp_path, monkeypatch, capsys
):
    """A real resume through ``conesurvey run``: 6 of 18 blocks stored by a killed run."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "grav.toml").write_text(GRAVITY)
    keep = [0, 3, 4, 8, 10, 15]
    _, _, tiling = unfinished_run(GRAVITY, tmp_path / "grav.nc", (1, 4, 1, 5), (1, 4, 3, 10), keep)
    kept = sum(tiling.points(i) for i in keep)
    assert cli.main(["run", "grav.toml", "-o", "grav.nc"]) == 0
    err = capsys.readouterr().err
    assert (
        f"resuming: 6 of 18 blocks verified and kept ({kept:,} of {tiling.size:,} points); "
        "12 to compute" in err
    )
    first = [line for line in err.splitlines() if re.search(r"\d points \(", line)][0]
    assert first.startswith(f"conesurvey: {kept:,}/{tiling.size:,} points")
    assert "? points/s" in first or " 0 points/s" in first  # none computed by this run yet

"""Draw the README's "Look at the results" figures with the ``conesurvey`` commands themselves.

    .venv/bin/python scripts/look_figures.py --out docs/figures

- ``plot_precession.png``: ``conesurvey plot`` of the precession rate of
  ``surveys/gravity_precession.toml``, one map per cone angle (``--facet alpha``);
- ``report.png``: the top of ``conesurvey report`` of the same survey, as headless Chromium
  shows it (Debian's ``chromium``; ``bash .ci/system-packages`` installs it).

The survey (336,000 points, exact method) runs in a temporary directory in a few seconds.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from figure_cli import TINY_HELP, add_out, shrunk  # noqa: E402
from figure_cli import conesurvey as _cli  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SURVEY = ROOT / "surveys" / "gravity_precession.toml"
CHROMIUM = "/usr/bin/chromium"
FLAGS = (
    "--headless --no-sandbox --disable-gpu --disable-background-networking "
    "--disable-component-update --disable-sync --no-first-run --hide-scrollbars"
).split()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_out(parser)
    parser.add_argument("--width", type=int, default=1200, help="browser window [px]")
    parser.add_argument("--height", type=int, default=1500, help="screenshot height [px]")
    parser.add_argument("--tiny", action="store_true", help=TINY_HELP)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="conesurvey-look-") as tmp:
        work = Path(tmp)
        nc = work / "gravity_precession.nc"
        _cli("run", shrunk(SURVEY, work) if args.tiny else SURVEY, "-o", nc, "-q")
        plot = args.out / "plot_precession.png"
        _cli("plot", nc, "precession_rate", "--facet", "alpha", "-o", plot, "--overwrite")
        page = work / "report.html"
        _cli("report", nc, "-o", page)
        shot = work / "report.png"
        if not Path(CHROMIUM).exists():
            print(f"wrote {plot} and {page.stat().st_size:,} B of report; no {CHROMIUM}: the "
                  "report's screenshot is not taken")  # fmt: skip
            return
        subprocess.run(
            [
                CHROMIUM,
                *FLAGS,
                f"--user-data-dir={work / 'profile'}",
                f"--window-size={args.width},{args.height}",
                f"--screenshot={shot}",
                page.as_uri(),
            ],
            check=True,
            capture_output=True,
        )
        shutil.copyfile(shot, args.out / "report.png")
        print(f"wrote {plot} and {args.out / 'report.png'} ({page.stat().st_size:,} B report)")


if __name__ == "__main__":
    main()

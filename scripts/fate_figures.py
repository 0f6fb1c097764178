"""Draw the README's figures of "What a map means for each scene" with the ``conesurvey``
commands themselves.

    .venv/bin/python scripts/fate_figures.py --out docs/figures

- ``fate_map.png``: what happens to a ball with rolling resistance launched at r0 with speed
  v0 inside a finite cone (``surveys/fate_rolling_resistance.toml``, rk45 fate map);
- ``fate_time.png``: when it happens (the same run);
- ``slip_map.png``: where rolling fails for mu = 0.25 (``surveys/slip_map.toml``, exact).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from figure_cli import TINY_HELP, add_out, shrunk  # noqa: E402
from figure_cli import conesurvey as _cli  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_out(parser)
    parser.add_argument("--tiny", action="store_true", help=TINY_HELP)
    args = parser.parse_args()
    out = args.out
    with tempfile.TemporaryDirectory() as tmp:
        fate = Path(tmp) / "fate.nc"
        slip = Path(tmp) / "slip.nc"
        surveys = [
            ROOT / "surveys" / "fate_rolling_resistance.toml",
            ROOT / "surveys" / "slip_map.toml",
        ]
        if args.tiny:
            surveys = [shrunk(s, Path(tmp)) for s in surveys]
        _cli("run", surveys[0], "-o", fate, "-q")
        _cli("run", surveys[1], "-o", slip, "-q")
        common = ("--x", "v0", "--y", "r0", "--facet", "alpha", "--overwrite")
        _cli("plot", fate, "fate", *common, "-o", out / "fate_map.png")
        _cli("plot", fate, "fate_time", *common, "-o", out / "fate_time.png")
        _cli("plot", slip, "orbit_class", "--x", "Lz", "--y", "h", "--facet", "alpha",
             "--overwrite", "-o", out / "slip_map.png")  # fmt: skip


if __name__ == "__main__":
    main()

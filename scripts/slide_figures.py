"""Draw the launch map of the whole story (sliding, rolling again, spin friction) from the
shipped survey ``surveys/slide_and_roll.toml``: a ball thrown outward on a wide cone with
radial speed u0 and a slip velocity slip_u at release (backspin a omega0 = slip_u - u0),
orbiting at v0, in two panels: coloured by its fate, and by the total time it slid.

    conesurvey run surveys/slide_and_roll.toml -o slide.nc
    .venv/bin/python scripts/slide_figures.py --nc slide.nc --out docs/figures

Without ``--nc`` the survey file is run here (``engine.surveyfile.load_survey(...).run()``,
the same map). Writes ``slide_and_roll.png`` into ``--out`` (default: the working
directory). ``--tiny`` runs the file on a 3 x 3 launch grid.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
from figure_cli import add_out  # noqa: E402  (scripts/, the script's folder)
from matplotlib.colors import BoundaryNorm, ListedColormap  # noqa: E402

from engine.surveyfile import parse_survey  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SURVEY = ROOT / "surveys" / "slide_and_roll.toml"
COLOURS = {"rolling": "#4c72b0", "sliding": "#dd8452", "spilled": "#c44e52", "rest": "#55a868",
           "vertex": "#8172b3", "failed": "#000000"}  # fmt: skip


def run_survey(tiny: bool) -> xr.Dataset:
    """The shipped survey's map (``tiny``: its u0 and slip_u axes cut to 3 points each)."""
    text = SURVEY.read_text()
    if tiny:
        for num in ("num = 60", "num = 70"):
            assert text.count(num) == 1, num
            text = text.replace(num, "num = 3")
    return parse_survey(text, origin=str(SURVEY)).run()


def launch_panels(ds: xr.Dataset) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(u0, backspin slip_u - u0, fate, slide_time) on the u0 x slip_u grid (2-D, [slip, u0])."""
    sel = ds.isel({d: 0 for d in ds["fate"].dims if d not in ("u0", "slip_u")})
    sel = sel.transpose("slip_u", "u0")
    U, S = np.meshgrid(sel["u0"].values, sel["slip_u"].values)
    return U, S - U, sel["fate"].values, sel["slide_time"].values


def draw(ds: xr.Dataset, path: Path) -> dict[str, int]:
    meanings = ds["fate"].attrs["flag_meanings"].split()
    values = [int(v) for v in np.atleast_1d(ds["fate"].attrs["flag_values"])]
    code = dict(zip(meanings, values, strict=True))
    U, B, fate, slide = launch_panels(ds)
    names = [nm for nm in COLOURS if nm in code and (fate == code[nm]).any()] or ["rolling"]
    order = {code[nm]: i for i, nm in enumerate(names)}
    img = np.vectorize(lambda c: order.get(int(c), -1))(fate)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    cmap = ListedColormap([COLOURS[nm] for nm in names])
    norm = BoundaryNorm(np.arange(len(names) + 1) - 0.5, len(names))
    im = a1.pcolormesh(U, B, img, cmap=cmap, norm=norm, shading="nearest")
    cb = fig.colorbar(im, ax=a1, ticks=range(len(names)))
    cb.ax.set_yticklabels(names)
    t_max = ds.attrs.get("horizon_time", "")
    a1.set_title(f"fate after {t_max} s")
    im2 = a2.pcolormesh(U, B, slide, cmap="viridis", shading="nearest")
    fig.colorbar(im2, ax=a2, label="slide_time [s]")
    a2.set_title("total time sliding")
    for ax in (a1, a2):
        ax.set_xlabel("radial throw speed u0 [m/s]")
        ax.set_ylabel("backspin a omega0 = slip_u - u0 [m/s]")
    fig.suptitle(f"{ds.attrs.get('title', SURVEY.name)} (surveys/{SURVEY.name})")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return {nm: int((fate == code[nm]).sum()) for nm in names}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nc", type=Path, help="the survey's netCDF (else it is run here)")
    add_out(parser)
    parser.add_argument("--tiny", action="store_true", help="a 3x3 launch grid (tests)")
    args = parser.parse_args()
    t0 = time.perf_counter()
    ds = xr.open_dataset(args.nc) if args.nc else run_survey(args.tiny)
    dt = time.perf_counter() - t0
    args.out.mkdir(parents=True, exist_ok=True)
    counts = draw(ds, args.out / "slide_and_roll.png")
    how = f"read from {args.nc}" if args.nc else "computed, compile included"
    print(f"{ds['fate'].size} launches in {dt:.1f} s ({how}); fates {counts}")


if __name__ == "__main__":
    main()

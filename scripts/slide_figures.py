"""Draw the launch map of the whole story (sliding, rolling again, spin friction): a ball
thrown outward on a wide cone with radial speed u0 and backspin a omega0, orbiting at v0,
coloured by its fate and by the total time it slid.

    python scripts/slide_figures.py --out docs/figures [--n 48]

Writes ``slide_and_roll.png`` (two panels: fate, slide time). The scene: M = 1 kg, a = 1 cm,
k = 2/5, mu = 0.4, mu_k = 0.3, c_spin = 0.005, c_rr = 0.002, a rim at 0.6 m; alpha = 1.2,
r0 = 0.3 m, v0 = 0.5 m/s, w0 = 0; dop853 at rtol 1e-9 up to 5 s.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import BoundaryNorm, ListedColormap  # noqa: E402

from engine.kernels.hybrid import HYBRID_FATE_NAMES  # noqa: E402
from engine.scene import Scene  # noqa: E402
from engine.story import launch_fates  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENE = Scene(mu=0.4, mu_k=0.3, c_spin=0.005, c_rr=0.002, rim=0.6)
ALPHA, R0, V0 = 1.2, 0.3, 0.5
COLOURS = {"rolling": "#4c72b0", "sliding": "#dd8452", "spilled": "#c44e52", "rest": "#55a868",
           "vertex": "#8172b3", "failed": "#000000"}  # fmt: skip


def launch_map(n: int) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    u0 = np.linspace(0.05, 2.5, n)
    spin = np.linspace(0.0, 4.0, n)
    U, S = np.meshgrid(u0, spin)
    res = launch_fates(ALPHA, R0, V0, 0.0, u0=U, slip_u=U + S, slip_v=V0, scene=SCENE,
                       rtol=1e-9, horizon_time=5.0)  # fmt: skip
    return u0, spin, res


def draw(u0, spin, res, path: Path) -> None:
    names = [nm for nm in COLOURS if nm in HYBRID_FATE_NAMES]
    codes = np.array([HYBRID_FATE_NAMES.index(nm) for nm in names])
    order = {c: i for i, c in enumerate(codes)}
    img = np.vectorize(lambda c: order.get(int(c), -1))(res["fate"])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4), constrained_layout=True)
    cmap = ListedColormap([COLOURS[nm] for nm in names])
    norm = BoundaryNorm(np.arange(len(names) + 1) - 0.5, len(names))
    ext = (u0[0], u0[-1], spin[0], spin[-1])
    im = a1.imshow(img, origin="lower", aspect="auto", extent=ext, cmap=cmap, norm=norm,
                   interpolation="nearest")  # fmt: skip
    cb = fig.colorbar(im, ax=a1, ticks=range(len(names)))
    cb.ax.set_yticklabels(names)
    a1.set_title("fate after 5 s")
    im2 = a2.imshow(res["slide_time"], origin="lower", aspect="auto", extent=ext,
                    cmap="viridis", interpolation="nearest")  # fmt: skip
    fig.colorbar(im2, ax=a2, label="slide_time [s]")
    a2.set_title("total time sliding")
    for ax in (a1, a2):
        ax.set_xlabel("radial throw speed u0 [m/s]")
        ax.set_ylabel("backspin a omega0 [m/s]")
    fig.suptitle(f"thrown on a cone alpha = {ALPHA}, r0 = {R0} m, v0 = {V0} m/s; "
                 f"mu = {SCENE.mu}, mu_k = {SCENE.mu_k}, c_spin = {SCENE.c_spin}, "
                 f"c_rr = {SCENE.c_rr}, rim {SCENE.rim} m")  # fmt: skip
    fig.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures")
    parser.add_argument("--n", type=int, default=48)
    parser.add_argument("--tiny", action="store_true", help="a 3x3 smoke run (tests)")
    args = parser.parse_args()
    if args.tiny:
        args.n = 3
    t0 = time.perf_counter()
    u0, spin, res = launch_map(args.n)
    dt = time.perf_counter() - t0
    args.out.mkdir(parents=True, exist_ok=True)
    draw(u0, spin, res, args.out / "slide_and_roll.png")
    counts = {nm: int((res["fate"] == HYBRID_FATE_NAMES.index(nm)).sum()) for nm in COLOURS}
    print(f"{args.n}x{args.n} launches in {dt:.1f} s (compile included); fates {counts}")


if __name__ == "__main__":
    main()

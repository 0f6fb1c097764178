"""Energy drift over 10^4 radial periods: rk45 and dop853 (drift grows) vs symplectic (bounded).

    .venv/bin/python scripts/energy_drift.py --out docs/figures

One typical bounded orbit (alpha 0.629, reference case P003), rtol 1e-8, sampled every 0.77
radial periods; |E(t) - E(0)| / |E(0)| against time in radial periods, log-log, written as
``energy_drift.png`` into ``--out`` (default: the working directory).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from figure_cli import TINY_HELP, add_out  # scripts/, the script's folder

import engine

ORBIT = dict(alpha=0.629192668725, energy=3.2037698430241135, h=4.56325009767, Lz=-0.6702997973)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    add_out(ap)
    ap.add_argument("--periods", type=int, default=10_000, help="radial periods (default 1e4)")
    ap.add_argument("--rtol", type=float, default=1e-8, help="integrator tolerance")
    ap.add_argument("--tiny", action="store_true", help=TINY_HELP)
    args = ap.parse_args()
    if args.tiny:
        args.periods = 20

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    T = float(engine.evaluate(**ORBIT).period)
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=100)
    for method, colour in (("rk45", "C0"), ("dop853", "C1"), ("symplectic", "C2")):
        t0 = time.perf_counter()
        ds = engine.simulate(**ORBIT, periods=args.periods, method=method, rtol=args.rtol,
                             dt_out=0.77 * T)  # fmt: skip
        secs = time.perf_counter() - t0
        rel = np.abs(ds.E_drift.values) / abs(ds.attrs["E0"])
        n = ds.time.values / T
        keep = n > 0
        ax.loglog(n[keep], np.maximum(rel[keep], 1e-17), color=colour, lw=0.6,
                  label=f"{method} ({ds.attrs['n_steps']:,} steps, {secs:.1f} s)")  # fmt: skip
        tenth = rel.size // 10
        print(f"{method:<11} |dE/E| max in first / last tenth: "
              f"{rel[:tenth].max():.2e} / {rel[-tenth:].max():.2e}  ({secs:.1f} s)")  # fmt: skip
    ax.set_xlabel("time [radial periods]")
    ax.set_ylabel("|E(t) - E(0)| / |E(0)| [1]")
    ax.set_title(f"energy drift over {args.periods:,} radial periods, rtol {args.rtol:g}")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    png = args.out / "energy_drift.png"
    fig.savefig(png)
    print(f"wrote {png}")


if __name__ == "__main__":
    main()

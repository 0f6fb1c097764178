"""Draw the documentation figures (PNG) from data computed by the engine, into ``--out`` (default:
the working directory; ``--out docs/figures`` updates the documentation's).

    .venv/bin/python scripts/figures.py --out docs/figures            # all five figures
    .venv/bin/python scripts/figures.py --only potential rosette      # a subset

Figures:

- ``potential.png``: V(r) = A/r^2 + B/r + C r with A = 1, B = -3.5, C = 2 and the energy level
  -1, its turning points and circular radius (the seed paper's figure 2).
- ``class_map_free_fall.png``: orbit class over (h, energy) in free fall (g = 0).
- ``gravity_maps.png``: precession rate and mu_required under gravity over (L_z, energy offset
  from V_min on a log axis).
- ``rosette.png``: a bounded orbit on the cone in 3-D and in the developed plane
  (phi = theta sin alpha), from the closed-form radial quadrature only.
- ``free_fall_orbits.png``: free-fall ellipse-like and hyperbola-like orbits from the closed form
  W = 1/r = (|B|/(2A)) (e cos(Omega (theta - theta0)) - sign(B)).

matplotlib is a benchmark/figure extra (``.venv/bin/pip install '.[bench]'`` in the checkout),
not a runtime dependency. Every figure's numbers are cross-checked against ``engine.evaluate``
and the check is printed.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
from figure_cli import TINY_HELP, add_out  # noqa: E402  (scripts/, the script's folder)

import engine  # noqa: E402
import engine.accessor  # noqa: E402,F401  (registers ds.cone)
import engine.plot  # noqa: E402
from engine.kernels.cone import coefficients, potential  # noqa: E402
from engine.kernels.roots import circular_radius, turning_points  # noqa: E402

DPI = 100
SCENE = engine.Scene(M=1.0, g=9.81, k=0.4)
FREE_FALL = engine.Scene(M=1.0, g=0.0, k=0.4)
ALPHA = math.radians(30.0)


def _save(fig: plt.Figure, out: Path, name: str, dpi: int) -> Path:
    path = out / name
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} kB)")
    return path


# -- (a) effective potential, the seed paper's figure 2 ---------------------------------------


def figure_potential(out: Path, dpi: int = DPI) -> Path:
    """V(r) for A = 1, B = -3.5, C = 2 (arbitrary units) with energy -1, r1, r2 and r_c."""
    A, B, C, energy = 1.0, -3.5, 2.0, -1.0
    rc = circular_radius(A, B, C)
    r1, r2 = turning_points(energy, A, B, C, rc)
    for r in (r1, r2):
        assert abs(C * r**3 - energy * r**2 + B * r + A) < 1e-12, "turning point is not a root"
    vc = potential(rc, A, B, C)
    print(f"potential: r_c = {rc:.6g}, V(r_c) = {vc:.6g}, r1 = {r1:.6g}, r2 = {r2:.6g}")
    r = np.linspace(0.12, 2.2, 700)
    V = A / r**2 + B / r + C * r
    fig, ax = plt.subplots(figsize=(6, 4.2))
    ax.plot(r, V, "k", lw=1.8, label=r"$V_{\rm eff}(r) = A/r^2 + B/r + C r$")
    ax.axhline(energy, color="tab:blue", lw=1.2, label=r"energy $\mathcal{E} = -1$")
    ax.plot([r1, r2], [energy, energy], "o", color="tab:blue", ms=6, zorder=3)
    ax.plot([rc], [vc], "s", color="tab:red", ms=6, zorder=3, label=f"minimum $V(r_c) = {vc:.3g}$")
    for x, y, name, offset, ha in (
        (r1, -3.0, "r_1", (0, 0), "center"),
        (r2, -3.0, "r_2", (0, 0), "center"),
        (rc, vc, "r_c", (0, -16), "center"),
    ):
        ax.axvline(x, color="0.6", lw=0.8, ls=":")
        ax.annotate(
            f"${name} = {x:.3f}$",
            (x, y),
            xytext=offset,
            textcoords="offset points",
            fontsize=9,
            ha=ha,
            bbox={"facecolor": "w", "edgecolor": "none", "pad": 1},
        )
    ax.fill_between(r, V, energy, where=V <= energy, color="tab:blue", alpha=0.12, lw=0)
    ax.set_ylim(-3.3, 4.0)
    ax.set_xlim(r[0], r[-1])
    ax.set_xlabel("r [arbitrary units]")
    ax.set_ylabel(r"$V_{\rm eff}(r)$ [arbitrary units]")
    ax.set_title("Effective potential, A = 1, B = -3.5, C = 2 (seed paper, fig. 2)", fontsize=10)
    ax.legend(loc="upper right", fontsize=9)
    ax.grid(alpha=0.3)
    return _save(fig, out, "potential.png", dpi)


# -- (b) classification map in free fall -------------------------------------------------------


def figure_class_map(out: Path, dpi: int = DPI) -> Path:
    """Orbit class over (h, energy) in free fall at alpha = 30 deg, L_z = 1 kg m^2/s."""
    Lz = 1.0
    h = xr.DataArray(np.linspace(-6.0, 6.0, 241), dims="h")
    e = xr.DataArray(np.linspace(-2.5, 1.0, 176), dims="energy")
    ds = engine.evaluate(ALPHA, e, h, Lz, FREE_FALL)
    ds = ds.assign_coords(h=h.values, energy=e.values)
    ds.h.attrs["units"] = "m s-1"
    ds.energy.attrs["units"] = "J"
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ds.cone.class_map(x="h", y="energy", ax=ax, legend=False)
    # The circular class is the line calE = V_min = -B^2/(4A) (B < 0): draw it on top.
    hv = h.values[h.values < 0]
    vmin = engine.minimum_energy(ALPHA, hv, Lz, FREE_FALL)
    ax.plot(hv, vmin, color="tab:red", lw=1.5)
    ax.axhline(0.0, color="k", lw=0.5, ls=":")
    from matplotlib.patches import Patch

    colors = engine.plot.CLASS_COLORS
    names = ds.cone.class_names
    present = set(np.unique(ds.orbit_class.values).tolist()) | {ds.cone.class_codes["circular"]}
    handles = [
        Patch(facecolor=colors[n], edgecolor="k", lw=0.5, label=n)
        for n in names
        if ds.cone.class_codes[n] in present
    ]
    handles[[h.get_label() for h in handles].index("circular")] = plt.Line2D(
        [], [], color="tab:red", lw=1.5, label=r"circular ($\mathcal{E} = V_{\min}$)"
    )
    ax.legend(handles=handles, title="orbit class", loc="lower right", fontsize=8)
    ax.set_xlabel(r"spin invariant $h$ [m s$^{-1}$]")
    ax.set_ylabel(r"radial energy $\mathcal{E}$ [J]")
    ax.set_title(
        r"Free fall ($g = 0$), $\alpha = 30^\circ$, $L_z = 1$ kg m$^2$ s$^{-1}$, $k = 0.4$",
        fontsize=10,
    )
    frac = ds.cone.class_fractions()
    print(
        "class map: fractions "
        + ", ".join(f"{n} {v:.3f}" for n, v in zip(names, frac.values, strict=True) if v > 0)
    )
    return _save(fig, out, "class_map_free_fall.png", dpi)


# -- (c) precession-rate and mu_required maps under gravity ------------------------------------


def figure_gravity_maps(out: Path, dpi: int = DPI, h: float = -1.0) -> Path:
    """Precession rate [rad/s] and mu_required over (L_z, energy offset) at alpha = 30 deg."""
    from matplotlib.colors import SymLogNorm

    offsets = np.geomspace(1e-6, 1e2, 121)
    Lz = np.geomspace(1e-3, 10.0, 151)
    ds = engine.survey([ALPHA], offsets, [h], Lz, SCENE, energy_relative=True)
    ds = ds.isel(alpha=0, h=0)
    assert (ds.orbit_class == ds.cone.class_codes["bounded"]).all(), "expected only bounded orbits"
    rate = ds.precession_rate
    mu = ds.mu_required
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.3), sharey=True)
    lim = float(np.nanmax(np.abs(rate)))
    pc = axes[0].pcolormesh(
        Lz,
        offsets,
        rate.transpose("energy", "Lz").values,
        cmap="RdBu_r",
        norm=SymLogNorm(linthresh=0.1, linscale=0.5, vmin=-lim, vmax=lim),
        shading="nearest",
    )
    axes[0].contour(Lz, offsets, rate.transpose("energy", "Lz").values, [0.0], colors="k")
    axes[0].plot([], [], "k", label="rate = 0")
    fig.colorbar(pc, ax=axes[0], label=r"precession rate $(2\psi - 2\pi)/T_r$ [rad s$^{-1}$]")
    pc2 = axes[1].pcolormesh(
        Lz, offsets, mu.transpose("energy", "Lz").values, cmap="viridis", shading="nearest"
    )
    fig.colorbar(pc2, ax=axes[1], label=r"$\mu_{\rm required}$ [1]")
    # Where V_min changes sign (possible for h L_z < 0) the relative energy axis degenerates:
    # |V_min| -> 0, so every offset there is a nearly circular orbit. Mark it.
    vmin = ds.V_min.values
    lz0 = [
        Lz[j] - vmin[j] * (Lz[j + 1] - Lz[j]) / (vmin[j + 1] - vmin[j])
        for j in np.flatnonzero(np.sign(vmin[:-1]) != np.sign(vmin[1:]))
    ]
    for ax in axes:
        for x0 in lz0:
            ax.axvline(x0, color="w", ls="--", lw=1.0)
    if lz0:
        axes[0].plot([], [], color="0.5", ls="--", label=r"$V_{\min} = 0$ (axis degenerate)")
    axes[0].legend(loc="lower right", fontsize=8, framealpha=0.9)
    for ax, title in zip(axes, ("precession rate", "friction needed to roll"), strict=True):
        ax.set_yscale("log")
        ax.set_xscale("log")
        ax.set_xlabel(r"$L_z$ [kg m$^2$ s$^{-1}$]")
        ax.set_title(title, fontsize=10)
    axes[0].set_ylabel(r"energy offset $(\mathcal{E} - V_{\min})/|V_{\min}|$ [1]")
    fig.suptitle(
        rf"Gravity $g = 9.81$ m s$^{{-2}}$, $\alpha = 30^\circ$, $h = {h:g}$ m s$^{{-1}}$, "
        r"$k = 0.4$, $M = 1$ kg (all orbits bounded)",
        fontsize=10,
    )
    i = np.unravel_index(int(np.nanargmax(np.abs(rate.values))), rate.shape)
    print(
        f"gravity maps: |precession rate| max {lim:.4g} rad/s at "
        f"{dict((d, float(rate[d][k])) for d, k in zip(rate.dims, i, strict=True))}; "
        f"mu_required {float(mu.min()):.3g} .. {float(mu.max()):.3g}; V_min = 0 at L_z = "
        + ", ".join(f"{x:.4g}" for x in lz0)
    )
    return _save(fig, out, "gravity_maps.png", dpi)


# -- (d) rosette from the closed-form radial quadrature ----------------------------------------


def radial_quadrature(
    alpha: float, energy: float, h: float, Lz: float, scene: engine.Scene, n: int = 4001
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Half a radial period r1 -> r2 from the closed form, g > 0: (r [m], theta [rad], t [s]).

    With r = r1 cos^2 s + r2 sin^2 s and calE - V = C (r - r1)(r2 - r)(r - r3)/r^2 the
    quadratures dtheta = K dr / (r^2 sqrt(2/M (calE - V))), dt = dr / sqrt(...) become
    dtheta/ds = 2 K / (q r sqrt(r - r3)), dt/ds = 2 r / (q sqrt(r - r3)), q = sqrt(2C/M):
    smooth and even about both ends, so the trapezoid rule converges geometrically.
    """
    A, B, C = coefficients(alpha, h, Lz, scene.M, scene.g, scene.k)
    rc = circular_radius(A, B, C)
    r1, r2 = turning_points(energy, A, B, C, rc)
    r3 = -A / (C * r1 * r2)
    K = abs(Lz) / (scene.M * math.sin(alpha) ** 2)
    q = math.sqrt(2.0 * C / scene.M)
    s = np.linspace(0.0, 0.5 * math.pi, n)
    r = r1 * np.cos(s) ** 2 + r2 * np.sin(s) ** 2
    dth = 2.0 * K / (q * r * np.sqrt(r - r3))
    dt = 2.0 * r / (q * np.sqrt(r - r3))
    ds_ = s[1] - s[0]

    def cumtrapz(f: np.ndarray) -> np.ndarray:
        return np.concatenate(([0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * ds_)))

    return r, cumtrapz(dth), cumtrapz(dt)


def full_orbit(r_half: np.ndarray, th_half: np.ndarray, periods: int) -> tuple[np.ndarray, ...]:
    """Unfold half a radial period (r1 -> r2) into ``periods`` radial periods by reflection."""
    psi = th_half[-1]
    r_back = r_half[::-1][1:]
    th_back = 2.0 * psi - th_half[::-1][1:]
    r_one = np.concatenate((r_half, r_back))
    th_one = np.concatenate((th_half, th_back))
    rs = [r_one] + [r_one[1:]] * (periods - 1)
    ths = [th_one] + [th_one[1:] + 2.0 * psi * p for p in range(1, periods)]
    return np.concatenate(rs), np.concatenate(ths)


def figure_rosette(out: Path, dpi: int = DPI, periods: int = 9) -> Path:
    """A bounded orbit at alpha = 30 deg in 3-D on the cone and in the developed plane."""
    alpha, h, Lz, offset = ALPHA, 0.0, 1.0, 1.5
    vmin = float(engine.minimum_energy(alpha, h, Lz, SCENE))
    energy = vmin + offset * abs(vmin)
    ref = engine.evaluate(alpha, energy, h, Lz, SCENE)
    r_half, th_half, t_half = radial_quadrature(alpha, energy, h, Lz, SCENE)
    err_psi = th_half[-1] / float(ref.apsidal_angle) - 1.0
    err_T = 2.0 * t_half[-1] / float(ref.period) - 1.0
    print(
        f"rosette: quadrature vs engine: psi rel. diff {err_psi:.1e}, T_r rel. diff {err_T:.1e};"
        f" precession per revolution {float(ref.cone.precession_per_revolution()):.3f} deg"
    )
    assert abs(err_psi) < 1e-10 and abs(err_T) < 1e-10, "quadrature disagrees with the engine"
    r, th = full_orbit(r_half, th_half, periods)
    sa, ca = math.sin(alpha), math.cos(alpha)
    r1, r2 = float(ref.r_min), float(ref.r_max)

    fig = plt.figure(figsize=(11.5, 5))
    fig.subplots_adjust(wspace=0.3)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    rr = np.linspace(0.0, 1.08 * r2, 10)
    tt = np.linspace(0.0, 2 * math.pi, 37)
    RR, TT = np.meshgrid(rr, tt)
    ax3.plot_wireframe(RR * sa * np.cos(TT), RR * sa * np.sin(TT), RR * ca, color="0.75", lw=0.4)
    ax3.plot(r * sa * np.cos(th), r * sa * np.sin(th), r * ca, color="tab:blue", lw=1.0)
    for rb, col in ((r1, "tab:green"), (r2, "tab:orange")):
        ax3.plot(rb * sa * np.cos(tt), rb * sa * np.sin(tt), rb * ca + 0 * tt, color=col, lw=1.2)
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.set_box_aspect((1, 1, ca / sa * 0.55))
    ax3.view_init(elev=28, azim=-60)
    ax3.set_title("centre of mass on its cone (3-D)", fontsize=10)

    ax = fig.add_subplot(1, 2, 2)
    phi = th * sa
    ax.plot(r * np.cos(phi), r * np.sin(phi), color="tab:blue", lw=1.0, label="orbit")
    circ = np.linspace(0, 2 * math.pi, 200)
    ax.plot(r1 * np.cos(circ), r1 * np.sin(circ), color="tab:green", lw=1, ls="--")
    ax.plot(r2 * np.cos(circ), r2 * np.sin(circ), color="tab:orange", lw=1, ls="--")
    ax.plot([], [], color="tab:green", ls="--", label=f"$r_1$ = {r1:.3f} m")
    ax.plot([], [], color="tab:orange", ls="--", label=f"$r_2$ = {r2:.3f} m")
    ax.plot([0], [0], "k+", ms=8)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$r\cos\varphi$ [m]")
    ax.set_ylabel(r"$r\sin\varphi$ [m]")
    ax.set_title(r"developed plane, $\varphi = \theta \sin\alpha$ (not wrapped)", fontsize=10)
    ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    ax.grid(alpha=0.3)
    fig.suptitle(
        rf"Bounded orbit, $\alpha = 30^\circ$, $L_z = {Lz:g}$ kg m$^2$ s$^{{-1}}$, "
        rf"$h = {h:g}$ m s$^{{-1}}$, $\mathcal{{E}} = V_{{\min}} + {offset:g}|V_{{\min}}|$, "
        rf"{periods} radial periods; $\psi$ = {math.degrees(float(ref.apsidal_angle)):.2f}$^\circ$",
        fontsize=10,
    )
    return _save(fig, out, "rosette.png", dpi)


# -- (e) free-fall conic-like orbits -----------------------------------------------------------


def free_fall_orbit(
    alpha: float, energy: float, h: float, Lz: float, scene: engine.Scene, n: int = 4000
) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
    """(r [m], theta [rad], info) of a free-fall orbit from W = 1/r = p (e cos x - sign B).

    x = Omega (theta - theta0), theta0 = 0 at the pericentre, p = |B|/(2A), e^2 = 1 + 4 A calE/B^2.
    Bounded (B < 0, calE < 0): x over [0, 2 pi periods); escapes: |x| < arccos(sign(B)/e).
    """
    A, B, _ = coefficients(alpha, h, Lz, scene.M, 0.0, scene.k)
    Om = math.sqrt((math.sin(alpha) ** 2 + scene.k) / (1.0 + scene.k))
    p = abs(B) / (2.0 * A)
    e = math.sqrt(1.0 + 4.0 * A * energy / (B * B))
    sb = math.copysign(1.0, B)
    if energy < 0.0:
        x = np.linspace(0.0, 2.0 * math.pi * 3, n)
        xmax = math.pi
    else:
        xmax = math.acos(sb / e)
        x = xmax * np.linspace(-1.0, 1.0, n)[1:-1]
    W = p * (e * np.cos(x) - sb)
    info = {"e": e, "Omega": Om, "r_min": 1.0 / (p * (e - sb)), "half_sweep": xmax / Om}
    return 1.0 / W, x / Om, info


def figure_free_fall(out: Path, dpi: int = DPI) -> Path:
    """Ellipse-like (bounded) and hyperbola-like free-fall orbits in the developed plane."""
    alpha, Lz, sa = ALPHA, 1.0, math.sin(ALPHA)
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
    cases = [
        (axes[0], -3.0, -0.54, "tab:blue", "bounded"),
        (axes[0], -3.0, -0.38, "tab:purple", "bounded"),
        (axes[1], -3.0, 0.4, "tab:blue", "B < 0, e > 1"),
        (axes[1], -3.0, 0.0, "tab:green", "B < 0, e = 1"),
        (axes[1], 1.5, 1.0, "tab:red", "B > 0, e > 1"),
    ]
    rlim = 8.0
    for ax, h, energy, col, kind in cases:
        ref = engine.evaluate(alpha, energy, h, Lz, FREE_FALL)
        r, th, info = free_fall_orbit(alpha, energy, h, Lz, FREE_FALL)
        # Cross-check the closed form against the engine: pericentre and apsidal angle / sweep.
        assert abs(info["r_min"] / float(ref.r_min) - 1) < 1e-12, "r_min disagrees"
        assert abs(info["half_sweep"] / float(ref.apsidal_angle) - 1) < 1e-12, "psi disagrees"
        cls = ref.cone.class_names[int(ref.orbit_class)]
        phi = th * sa
        keep = (r < rlim) | (energy < 0.0)
        x, y = np.where(keep, r * np.cos(phi), np.nan), np.where(keep, r * np.sin(phi), np.nan)
        label = rf"{kind}: $\mathcal{{E}}$ = {energy:g} J, $h$ = {h:g} m/s, $e$ = {info['e']:.3f}"
        ax.plot(x, y, color=col, lw=1.1, label=label)
        ax.plot([info["r_min"]], [0.0], "o", color=col, ms=4)
        print(
            f"free fall {cls:10s} h={h:+.1f} calE={energy:+.2f}: e = {info['e']:.4f}, "
            f"r_min = {info['r_min']:.4f} m, psi or half sweep = "
            f"{math.degrees(info['half_sweep']):.2f} deg (engine agrees to 1e-12)"
        )
        if energy >= 0.0:  # asymptote directions in the developed plane
            for sgn in (-1.0, 1.0):
                ph = sgn * info["half_sweep"] * sa
                ax.plot(
                    [0, rlim * math.cos(ph)], [0, rlim * math.sin(ph)], color=col, lw=0.6, ls=":"
                )
    om = math.sqrt((sa**2 + 0.4) / 1.4)
    axes[0].set_title(
        rf"bounded, 3 radial periods: $\psi = \pi/\Omega$ = "
        rf"{math.degrees(math.pi / om):.1f}$^\circ$ in $\theta$, "
        rf"{math.degrees(math.pi * sa / om):.1f}$^\circ$ in $\varphi$",
        fontsize=9,
    )
    axes[1].set_title(
        r"escapes: sweep $2\arccos(\mathrm{sign}\,B/e)/\Omega$ in $\theta$ "
        r"(dotted: asymptote directions)",
        fontsize=9,
    )
    for ax in axes:
        ax.plot([0], [0], "k+", ms=8)
        ax.set_aspect("equal")
        ax.set_xlabel(r"$r\cos\varphi$ [m]")
        ax.set_ylabel(r"$r\sin\varphi$ [m]")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower left", fontsize=7.5, framealpha=0.9)
    axes[1].set_xlim(-rlim, rlim)
    axes[1].set_ylim(-rlim, rlim)
    fig.suptitle(
        r"Free fall ($g = 0$), developed plane $\varphi = \theta\sin\alpha$, $\alpha = 30^\circ$, "
        r"$L_z = 1$ kg m$^2$ s$^{-1}$, $k = 0.4$; $1/r = (|B|/2A)(e\cos\Omega(\theta-\theta_0) "
        r"- \mathrm{sign}\,B)$",
        fontsize=10,
    )
    return _save(fig, out, "free_fall_orbits.png", dpi)


FIGURES: dict[str, Callable[[Path, int], Path]] = {
    "potential": figure_potential,
    "class_map": figure_class_map,
    "gravity_maps": figure_gravity_maps,
    "rosette": figure_rosette,
    "free_fall": figure_free_fall,
}


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point: draw the selected figures into ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_out(parser)
    parser.add_argument("--dpi", type=int, default=DPI, help="resolution (default %(default)s)")
    parser.add_argument("--only", nargs="+", choices=sorted(FIGURES), help="figures to draw")
    parser.add_argument("--tiny", action="store_true", help=TINY_HELP)
    args = parser.parse_args(argv)
    if args.tiny:
        args.dpi = 20
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.only or FIGURES:
        FIGURES[name](args.out, args.dpi)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""One orbit as a picture and as an animation (``conesurvey orbit``; docs/surveys.md, "One
orbit").

The picture (:func:`orbit_figure`): the centre's path in 3-D on its cone, the top view with the
turning circles r_min sin(alpha) and r_max sin(alpha) of the closed form (and the rim), and
r(t) against the closed form's r_min and r_max; the events of the trajectory are marked
(apsides, and on a scene with ``mu_k`` the story's slip, roll, spin_stop, rest, spill...) and
its sliding stretches shaded. The animation (:func:`write_animation`): the top view with the
ball rolling along the path (drawn enlarged where it would be too small to see) and a mark on
its surface turned by the attitude quaternion (its top point at the start: filled while it
faces up, hollow while it faces down), and r(t) with a cursor; a GIF (Pillow) or, where
ffmpeg is on the PATH, an MP4.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from .figurefile import check_figure_size, matplotlib_parts
from .io.atomic import fsync_path, replacing
from .mapspec import LookError
from .orbitview import Orbit

__all__ = [
    "ANIMATION_FORMATS",
    "BALL_COLOR",
    "MAX_FRAMES",
    "animation_frames",
    "ball_state",
    "check_animation",
    "orbit_figure",
    "orbit_thumbnail",
    "write_animation",
]

PATH_COLOR, SLIDE_COLOR, CIRCLE_COLOR, RIM_COLOR = "#1f77b4", "#ff7f0e", "#7f7f7f", "#2ca02c"
BALL_COLOR, MARK_COLOR = "#d62728", "#000000"
EVENT_MARKERS = {"pericentre": "v", "apocentre": "^", "slip": "X", "roll": "o",
                 "spin_stop": "s", "spin_go": "D", "rest": "P", "spill": "*", "vertex": "h",
                 "horizon": "|", "failed": "x"}  # fmt: skip
FIGURE_SIZE = (14.0, 4.8)
ANIMATION_SIZE = (9.6, 4.8)
#: Bounds of an animation: frames, frames per second, and pixels of all frames together
#: (a GIF's frames are held as 1-byte palette images until written: 200 MB).
MAX_FRAMES, MAX_FPS = 1000, 60
MAX_ANIMATION_PIXELS = 200_000_000
ANIMATION_FORMATS = (".gif", ".mp4")
#: The drawn ball's radius at least this fraction of the top view's width.
MIN_BALL_FRACTION = 0.025


def _events(o: Orbit) -> list[tuple[str, float, float, float]]:
    """(kind, t, r, theta) of each event of the trajectory, the kinds from its flag table."""
    tr = o.traj
    if "event_kind" not in tr or tr.sizes.get("event", 0) == 0:
        return []
    names = str(tr["event_kind"].attrs["flag_meanings"]).split()
    codes = np.atleast_1d(tr["event_kind"].attrs["flag_values"]).tolist()
    table = dict(zip(codes, names, strict=True))
    return [(table.get(int(k), str(k)), float(t), float(r), float(th)) for k, t, r, th in
            zip(tr["event_kind"].values, tr["event_time"].values, tr["event_r"].values,
                tr["event_theta"].values, strict=True)]  # fmt: skip


def _sliding_spans(o: Orbit) -> list[tuple[float, float]]:
    """The time spans [s] the trajectory slides (its ``mode`` is sliding)."""
    tr = o.traj
    if "mode" not in tr:
        return []
    names = str(tr["mode"].attrs["flag_meanings"]).split()
    code = np.atleast_1d(tr["mode"].attrs["flag_values"])[names.index("sliding")]
    on = np.asarray(tr["mode"].values) == code
    t = tr["time"].values
    spans, start = [], None
    for i, s in enumerate(on):
        if s and start is None:
            start = t[i]
        if not s and start is not None:
            spans.append((float(start), float(t[i])))
            start = None
    if start is not None:
        spans.append((float(start), float(t[-1])))
    return spans


def _circle(ax: Any, radius: float, **kw: Any) -> None:
    phi = np.linspace(0.0, 2.0 * np.pi, 361)
    ax.plot(radius * np.cos(phi), radius * np.sin(phi), **kw)


def _top_view(ax: Any, o: Orbit, events: bool = True) -> None:
    """The path seen from above, the turning circles, the rim, the events."""
    s = math.sin(o.alpha)
    tr = o.traj
    ax.plot(tr["x"].values, tr["y"].values, color=PATH_COLOR, lw=0.9, label="path of the centre")
    what = "of the rolling launch orbit" if o.sliding else "(closed form)"
    for r, name in ((o.r_min, "r_min"), (o.r_max, "r_max")):
        if math.isfinite(r):
            _circle(ax, r * s, color=CIRCLE_COLOR, ls="--", lw=0.9,
                    label=f"turning circles {what}" if name == "r_min" else None)  # fmt: skip
    if o.rim_r is not None:
        _circle(ax, o.rim_r * s, color=RIM_COLOR, lw=1.2, label="rim")
    if events:
        for kind, _, r, th in _events(o):
            ax.plot(r * s * math.cos(th), r * s * math.sin(th), ls="none",
                    marker=EVENT_MARKERS.get(kind, "o"), color="k", ms=5)  # fmt: skip
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("from above", fontsize="medium")


def _radius(ax: Any, o: Orbit) -> None:
    """r(t) with the closed form's turning points, the events and the sliding spans."""
    tr = o.traj
    ax.plot(tr["time"].values, tr["r"].values, color=PATH_COLOR, lw=1.0, label="r(t)")
    for r, name in ((o.r_min, "r_min"), (o.r_max, "r_max")):
        if math.isfinite(r):
            ax.axhline(r, color=CIRCLE_COLOR, ls="--", lw=0.9)
            ax.annotate(f"{name} {r:.4g} m", (0.0, r), fontsize="x-small", va="bottom")
    for i, (t0, t1) in enumerate(_sliding_spans(o)):
        ax.axvspan(t0, t1, color=SLIDE_COLOR, alpha=0.25, label="sliding" if i == 0 else None)
    seen = set()
    for kind, t, r, _ in _events(o):
        ax.plot(t, r, ls="none", marker=EVENT_MARKERS.get(kind, "o"), color="k", ms=5,
                label=kind if kind not in seen else None)  # fmt: skip
        seen.add(kind)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("r [m] (centre from its cone's vertex)")
    ax.legend(fontsize="x-small", loc="best")


def _cone3d(ax: Any, o: Orbit) -> None:
    """The centre's cone as a light mesh, and the path on it."""
    s, c = math.sin(o.alpha), math.cos(o.alpha)
    tr = o.traj
    top = float(np.nanmax(tr["r"].values)) * 1.08
    rr, phi = np.meshgrid(np.linspace(0.0, top, 12), np.linspace(0, 2 * np.pi, 49))
    ax.plot_wireframe(rr * s * np.cos(phi), rr * s * np.sin(phi), rr * c, color="#b0b0b0",
                      lw=0.4, rstride=4, cstride=1)  # fmt: skip
    ax.plot(tr["x"].values, tr["y"].values, tr["z"].values, color=PATH_COLOR, lw=1.0)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title("on its cone", fontsize="medium")


def _title(o: Orbit) -> str:
    tr = o.traj
    how = f"{tr.attrs.get('method', '?')}, rtol {float(tr.attrs.get('rtol', math.nan)):g}"
    end = f"; {tr.attrs['fate']}" if "fate" in tr.attrs else ""
    return (f"{o.label}\n{o.orbit_class} on the ideal cone: r {o.r_min:.4g} .. {o.r_max:.4g} m"
            f"; {float(tr['time'].values[-1]):.4g} s drawn ({how}){end}")  # fmt: skip


def orbit_figure(o: Orbit) -> Any:
    """The picture of ``o``: on its cone (3-D), from above, and r(t) (see the module
    docstring)."""
    m = matplotlib_parts()
    fig = m.Figure(figsize=FIGURE_SIZE, layout="constrained")
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    _cone3d(ax3, o)
    top = fig.add_subplot(1, 3, 2)
    _top_view(top, o)
    top.legend(fontsize="x-small", loc="upper right")
    _radius(fig.add_subplot(1, 3, 3), o)
    fig.suptitle(_title(o), fontsize="medium")
    return fig


def orbit_thumbnail(o: Orbit, title: str) -> Any:
    """A small picture of ``o`` for the report: from above and r(t), under ``title``."""
    m = matplotlib_parts()
    fig = m.Figure(figsize=(8.0, 3.4), layout="constrained")
    top, rad = fig.subplots(1, 2)
    _top_view(top, o)
    _radius(rad, o)
    fig.suptitle(title, fontsize="medium")
    return fig


# --- the animation ----------------------------------------------------------------------------


def check_animation(path: Path, frames: int, fps: float, dpi: float) -> str:
    """The animation's format (``gif`` or ``mp4``); LookError, before anything is computed,
    for a suffix, a count, a rate or a size out of bounds, or an MP4 without ffmpeg."""
    fmt = path.suffix.lower()
    if fmt not in ANIMATION_FORMATS:
        raise LookError(
            f"--animate {path}: unknown format {fmt!r}; use {', '.join(ANIMATION_FORMATS)}"
        )
    if not 2 <= frames <= MAX_FRAMES:
        raise LookError(f"--frames must be in 2..{MAX_FRAMES}; got {frames}")
    if not (math.isfinite(fps) and 1 <= fps <= MAX_FPS):
        raise LookError(f"--fps must be in 1..{MAX_FPS}; got {fps:g}")
    check_figure_size(ANIMATION_SIZE, dpi)
    pixels = frames * ANIMATION_SIZE[0] * ANIMATION_SIZE[1] * dpi * dpi
    if pixels > MAX_ANIMATION_PIXELS:
        raise LookError(f"{frames} frames at --dpi {dpi:g} are {pixels:,.0f} pixels, more than "
                        f"{MAX_ANIMATION_PIXELS:,}: fewer --frames or a lower --dpi")  # fmt: skip
    if fmt == ".mp4" and shutil.which("ffmpeg") is None:
        raise LookError("--animate *.mp4 needs ffmpeg on the PATH, which is not there; "
                        "write a GIF (--animate ORBIT.gif)")  # fmt: skip
    return fmt[1:]


def ball_state(o: Orbit, t: float) -> tuple[float, float, np.ndarray | None]:
    """(x, y) of the centre at time ``t`` (interpolated between samples) and the world
    direction of the mark (the body's +z, the ball's top point at the start) from the attitude
    quaternion (None without one)."""
    tr = o.traj
    ts = tr["time"].values
    x = float(np.interp(t, ts, tr["x"].values))
    y = float(np.interp(t, ts, tr["y"].values))
    if not o.has_attitude:
        return x, y, None
    q = np.array([np.interp(t, ts, tr[f"quat_{c}"].values) for c in "wxyz"])
    w, qx, qy, qz = q / np.linalg.norm(q)
    mark = np.array([2 * (qx * qz + w * qy), 2 * (qy * qz - w * qx), 1 - 2 * (qx * qx + qy * qy)])
    return x, y, mark


def animation_frames(o: Orbit, frames: int, dpi: float) -> Iterator[tuple[float, Any, Any]]:
    """Each frame of the animation of ``o``: (its time [s], the figure drawn at it, the top
    view's axes); one figure, redrawn."""
    m = matplotlib_parts()
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = m.Figure(figsize=ANIMATION_SIZE, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)  # draws into memory: each frame's pixels
    top, rad = fig.subplots(1, 2)
    _top_view(top, o, events=False)
    _radius(rad, o)
    tr = o.traj
    xs, ys = tr["x"].values, tr["y"].values
    half = 0.5 * max(np.ptp(xs), np.ptp(ys), 1e-12)
    size = max(o.scene.a, MIN_BALL_FRACTION * 2 * half)
    cx, cy = 0.5 * (xs.max() + xs.min()), 0.5 * (ys.max() + ys.min())
    lim = half + 2 * size
    top.set_xlim(cx - lim, cx + lim)
    top.set_ylim(cy - lim, cy + lim)
    top.set_aspect("equal", adjustable="box")
    note = f"ball drawn {size / o.scene.a:.0f}x its size" if size > o.scene.a else ""
    mark_note = "" if o.has_attitude else "; no spin mark (attitude not integrated)"
    top.set_title(f"from above ({note}{mark_note})" if note or mark_note else "from above",
                  fontsize="small")  # fmt: skip
    ball = m.patches.Circle((xs[0], ys[0]), size, color=BALL_COLOR, zorder=5)
    top.add_patch(ball)
    (mark,) = top.plot([], [], "o", ms=4, zorder=6, mec=MARK_COLOR)
    cursor = rad.axvline(0.0, color=BALL_COLOR, lw=1.0)
    times = np.linspace(float(tr["time"].values[0]), float(tr["time"].values[-1]), frames)
    for t in times:
        x, y, d = ball_state(o, float(t))
        ball.center = (x, y)
        if d is not None:
            mark.set_data([x + 0.7 * size * d[0]], [y + 0.7 * size * d[1]])
            mark.set_markerfacecolor(MARK_COLOR if d[2] >= 0 else "none")
        cursor.set_xdata([t, t])
        fig.canvas.draw()
        fig.set_layout_engine("none")  # laid out once, at the first frame
        yield float(t), fig, top


def write_animation(
    o: Orbit, path: str | os.PathLike[str], *, frames: int = 120, fps: float = 24,
    dpi: float = 80, overwrite: bool = False,
) -> Path:  # fmt: skip
    """Write the animation of ``o`` to ``path`` (``.gif``, or ``.mp4`` with ffmpeg) through
    ``path.tmp`` and a rename; FileExistsError if it exists and not ``overwrite``."""
    from PIL import Image

    path = Path(path)
    fmt = check_animation(path, frames, fps, dpi)
    with replacing(path, overwrite=overwrite) as tmp:
        if fmt == "gif":
            images = []
            for _, fig, _ in animation_frames(o, frames, dpi):
                rgb = Image.frombuffer("RGBA", fig.canvas.get_width_height(),
                                       fig.canvas.buffer_rgba()).convert("RGB")  # fmt: skip
                images.append(rgb.quantize(colors=128, method=Image.Quantize.FASTOCTREE))
            images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                           duration=max(int(round(1000 / fps)), 20), loop=0)  # fmt: skip
        else:
            _write_mp4(o, tmp, frames, fps, dpi)
        fsync_path(tmp)
    return path


def _write_mp4(o: Orbit, tmp: Path, frames: int, fps: float, dpi: float) -> None:
    """The frames piped to ffmpeg as raw RGBA (none held in memory), encoded as H.264."""
    proc = None
    try:
        for _, fig, _ in animation_frames(o, frames, dpi):
            w, h = fig.canvas.get_width_height()
            if proc is None:
                cmd = ["ffmpeg", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt",
                       "rgba", "-s", f"{w}x{h}", "-r", f"{fps:g}", "-i", "-", "-vf",
                       "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p", "-f", "mp4",
                       str(tmp)]  # fmt: skip
                proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
            assert proc.stdin is not None
            proc.stdin.write(bytes(fig.canvas.buffer_rgba()))
    finally:
        if proc is not None:
            _, err = proc.communicate()
            if proc.returncode != 0:
                raise OSError(f"ffmpeg failed: {err.decode(errors='replace').strip()[-300:]}")

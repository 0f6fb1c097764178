"""One orbit as a picture and an animation (``conesurvey orbit``, engine.orbitview,
engine.orbitplot, ``ds.cone.orbit``): what is drawn is checked against numbers the drawing
did not compute: the closed form's turning points and period (engine.evaluate), the story's
mode changes (engine.story) and, in a frame of the GIF, the trajectory's position.

The integrations use method/effect sets the suite compiles anyway (dop853 and rk45 with the
attitude on the ideal cone, dop853 on a sliding scene with mu, mu_k and a rim)."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

import engine
from engine import cli
from engine.orbitplot import BALL_COLOR, animation_frames, ball_state, orbit_figure
from engine.orbitview import orbit
from engine.story import story

ROOT = Path(__file__).resolve().parents[1]
PNG = b"\x89PNG\r\n\x1a\n"
#: A launch at its apocentre on the gravity cone (slower than circular): r 0.579 .. 2 m.
LAUNCH = dict(alpha=0.5, r0=2.0, v0=1.0, w0=0.3)


def _closed_form(alpha, r0, v0, w0, scene=None):
    scene = scene or engine.Scene()
    inv = engine.invariants(alpha, r0, 0.0, v0, w0, scene)
    return engine.evaluate(alpha, inv["energy"], inv["h"], inv["Lz"], scene)


def _sampling_slack(t: np.ndarray, r: np.ndarray) -> float:
    """How far the samples' extreme may fall short of the true one: r'' dt^2 / 8 with the
    largest |r''| of the samples (the apsis lies within dt / 2 of a sample)."""
    dt = float(np.max(np.diff(t)))
    d2 = np.abs(np.diff(r, 2)) / dt**2
    return float(d2.max()) * dt * dt / 8 * 1.5


def test_the_picture_draws_the_path_between_the_closed_form_turning_circles():
    o = orbit(**LAUNCH)
    ref = _closed_form(**LAUNCH)
    r_min, r_max = float(ref.r_min), float(ref.r_max)
    assert (o.r_min, o.r_max) == (r_min, r_max) and o.orbit_class == "bounded"
    s, c = math.sin(0.5), math.cos(0.5)
    fig = orbit_figure(o)
    ax3, top, rad = fig.axes[:3]
    path = top.lines[0].get_xydata()
    rho = np.hypot(path[:, 0], path[:, 1])
    t, r = o.traj.time.values, o.traj.r.values
    slack = _sampling_slack(t, r) * s
    assert r_max * s - slack <= rho.max() <= r_max * s * (1 + 1e-9)
    assert r_min * s * (1 - 1e-9) <= rho.min() <= r_min * s + slack
    circles = [np.hypot(*ln.get_xydata().T) for ln in top.lines[1:3]]
    np.testing.assert_allclose([c_.mean() for c_ in circles], [r_min * s, r_max * s], rtol=1e-12)
    # the apsides marked lie on the circles, to the integration's accuracy
    marks = [ln.get_xydata()[0] for ln in top.lines[3:]]
    assert len(marks) == len(o.traj.event_time) >= 12
    for x, y in marks:
        assert min(abs(math.hypot(x, y) - r_min * s) / r_min,
                   abs(math.hypot(x, y) - r_max * s) / r_max) < 1e-8  # fmt: skip
    # r(t): 6 closed-form periods between r_min and r_max
    tr, rr = rad.lines[0].get_xydata().T
    assert r_max - _sampling_slack(t, r) <= rr.max() <= r_max * (1 + 1e-9)
    assert tr[-1] == pytest.approx(6 * float(ref.period), rel=1e-8)
    # on its cone: z = r cos(alpha)
    z = ax3.lines[0].get_data_3d()[2]
    np.testing.assert_allclose(z / c, np.hypot(*ax3.lines[0].get_data_3d()[:2]) / s, rtol=1e-12)


def test_a_sliding_story_is_shaded_where_it_slides():
    """A launch that slips, slides and rolls again: the shaded span is the story's slip to
    its roll (engine.story), to a sample spacing."""
    sc = engine.Scene(M=1.0, a=0.01, k=0.4, rim=1.0, mu=0.05, mu_k=0.04)
    o = orbit(0.6, r0=0.2, v0=0.9, w0=-1.5, scene=sc, t_end=0.5, method="dop853", rtol=1e-11)
    out = story(0.6, 0.2, 0.9, -1.5, scene=sc, rtol=1e-11, horizon_time=0.5)
    kinds = [e["kind"] for e in out["events"]]
    assert kinds[:2] == ["slip", "roll"]
    t_slip, t_roll = out["events"][0]["t"], out["events"][1]["t"]
    rad = orbit_figure(o).axes[2]
    spans = [(p.get_x(), p.get_x() + p.get_width()) for p in rad.patches]
    assert len(spans) == 1
    dt = float(np.diff(o.traj.time.values).max())
    assert abs(spans[0][0] - t_slip) <= dt and abs(spans[0][1] - t_roll) <= dt
    labels = [t.get_text() for t in rad.get_legend().get_texts()]
    assert "sliding" in labels and "slip" in labels and "roll" in labels


def _ball_pixels(rgb: np.ndarray, box) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of the pixels of the ball's colour inside the axes box (x0, y0, x1, y1
    in image pixels, y down)."""
    want = np.array([int(BALL_COLOR[i : i + 2], 16) for i in (1, 3, 5)])
    near = np.abs(rgb.astype(int) - want).sum(axis=2) < 60
    x0, y0, x1, y1 = box
    near[:, : int(x0)] = near[:, int(x1) :] = False
    near[: int(y0), :] = near[int(y1) :, :] = False
    return np.nonzero(near)


def test_a_frame_of_the_animation_shows_the_ball_where_the_trajectory_is(tmp_path):
    """The GIF's frames, decoded: the ball's pixels centre on the trajectory's (x, y) at the
    frame's time (through the axes' own transform), and the spin mark sits off the centre in
    the direction of the attitude quaternion's turn of the ball's top point."""
    from PIL import Image

    frames, dpi = 12, 60
    o = orbit(**LAUNCH, method="rk45", attitude=True)
    assert o.has_attitude
    out = tmp_path / "roll.gif"
    rc = cli.main(["orbit", *sum(([f"--{k}", str(v)] for k, v in LAUNCH.items()), []),
                   "--method", "rk45", "-o", str(tmp_path / "o.png"), "--animate", str(out),
                   "--frames", str(frames), "--dpi", str(dpi)])  # fmt: skip
    assert rc == 0
    gif = Image.open(out)
    assert gif.n_frames == frames
    checked = 0
    for k, (t, fig, top) in enumerate(animation_frames(o, frames, dpi)):
        w, h = fig.canvas.get_width_height()
        x, y, d = ball_state(o, t)
        px, py = top.transData.transform((x, y))
        size = top.patches[0].radius
        rpx = top.transData.transform((x + size, y))[0] - px
        (bx0, by0), (bx1, by1) = top.bbox.get_points()
        gif.seek(k)
        rgb = np.asarray(gif.convert("RGB"))
        assert rgb.shape == (h, w, 3)
        rows, cols = _ball_pixels(rgb, (bx0, h - by1, bx1, h - by0))
        assert rows.size > 10, k
        assert abs(cols.mean() - px) < 1.5 and abs(rows.mean() - (h - py)) < 1.5, (k, t)
        if math.hypot(d[0], d[1]) > 0.6:  # the mark: dark pixels inside the ball
            dark = np.abs(rgb.astype(int)).sum(axis=2) < 120
            yy, xx = np.mgrid[:h, :w]
            inside = dark & ((xx - px) ** 2 + (yy - (h - py)) ** 2 < (0.95 * rpx) ** 2)
            my, mx = np.nonzero(inside)
            if mx.size:
                angle = math.atan2(-(my.mean() - (h - py)), mx.mean() - px)
                diff = (angle - math.atan2(d[1], d[0]) + math.pi) % (2 * math.pi) - math.pi
                assert abs(diff) < math.radians(25), (k, math.degrees(diff))
                checked += 1
    assert checked >= 3


def test_orbit_of_a_survey_file_point(tmp_path, monkeypatch, capsys):
    """SOURCE + --at: the grid point nearest the values, the survey's relative energy made
    absolute (V_min + e |V_min|), drawn; the message names the point used."""
    monkeypatch.chdir(tmp_path)
    src = ROOT / "surveys" / "gravity_precession.toml"
    rc = cli.main(["orbit", str(src), "--at", "alpha=0.5,energy=0.3,h=0.1,Lz=1"])
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert (tmp_path / "orbit.png").read_bytes()[:8] == PNG
    s = engine.surveyfile.load_survey(src)
    e = s.energy[np.argmin(np.abs(s.energy - 0.3))]
    lz = s.Lz[np.argmin(np.abs(s.Lz - 1.0))]
    h = s.h[np.argmin(np.abs(s.h - 0.1))]
    assert f"energy = {e:.6g}" in out and f"Lz = {lz:.6g}" in out and f"h = {h:.6g}" in out
    vmin = float(engine.minimum_energy(0.5, h, lz, s.scene))
    ref = engine.evaluate(0.5, vmin + e * abs(vmin), h, lz, s.scene)
    assert f"r {float(ref.r_min):.6g} .. {float(ref.r_max):.6g} m" in out


def test_ds_cone_orbit_draws_the_point_of_a_result():
    ds = engine.survey([0.5], [0.2, 1.0], [0.0], [0.5, 1.0], energy_relative=True)
    fig = ds.cone.orbit(energy=1.0, Lz=0.5)
    o = fig.orbit
    vmin = float(ds.V_min.sel(alpha=0.5, h=0.0, Lz=0.5))
    assert o.energy == vmin + 1.0 * abs(vmin)
    assert o.r_max == float(ds.r_max.sel(energy=1.0, Lz=0.5).squeeze())


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "give --alpha and --energy --h --Lz"),
        (["--alpha", "0.5", "--energy", "1", "--h", "0", "--Lz", "1", "--r0", "1"], "not both"),
        (["--alpha", "0.5", "--r0", "1", "--v0", "1"], "needs r0, v0 and w0"),
        (["--alpha", "0.5", "--r0", "1", "--v0", "1", "--w0", "0", "--scene", "rimm=3"],
         "did you mean 'rim'?"),
        (["--alpha", "0.5", "--r0", "1", "--v0", "1", "--w0", "0", "--dpi", "5000"],
         "--dpi must be in 10..1200"),
        (["--alpha", "0.5", "--r0", "1", "--v0", "1", "--w0", "0", "--animate", "a.gif",
          "--frames", "5000"], "--frames must be in 2..1000"),
        (["--alpha", "0.5", "--r0", "1", "--v0", "1", "--w0", "0", "--animate", "a.avi"],
         "unknown format '.avi'"),
        (["--alpha", "2.0", "--r0", "1", "--v0", "1", "--w0", "0"], "alpha"),
        (["--alpha", "0.5", "--r0", "1", "--v0", "1", "--w0", "0", "-o", "o.txt"],
         "unknown format '.txt'"),
    ],
)  # fmt: skip
def test_bad_orbit_requests_exit_2_and_write_nothing(tmp_path, monkeypatch, capsys, args,
                                                     message):  # fmt: skip
    monkeypatch.chdir(tmp_path)
    assert cli.main(["orbit", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []


def test_an_mp4_needs_ffmpeg_or_is_refused_saying_so(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(shutil, "which", lambda name: None)
    args = ["orbit", "--alpha", "0.5", "--r0", "1", "--v0", "1", "--w0", "0", "--animate", "a.mp4"]
    assert cli.main(args) == 2
    assert "needs ffmpeg on the PATH" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_an_mp4_pipes_every_frame_to_ffmpeg(tmp_path, monkeypatch, capsys):
    """Where ffmpeg is on the PATH the frames go to it raw (RGBA, the frame's size, the rate
    asked): here a stand-in ffmpeg (a real process on the PATH) that counts what it reads and
    writes it where the encoder would."""
    import json
    import os
    import sys

    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    fake = bin_dir / "ffmpeg"
    fake.write_text(
        f"#!{sys.executable}\n"
        "import json, sys\n"
        "a = sys.argv[1:]\n"
        "n = len(sys.stdin.buffer.read())\n"
        "json.dump({'size': a[a.index('-s') + 1], 'rate': a[a.index('-r') + 1],\n"
        "           'fmt': a[a.index('-pix_fmt') + 1], 'bytes': n}, open(a[-1], 'w'))\n"
    )
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.chdir(tmp_path)
    frames, dpi = 5, 40
    rc = cli.main(["orbit", *sum(([f"--{k}", str(v)] for k, v in LAUNCH.items()), []),
                   "--method", "rk45", "--animate", "roll.mp4", "--frames", str(frames),
                   "--fps", "12", "--dpi", str(dpi)])  # fmt: skip
    assert rc == 0, capsys.readouterr().err
    got = json.loads((tmp_path / "roll.mp4").read_text())
    w, h = (int(round(x * dpi)) for x in (9.6, 4.8))
    assert got == {"size": f"{w}x{h}", "rate": "12", "fmt": "rgba", "bytes": frames * w * h * 4}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bin", "orbit.png", "roll.mp4"]

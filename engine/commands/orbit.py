"""``conesurvey orbit``: one orbit as a picture (and an animation) (docs/surveys.md, "One
orbit").

The orbit is given by its invariants (``--alpha --energy --h --Lz``), by a launch (``--alpha
--r0 --v0 --w0``, and on a scene with mu_k ``--u0``, ``--slip-u`` or ``--backspin``,
``--slip-v``) on the scene of ``--scene``, or as the point nearest ``--at`` of a survey file or a
result (its scene, method and horizon). Exit status: 0 written; 1 the output could not be
written; 2 bad input (nothing written); 130 interrupted.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

from ..errortext import suggest
from ..figurefile import FORMATS, check_figure_size, output_format, save_figure
from ..io.results import open_result
from ..mapspec import LookError, parse_at
from ..orbitplot import (
    FIGURE_SIZE,
    MAX_FPS,
    MAX_FRAMES,
    check_animation,
    orbit_figure,
    write_animation,
)
from ..orbitview import DEFAULT_SAMPLES, MAX_SAMPLES, Orbit, orbit, orbit_at
from ..scene import Scene
from ..surveyfile import parse_survey
from . import Command, InputError, load_plan
from .look import drawing

__all__ = ["COMMAND"]

DESCRIPTION = """\
Draw one orbit: the centre's path on its cone (3-D), from above with the turning circles
r_min sin(alpha) and r_max sin(alpha) of the closed form (and the rim), and r(t) against r_min
and r_max; the trajectory's events marked (apsides; on a scene with mu_k the slip, roll,
spin_stop, rest, spill...) and its sliding stretches shaded. --animate writes the ball rolling
along it, a mark on its surface turned by its attitude (its spin), as a GIF (or an MP4 where
ffmpeg is on the PATH).

The orbit is given either by its invariants or a launch, on the scene of --scene (default the
engine's Scene()), or as the point of SOURCE (a survey file, or a result: its scene, method and
horizon) nearest to --at (axes not named: their middle values). It is integrated by
engine.simulate (dop853, rtol 1e-10 unless the survey names an integrator), from r_min or
from the launch point, for 6 radial periods of a bounded orbit on a scene without losses,
else to --t-end (default: the survey's horizon, or 6 closed-form periods)."""

EPILOG = """\
examples:
  conesurvey orbit --alpha 0.5 --energy 8 --h 0 --Lz 0.5 -o rosette.png
  conesurvey orbit --alpha 0.5 --r0 2 --v0 1 --w0 0 --animate roll.gif
  conesurvey orbit surveys/gravity_precession.toml --at alpha=0.5,energy=0.3,h=0,Lz=1
  conesurvey orbit surveys/slide_and_roll.toml --at u0=1.5,slip_u=3 -o story.png

exit status: 0 written, 1 output not written, 2 bad input or usage, 130 interrupted"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", nargs="?", metavar="SOURCE",
                   help="a survey file (TOML) or a result (OUT.nc, OUT.zarr): the point of "
                   "its grid nearest --at")  # fmt: skip
    p.add_argument(
        "--at",
        action="append",
        metavar="AXIS=VALUE[,...]",
        help="the point of SOURCE's grid (nearest values; default: middle values)",
    )
    for name, unit in (("alpha", "radian"), ("energy", "J"), ("h", "m/s"), ("Lz", "kg m2/s"),
                       ("r0", "m"), ("v0", "m/s"), ("w0", "m/s"), ("u0", "m/s"),
                       ("slip-u", "m/s"), ("backspin", "m/s"), ("slip-v", "m/s")):  # fmt: skip
        p.add_argument(f"--{name}", type=float, metavar="X", help=f"[{unit}]")
    p.add_argument(
        "--scene",
        action="append",
        metavar="KEY=VALUE[,...]",
        help="the scene without SOURCE (any field of engine.Scene, e.g. g=9.81,rim=3)",
    )
    p.add_argument("--method", default=None, help="rk45 or dop853 (default dop853)")
    p.add_argument("--rtol", type=float, default=None, help="default 1e-10")
    p.add_argument("--t-end", type=float, metavar="SECONDS", help="how long to follow it")
    p.add_argument("--periods", type=int, metavar="N", help="radial periods to follow")
    p.add_argument("--samples", type=int, default=DEFAULT_SAMPLES,
                   help=f"points of the path drawn (default {DEFAULT_SAMPLES}, at most "
                   f"{MAX_SAMPLES:,})")  # fmt: skip
    p.add_argument(
        "-o",
        "--output",
        metavar="ORBIT.png",
        help=f"the picture ({', '.join(FORMATS)}; default orbit.png here)",
    )
    p.add_argument("--animate", metavar="ORBIT.gif", help="also write an animation (.gif, .mp4)")
    p.add_argument("--frames", type=int, default=120, help=f"frames (default 120, <= {MAX_FRAMES})")
    p.add_argument(
        "--fps", type=float, default=24.0, help=f"frames a second (default 24, <= {MAX_FPS})"
    )
    p.add_argument("--dpi", type=int, default=100, help="resolution (default 100; 80 animated)")
    p.add_argument("--overwrite", action="store_true", help="replace the outputs if they exist")


def _scene(items: list[str] | None) -> Scene:
    """``--scene g=9.81,rim=3`` as a Scene; LookError naming a key or value it refuses."""
    fields = {f.name: f for f in dataclasses.fields(Scene) if not f.name.startswith("_")}
    kw: dict[str, Any] = {}
    for item in items or ():
        for part in filter(None, (x.strip() for x in item.split(","))):
            key, sep, text = part.partition("=")
            key = key.strip()
            if not sep:
                raise LookError(f"--scene {part!r}: expected KEY=VALUE, e.g. g=9.81")
            if key not in fields:
                raise LookError(f"--scene: no field {key!r}{suggest(key, tuple(fields))}")
            if isinstance(fields[key].default, bool):
                if text.strip().lower() not in ("true", "false"):
                    raise LookError(f"--scene {key}={text!r}: must be true or false")
                kw[key] = text.strip().lower() == "true"
            else:
                try:
                    kw[key] = float(text)
                except ValueError:
                    raise LookError(f"--scene {key}={text.strip()!r}: not a number") from None
    try:
        return Scene(**kw)
    except ValueError as exc:
        raise LookError(f"--scene: {exc}") from None


def _given(args: argparse.Namespace) -> dict[str, float]:
    names = ("alpha", "energy", "h", "Lz", "r0", "v0", "w0", "u0", "slip_u", "backspin", "slip_v")
    return {n: getattr(args, n) for n in names if getattr(args, n) is not None}


def _orbit(args: argparse.Namespace, animate: bool) -> tuple[Orbit, str]:
    opts: dict[str, Any] = dict(samples=args.samples, attitude=animate)
    if args.t_end is not None:
        opts["t_end"] = args.t_end
    if args.periods is not None:
        opts["periods"] = args.periods
    if args.source is None:
        given = _given(args)
        if args.at:
            raise LookError("--at picks a point of SOURCE: give a survey file or a result")
        if "alpha" not in given:
            raise LookError("give --alpha and --energy --h --Lz (an orbit) or --r0 --v0 --w0 "
                            "(a launch), or a SOURCE and --at")  # fmt: skip
        o = orbit(scene=_scene(args.scene), method=args.method or "dop853",
                  rtol=args.rtol or 1e-10, **given, **opts)  # fmt: skip
        return o, ""
    if args.scene or _given(args):
        raise LookError("with SOURCE the point is --at AXIS=VALUE,... and the scene its own")
    plan = _source_plan(args.source)
    axes = dict(zip(plan.dims, plan.axes, strict=True))
    horizon = plan.horizon.time if plan.horizon is not None else None
    o, at = orbit_at(plan.dims, axes, parse_at(args.at), scene=plan.scene,
                     method=args.method or plan.method.name, rtol=args.rtol or plan.rtol,
                     energy_relative=plan.energy_relative, horizon_time=horizon,
                     **opts)  # fmt: skip
    return o, ", ".join(f"{k} = {v:.6g}" for k, v in at.items())


def _source_plan(source: str) -> Any:
    """The run plan of a survey file, or of the survey a result stores."""
    if source.lower().endswith(".toml"):
        return load_plan(source)
    with open_result(source) as result:
        text = result.ds.attrs.get("survey_definition")
    if not text:
        raise LookError(f"{source}: holds no survey_definition to take the scene from")
    return parse_survey(str(text), origin=source).plan


def _run(args: argparse.Namespace, command_line: str = "") -> int:
    return drawing(lambda: _orbit_command(args))


def _orbit_command(args: argparse.Namespace) -> int:
    out = Path(args.output) if args.output else Path.cwd() / "orbit.png"
    output_format(out)
    check_figure_size(FIGURE_SIZE, args.dpi)
    anim = Path(args.animate) if args.animate else None
    anim_dpi = min(args.dpi, 80)
    if anim is not None:
        check_animation(anim, args.frames, args.fps, anim_dpi)
    for path in [out] + ([anim] if anim else []):
        if path.is_dir() or not path.parent.is_dir():
            raise LookError(f"output {path}: a directory, or in one that does not exist")
        if path.exists() and not args.overwrite:
            raise LookError(f"output file exists: {path} (use --overwrite to replace it)")
    try:
        o, at = _orbit(args, anim is not None)
    except (InputError, ValueError) as exc:  # a survey file's, or an input the engine refuses
        raise LookError(str(exc)) from None
    save_figure(orbit_figure(o), out, overwrite=args.overwrite, dpi=args.dpi)
    where = f" (the grid point {at})" if at else ""
    tr = o.traj
    print(f"wrote {out}: {o.orbit_class} orbit{where}, r {o.r_min:.6g} .. {o.r_max:.6g} m, "
          f"{float(tr['time'].values[-1]):.4g} s, {len(_events_of(o))} events")  # fmt: skip
    if anim is not None:
        write_animation(o, anim, frames=args.frames, fps=args.fps, dpi=anim_dpi,
                        overwrite=args.overwrite)  # fmt: skip
        spin = "" if o.has_attitude else " (no spin mark: a sliding scene has no attitude)"
        print(f"wrote {anim}: {args.frames} frames at {args.fps:g} per second{spin}")
    return 0


def _events_of(o: Orbit) -> list[float]:
    return list(o.traj["event_time"].values) if "event_time" in o.traj else []


COMMAND = Command(
    name="orbit",
    help="draw one orbit on its cone, from above and r(t); --animate it (GIF, MP4)",
    description=DESCRIPTION,
    add_arguments=add_arguments,
    run=_run,
    epilog=EPILOG,
)

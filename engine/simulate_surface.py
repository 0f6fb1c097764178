"""One trajectory on a surface of revolution: :func:`engine.simulate` with ``surface=``.

The ball starts at its launch (the centre at ``rho0`` from the axis, the cylinder at height
``z0``, with ``v0`` along the parallel, spin ``w0`` and ``u0`` along the meridian; theta = 0,
t = 0) and is followed by the surface model (``engine.kernels.surface``) through the same run
kernel as on the cone, across stops by rolling resistance, to ``t_end`` or its ``periods``, or
to its end: over the rim, into the hole (the inner end), slipping, at rest.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr

from ._version import __version__
from .checks import PlanError, check_named_surface, check_number
from .kernels.fate_codes import REST_SPEED
from .kernels.layouts import ATTITUDE, P_V_REST
from .kernels.meridian import centre
from .kernels.model import SURFACE, scene_key
from .kernels.protocol import (
    FAILURE,
    HORIZON,
    NORMAL_ENDS,
    OK,
    RECORD_EVERY_DT,
    RECORD_STEPS,
    STATUS_MESSAGES,
)
from .kernels.surface import invariants
from .kernels.surface_starts import launch_state, set_point, tolerance_scales
from .methods import Method
from .scene import Scene
from .schema import TRAJECTORY
from .surface_maps import surface_params, surface_points
from .surfaces import Surface
from .trajectory_run import TrajectoryRun

__all__ = ["check_surface_launch", "simulate_surface"]

#: Recorded states and events a run starts with room for (grown as needed).
START_ROOM = 4096


def check_surface_launch(
    surface: Any, cone: dict[str, Any], why: str, launch: dict[str, Any]
) -> tuple[Surface, dict[str, float]]:
    """A launch on a surface (:func:`engine.simulate`, :func:`engine.story.story`): the surface
    named and checked, none of the cone's fields ``cone`` given (``why`` says what they are),
    the position the surface takes (rho0; z0 on the cylinder) and v0, w0 given, each a number.
    Returns (the surface, {"position", "v0", "w0"})."""
    surface = check_named_surface(surface, cone, lambda s: f"{why} ({s.position}, v0, w0, u0)")
    other = "z0" if surface.position == "rho0" else "rho0"
    if launch[other] is not None:
        raise PlanError(other, f"the {surface.kind}'s launch position is {surface.position}",
                        launch[other])  # fmt: skip
    values = {"position": launch[surface.position], "v0": launch["v0"], "w0": launch["w0"]}
    for name, value in values.items():
        field = surface.position if name == "position" else name
        if value is None:
            raise PlanError(field, "is needed: the launch on the surface")
        values[name] = check_number(field, value)
    return surface, values


def simulate_surface(
    surface: Surface,
    launch: dict[str, float],
    scene: Scene,
    method: Method,
    rtol: float,
    t_end: float | None,
    n_apsides: int,
    dt_out: float | None,
    max_steps: int,
) -> xr.Dataset:
    """The trajectory of ``launch`` (position, v0, w0, u0) on ``surface`` (inputs checked by
    :func:`engine.simulate`): a Dataset along ``time`` (q, the meridian parameter; rho and z of
    the centre; theta, u, v, w; Cartesian x, y, z; the energy's drift) and ``event``."""
    effects = scene_key(SURFACE, scene.effects_mask)
    p = surface_params(scene, surface)
    s1, s2 = surface.shape
    X = surface_points(np.array([s1]), np.array([s2]), np.array([launch["position"]]),
                       np.array([launch["v0"]]), np.array([launch["w0"]]),
                       np.array([launch["u0"]]))  # fmt: skip
    set_point(p, X, 0)
    y0 = launch_state(scene.effects_mask, p, X, 0)
    if y0.shape[0] == 0:
        raise ValueError(f"{surface.position}={launch['position']!r}: not a place on the "
                         f"{surface.kind} where the ball fits and touches")  # fmt: skip
    sc = tolerance_scales(scene.effects_mask, p, y0)
    p[P_V_REST] = REST_SPEED * rtol * max(sc[2], abs(y0[3]))
    run = TrajectoryRun(method.kernel_id, effects, p, (math.nan,) * 3, rtol, rtol * sc, max_steps)
    run.capacities(START_ROOM, START_ROOM)
    t_stop = math.inf if t_end is None else t_end
    record = RECORD_STEPS if dt_out is None else RECORD_EVERY_DT
    status = run.follow(y0, t_stop, n_apsides, record, dt_out or 0.0)
    return _dataset(
        surface, scene, p, method.name, rtol, launch, y0, status, run, t_end is not None
    )


def _dataset(surface, scene, p, method, rtol, launch, y0, status, run, to_time) -> xr.Dataset:
    t, Y, rate, ev_t, ev_kind, ev_y = run.arrays()
    if status not in NORMAL_ENDS:  # the run failed: say where, as an event
        ev_t, ev_kind = np.append(ev_t, run.t_final), np.append(ev_kind, np.int8(FAILURE))
        ev_y = np.vstack([ev_y, Y[-1:] if Y.shape[0] else y0[None]])
    elif status == OK and to_time:
        ev_t, ev_kind = np.append(ev_t, run.t_final), np.append(ev_kind, np.int8(HORIZON))
        ev_y = np.vstack([ev_y, run.y_final[None]])
    geo = np.array([centre(p, q)[:2] for q in Y[:, 0]]).reshape(-1, 2)
    rho, zc = geo[:, 0], geo[:, 1]
    th = Y[:, 1]
    E0 = invariants(y0, p)[0]
    E_t = np.array([invariants(y, p)[0] for y in Y])
    columns: dict[str, Any] = {
        "q": Y[:, 0],
        "rho": rho,
        "theta": th,
        "u": Y[:, 2],
        "v": Y[:, 3],
        "w": Y[:, 4],
        "x": rho * np.cos(th),
        "y": rho * np.sin(th),
        "z": zc,
        "E_drift": E_t - E0,
    }
    if scene.effects_mask & ATTITUDE:
        for i, name in enumerate("wxyz"):
            columns[f"quat_{name}"] = Y[:, 5 + i]
        columns["quat_norm_error"] = np.linalg.norm(Y[:, 5:9], axis=1) - 1.0
    data = {n: (("time",), c, TRAJECTORY[n].attrs()) for n, c in columns.items()}
    ev_rho = np.array([centre(p, q)[0] for q in ev_y[:, 0]])
    events = {"event_time": ev_t, "event_kind": ev_kind.astype(np.int8),
              "event_rho": ev_rho, "event_theta": ev_y[:, 1]}  # fmt: skip
    data.update({n: (("event",), c, TRAJECTORY[n].attrs()) for n, c in events.items()})
    ds = xr.Dataset(data, coords={"time": (("time",), t, TRAJECTORY["time"].attrs())})
    ds.time.encoding["_FillValue"] = None
    ds.attrs.update({
        "title": f"trajectory of a ball rolling on a {surface.kind}",
        "source": f"conesurvey {__version__}",
        "method": method, "rtol": rtol, "E0": E0, "status": int(status),
        "status_message": STATUS_MESSAGES[status], "n_steps": run.n_acc,
        "n_rejected": run.n_rej,
        **{f"launch_{k}": float(v) for k, v in launch.items()},
    })  # fmt: skip
    ds.attrs.update(surface.as_attrs())
    ds.attrs.update(scene.as_attrs())
    return ds

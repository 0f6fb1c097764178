"""One trajectory of a scene with kinetic friction ``mu_k``: rolling, sliding, rolling again
(:func:`engine.simulate`'s hybrid path), returned as an xarray Dataset.

The mode changes are the launch's story (:func:`engine.kernels.hybrid.hybrid_story`, as
:func:`engine.story.story` tells it); the samples between them are each stretch integrated
again from the state after its opening change (:mod:`engine.kernels.trajectory`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr

from ._jit import call_specialized
from ._version import __version__
from .hybrid import HYBRID_STATE, hybrid_model, hybrid_setup, whole_story
from .kernels.cone import set_alpha
from .kernels.hybrid import HYBRID_FATE_NAMES
from .kernels.hybrid_step import ARMED_KEPT, EV_NO_HOLD, EV_ROT_STOP, HYBRID_EVENT_NAMES
from .kernels.layouts import P_K, P_M
from .kernels.model import N_PARAMS
from .kernels.protocol import (
    AT_VERTEX,
    BUFFER_FULL,
    MAX_STEPS,
    OK,
    RESTED,
    SPILLED,
    STATUS_MESSAGES,
)
from .kernels.sliding import (
    H_C_SPIN,
    H_MU_K,
    MODE_ROLLING,
    MODE_SLIDING,
    N_HYBRID,
    N_HYBRID_PARAMS,
    hybrid_energy,
    spin_hold_margin,
)
from .kernels.trajectory import trace_stretches
from .scene import Scene
from .schema import TRAJECTORY, Variable

__all__ = ["HYBRID_TRAJECTORY", "HYBRID_EVENT_KINDS", "MODE_NAMES", "hybrid_trajectory"]

#: Modes (the ``mode`` variable's flag meanings).
MODE_NAMES = ("rolling", "sliding")
#: Event kinds of a hybrid trajectory: the story's mode changes and ends, and "failed".
HYBRID_EVENT_KINDS = (*HYBRID_EVENT_NAMES, "failed")
_FAILED = len(HYBRID_EVENT_NAMES)
_EV = {name: i for i, name in enumerate(HYBRID_EVENT_NAMES)}
#: Every kind the story's kernel records: its events, then its own marks, which split the
#: stretches (:data:`engine.kernels.hybrid_step.EV_ROT_STOP`, ``EV_NO_HOLD``) but are not
#: events of the trajectory.
_KIND_NAMES = (*HYBRID_EVENT_NAMES, "rot_stop", "no_hold")
assert (_KIND_NAMES.index("rot_stop"), _KIND_NAMES.index("no_hold")) == (EV_ROT_STOP, EV_NO_HOLD)
_WORK = {
    "W_effects": "work the effects acting through forces took since the start (rolling "
    "resistance and any applied effect of the scene)",
    "W_sliding_friction": "work done against sliding friction since the start (sticking "
    "impulses included)",
    "W_spin_friction": "work done against spin friction since the start",
}


def _f(units: str, long_name: str) -> Variable:
    return Variable("float64", units, long_name)


#: Variables of a hybrid trajectory beyond :data:`engine.schema.TRAJECTORY`'s (same names,
#: same meaning where they are shared).
HYBRID_TRAJECTORY: dict[str, Variable] = {
    "mode": Variable("int8", None, "mode of the contact", MODE_NAMES),
    "p1": _f("m s-1", "angular velocity about the generatrix's normal e1 times the radius"),
    "p2": _f("m s-1", "angular velocity about the parallel e2 times the radius (u when rolling)"),
    "slip_speed": _f("m s-1", "speed of the contact point |(u - p2, v + p1)| (0 when rolling)"),
    "energy": _f("J", "total energy E (kinetic, rotational and potential)"),
    "E_drift": _f("J", "total energy minus its initial value (falls by the work below)"),
    **{name: _f("J", text) for name, text in _WORK.items()},
    "balance_drift": _f(
        "J",
        "E + W_effects + W_sliding_friction + W_spin_friction "
        "- E(0): the energy balance, 0 up to the integration error",
    ),  # fmt: skip
    "event_kind": Variable("int8", None, "event kind", HYBRID_EVENT_KINDS),
    **{
        f"event_{n}": _f(TRAJECTORY[n].units or "1", f"{n} at the event")
        for n in ("r", "theta", "u", "v", "w")
    },  # fmt: skip
    **{f"event_{n}": _f("m s-1", f"{n} at the event") for n in ("p1", "p2")},
}


def _attrs(name: str) -> dict[str, Any]:
    var = HYBRID_TRAJECTORY.get(name) or TRAJECTORY[name]
    return var.attrs()


def _start(alpha, energy, h, Lz, r0, u0, slip_u, slip_v, scene):
    """The hybrid state of the launch (as :func:`.kernels.hybrid.hybrid_fate_of` builds it)."""
    s, c, M = math.sin(alpha), math.cos(alpha), scene.M
    y = np.zeros(N_HYBRID)
    v = Lz / (M * r0 * s)
    y[0], y[2], y[3] = r0, u0, v
    y[4] = slip_v - v
    y[5] = u0 - slip_u
    y[6] = h + Lz * c / (M * r0 * s * s)
    return y


def _stretches(key, y, mode, stuck, spin, hp, fate, ev_t, ev_kind, ev_y, t_last):
    """(t0, t1, start state, mode, stuck, the armed bits kept) of each stretch between the
    story's mode changes: the state after each change follows the story's rules
    (docs/physics.md "Switching between rolling and sliding", "Spin stick"), and so does the
    arming of the stops (:func:`.kernels.hybrid.hybrid_fate_of`); ``key`` the hybrid kernels'
    literal ``model`` (:func:`.hybrid.hybrid_model`)."""
    t0s, t1s, ys, modes, stucks, keeps = [], [], [], [], [], []
    t, keep = 0.0, 0
    for i in range(len(ev_t)):
        t0s.append(t), t1s.append(ev_t[i]), ys.append(y), modes.append(mode)
        stucks.append(stuck), keeps.append(keep)
        kind = _KIND_NAMES[ev_kind[i]]
        keep = ARMED_KEPT[ev_kind[i]]
        t = ev_t[i]
        y = ev_y[i].copy()
        if kind == "slip":
            mode = MODE_SLIDING
        elif kind == "roll":  # the story applied the sticking impulse (friction holds it)
            mode = MODE_ROLLING
        elif kind in ("rot_stop", "no_hold"):  # the state after it, sliding on
            pass
        elif kind == "spin_stop" and i == len(ev_t) - 1 and fate == "rest":
            return t0s, t1s, ys, modes, stucks, keeps  # the spin stopped in place, at rest
        elif kind == "spin_stop":  # the rest of the spin goes to spin friction
            y[9] += 0.5 * hp[P_K] * hp[P_M] * y[6] * y[6]
            y[6] = 0.0
            stuck = spin_hold_margin.py_func(key, y, hp) <= 0.0
        elif kind == "spin_go":
            y[6] = 0.0
            stuck = False
        elif kind == "rest" and not (i == len(ev_t) - 1 and fate in ("rest", "spinning")):
            y[2:6] = 0.0  # it starts again from rest (or stays, its spin stopping in place)
        else:  # spill, vertex, horizon, a final rest: the end
            return t0s, t1s, ys, modes, stucks, keeps
    t0s.append(t), t1s.append(max(t, t_last)), ys.append(y), modes.append(mode)
    stucks.append(stuck), keeps.append(keep)
    return t0s, t1s, ys, modes, stucks, keeps


def hybrid_trajectory(
    alpha: float,
    energy: float,
    h: float,
    Lz: float,
    r0: float,
    scene: Scene,
    method_id: int,
    method: str,
    rtol: float,
    t_end: float,
    dt_out: float | None,
    max_steps: int,
    u0: float,
    slip_u: float,
    slip_v: float,
    orbit_class: str,
) -> xr.Dataset:
    """The trajectory of :func:`engine.simulate` on a scene with ``mu_k`` (validated inputs)."""
    params, effects, spin = hybrid_setup(scene, math.inf)
    set_alpha(params, alpha)
    res = whole_story(method_id, params, effects, spin, scene,
                      (energy, h, Lz, r0, u0, slip_u, slip_v), rtol, t_end, max_steps)  # fmt: skip
    fate_id, f, story_steps, n_ev, ev_t, ev_kind, ev_y = res
    fate = HYBRID_FATE_NAMES[fate_id]
    if fate == "no_orbit":
        raise ValueError(f"the orbit starts at r = {r0!r} m, beyond the rim ({scene.rim!r} m)")
    hp = np.empty(N_HYBRID_PARAMS)
    hp[:N_PARAMS] = params
    hp[H_MU_K], hp[H_C_SPIN] = scene.mu_k, scene.c_spin
    y0 = _start(alpha, energy, h, Lz, r0, u0, slip_u, slip_v, scene)
    mode = MODE_SLIDING if (slip_u != 0.0 or slip_v != 0.0) else MODE_ROLLING
    key = hybrid_model(effects)
    stuck = bool(spin and y0[6] == 0.0 and spin_hold_margin.py_func(key, y0, hp) <= 0.0)
    if fate == "vertex" and n_ev == 0:  # it starts in the vertex region, moving in
        ev_t, ev_kind, ev_y = np.zeros(1), np.array([_EV["vertex"]], np.int8), y0[None].copy()
    t_last = float(f[0]) if math.isfinite(f[0]) else 0.0
    t0, t1, ys, modes, stucks, keeps = _stretches(key, y0, mode, stuck, spin, hp, fate, ev_t,
                                                  ev_kind, ev_y, t_last)  # fmt: skip
    told = ev_kind < len(HYBRID_EVENT_NAMES)  # the story's events, without the kernel's marks
    ev_t, ev_kind, ev_y, n_ev = ev_t[told], ev_kind[told], ev_y[told], int(told.sum())
    states = np.vstack([y0[None], ev_y])
    atol = rtol * np.maximum(np.abs(states).max(axis=0), 1e-300)
    vel = float(np.abs(states[:, 2:7]).max())
    E0 = float(hybrid_energy.py_func(key, *y0[[0, 2, 3, 4, 5, 6]], hp))
    atol[0] = rtol * r0
    atol[1] = rtol
    atol[2:7] = rtol * vel
    atol[7:] = rtol * max(abs(E0), 0.5 * scene.M * vel * vel)
    args_head = (method_id, key, hp, np.array(t0), np.array(t1), np.array(ys),
                 np.array(modes, np.int64), np.array(stucks, np.bool_),
                 np.array(keeps, np.int64), rtol, atol,
                 float(dt_out or 0.0), int(max_steps))  # fmt: skip
    n_cap = len(t0) + (int(t1[-1] / dt_out) + 2 if dt_out else 4096)
    while True:
        tr = (np.empty(n_cap), np.empty((n_cap, N_HYBRID)), np.empty(n_cap, np.int64))
        literal = ("method", "model")
        st, n_tr, trace_steps = call_specialized(trace_stretches, (*args_head, *tr), literal)
        if st != BUFFER_FULL:
            break
        n_cap *= 4
    t, Y, modes_t = tr[0][:n_tr], tr[1][:n_tr], tr[2][:n_tr]
    status = {"spilled": SPILLED, "vertex": AT_VERTEX, "rest": RESTED, "spinning": RESTED}.get(
        fate, OK
    )
    if fate == "failed" or st != OK:
        status = st if st != OK else MAX_STEPS
        ev_t = np.append(ev_t, t[-1])
        ev_kind = np.append(ev_kind, np.int8(_FAILED))
        ev_y = np.vstack([ev_y, Y[-1:]])
    elif fate in ("rolling", "sliding"):  # it ran to t_end: the horizon is where it ended
        ev_t = np.append(ev_t, t[-1])
        ev_kind = np.append(ev_kind, np.int8(_EV["horizon"]))
        ev_y = np.vstack([ev_y, Y[-1:]])
    elif n_ev:  # it ended at its last event: the trajectory too
        Y[-1] = ev_y[-1]
    return _dataset(scene, alpha, energy, h, Lz, u0, slip_u, slip_v, method, rtol, orbit_class,
                    fate, status, int(story_steps) + int(trace_steps), t, Y, modes_t, ev_t,
                    ev_kind, ev_y, hp, key, E0)  # fmt: skip


def _dataset(scene, alpha, energy, h, Lz, u0, slip_u, slip_v, method, rtol, orbit_class, fate,
             status, n_steps, t, Y, modes, ev_t, ev_kind, ev_y, hp, key,
             E0) -> xr.Dataset:  # fmt: skip
    s, c = math.sin(alpha), math.cos(alpha)
    col = dict(zip(HYBRID_STATE, Y.T, strict=True))
    r, th = col["r"], col["theta"]
    E = hybrid_energy.py_func(key, r, col["u"], col["v"], col["p1"], col["p2"], col["w"], hp)
    work = col["W_effects"] + col["W_sliding_friction"] + col["W_spin_friction"]
    columns: dict[str, Any] = {
        "mode": modes.astype(np.int8),
        **{n: col[n] for n in ("r", "theta", "u", "v", "w", "p1", "p2")},
        "x": r * s * np.cos(th),
        "y": r * s * np.sin(th),
        "z": r * c,
        "slip_speed": np.hypot(col["u"] - col["p2"], col["v"] + col["p1"]),
        "energy": E,
        "E_drift": E - E0,
        **{n: col[n] for n in _WORK},
        "balance_drift": E + work - E0,
    }
    data = {name: (("time",), v, _attrs(name)) for name, v in columns.items()}
    ev = dict(zip(HYBRID_STATE, ev_y.T, strict=True))
    events = {"event_time": ev_t, "event_kind": ev_kind.astype(np.int8)}
    events.update({f"event_{n}": ev[n] for n in ("r", "theta", "u", "v", "w", "p1", "p2")})
    data.update({n: (("event",), v, _attrs(n)) for n, v in events.items()})
    ds = xr.Dataset(data, coords={"time": (("time",), t, _attrs("time"))})
    ds.time.encoding["_FillValue"] = None
    ds.attrs.update(
        {
            "title": "trajectory of a sphere rolling and sliding inside a cone",
            "source": f"conesurvey {__version__}",
            "method": method,
            "rtol": rtol,
            "alpha": alpha,
            "energy": energy,
            "h": h,
            "Lz": Lz,
            "u0": u0,
            "slip_u": slip_u,
            "slip_v": slip_v,
            "orbit_class": orbit_class,
            "E0": E0,
            "fate": fate,
            "status": int(status),
            "status_message": STATUS_MESSAGES[status],
            "n_steps": n_steps,
        }
    )
    ds.attrs.update(scene.as_attrs())
    return ds

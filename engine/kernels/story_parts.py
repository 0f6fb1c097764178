"""The pieces of a launch's whole story (:mod:`.hybrid`), one rule for the scalar kernel
(:func:`.hybrid.hybrid_fate_of`) and the lanes (:mod:`.lanes_hybrid`).

A story is a loop: a rolling stretch without spin friction is a fate run
(:func:`rolling_stretch` gives its start, :func:`.fate.fate_run` runs it, :func:`rolled` takes
its end: a slip starts sliding); anything else runs on the hybrid steps, one segment to its
first event (:func:`hybrid_stretch`, the switches and their rules). :func:`story_begin` sets
it up and :func:`story_result` gives its rows. Its state between the pieces is a float array
``hs`` (:data:`HS_T` ...) and an int array ``hi`` (:data:`HI_MODE` ...), so a lane can hold
it while other lanes step.

``spin`` (a literal: 0 or 1) compiles spin friction in; ``effects`` is the rolling scene's
literal effect set (with :data:`.model.SLIP_CHECK`: the static friction limit).
"""

from __future__ import annotations

import math

from .._jit import kernel
from .contact import holds_at_rest, resume_rolling, rolling_energy, rolling_orbit, story_start
from .effects import DISSIPATIVE
from .fate import (
    FAILED,
    FATE_LIFTED_OFF,
    FATE_REST,
    FATE_SLIPPED,
    FATE_SPILLED,
    FATE_VERTEX,
    MAX_RESTARTS,
    ROLLING,
)
from .hybrid_step import (
    ARMED_ROLL,
    ARMED_ROT,
    ARMED_SPIN,
    EV_LIFTOFF,
    EV_NO_HOLD,
    EV_REST,
    EV_RIM,
    EV_ROT_STOP,
    EV_SLIP,
    EV_SPIN_GO,
    EV_SPIN_STOP,
    EV_STICK,
    EV_THETA,
    EV_VERTEX,
    SEG_FAILED,
    SEG_TIME,
    release_spin,
    segment,
)
from .layouts import P_CRR, P_K, P_M, P_V_REST, Y_R, Y_THETA, Y_U, Y_V, Y_W
from .model import energy, kinetic_energy
from .protocol import push_event
from .sliding import (
    MODE_ROLLING,
    MODE_SLIDING,
    N_HYBRID,
    YH_P1,
    YH_P2,
    YH_R,
    YH_THETA,
    YH_U,
    YH_V,
    YH_W,
    YH_WORK_EFFECTS,
    YH_WORK_SLIDE,
    YH_WORK_SPIN,
    hold_margin,
    hybrid_energy,
    hybrid_params,
    spin_hold_margin,
    stick,
)

#: Fate codes beyond :data:`.fate.FATE_NAMES`: still sliding at the horizon; at rest and held
#: there, but spinning in place about the normal (no spin friction to stop it: ``fate_spin``
#: holds the spin). ``rest`` is the centre and the spin both stopped.
SLIDING = 7
SPINNING = 8
HYBRID_FATE_NAMES = ("no_orbit", "rolling", "spilled", "slipped", "rest", "vertex", "failed",
                     "sliding", "spinning", "lifted_off")  # fmt: skip
assert HYBRID_FATE_NAMES.index("lifted_off") == FATE_LIFTED_OFF  # one code, one fate
#: A hybrid fate map's launches travel as one tuple of arrays (numba's own type: see
#: docs/architecture.md's kernel contract), a column at each of these places: the rolling
#: orbit's cone, radial energy [J], spin invariant h [m/s] and L_z, where it starts [m], its
#: radial speed and slip velocity [m/s] (:func:`.hybrid.hybrid_fate_points`, the lanes).
LAUNCH_COLUMNS = ("alpha", "energy", "h", "Lz", "r_start", "u0", "slip_u", "slip_v")
L_ALPHA, L_ENERGY, L_H, L_LZ, L_R_START, L_U0, L_SLIP_U, L_SLIP_V = range(len(LAUNCH_COLUMNS))
#: Rows of the float output of :func:`hybrid_fate_points`.
HYBRID_ROWS = ("fate_time", "fate_r", "fate_theta", "revolutions", "energy_lost",
               "invariant_drift", "slide_time", "slip_episodes", "fate_speed", "final_energy",
               "final_h", "final_Lz", "lost_effects", "lost_sliding_friction",
               "lost_spin_friction", "fate_spin")  # fmt: skip


@kernel
def mode_energy(model, y, hp, mode):
    """E [J] of the hybrid state: the rolling formula while rolling (as a fate map computes
    it), the sliding one otherwise."""
    if mode == MODE_ROLLING:
        return rolling_energy(model, y[YH_R], y[YH_U], y[YH_V], y[YH_W], hp)
    return hybrid_energy(model, y[YH_R], y[YH_U], y[YH_V], y[YH_P1], y[YH_P2], y[YH_W], hp)


#: Floats of a story's state (``hs``): its time [s], the time spent sliding [s], the energy at
#: the start [J] and its scale, the invariants of the last rolling orbit, the launch's orbit.
HS_T, HS_SLIDE, HS_E0, HS_SCALE, HS_FE, HS_FH, HS_FL, HS_ENERGY, HS_H, HS_LZ = range(10)
N_HS = 10
#: Ints of a story's state (``hi``): the mode, slip episodes, the spin stick (0/1), the arming
#: bits, steps so far, restarts from rest, the fate (-1 while it runs), events recorded.
HI_MODE, HI_EPISODES, HI_STUCK, HI_ARMED, HI_STEPS, HI_RESTARTS, HI_FATE, HI_NEV = range(8)
N_HI = 8


@kernel
def story_begin(effects, model, spin, p, mu_k, c_spin, start, rtol, out, y0, atol, hp, y, hatol, hs,
                hi):  # fmt: skip
    """Set up the story of a launch (``start``: the model's launch tuple,
    :func:`.contact.story_start`; its last two are the slip velocity (slip_u, slip_v) [m/s]):
    the rest threshold in p, the rolling start state y0 and its tolerances atol (length
    ``state_size(effects)``), the hybrid parameters hp, state y and tolerances hatol, and the
    story's state hs, hi. Returns the fate where the launch ends at its start (``out`` then
    holds its floats), else -1."""
    slip_u = start[5]
    slip_v = start[6]
    M = p[P_M]
    fate, e_true, vel, orbit = story_start(model, effects, p, start, rtol, out, y0, atol)
    if fate >= 0:
        return fate
    hq = hybrid_params(p, mu_k, c_spin)
    for j in range(hq.shape[0]):
        hp[j] = hq[j]
    for j in range(N_HYBRID):
        y[j] = 0.0
    y[YH_R] = y0[Y_R]
    y[YH_U] = y0[Y_U]
    y[YH_V] = y0[Y_V]
    y[YH_P1] = slip_v - y0[Y_V]
    y[YH_P2] = y0[Y_U] - slip_u
    y[YH_W] = y0[Y_W]
    hatol[YH_R] = atol[Y_R]
    hatol[YH_THETA] = rtol
    hatol[YH_U] = atol[Y_U]
    hatol[YH_V] = atol[Y_V]
    hatol[YH_P1] = rtol * vel
    hatol[YH_P2] = rtol * vel
    hatol[YH_W] = atol[Y_W]
    e_scale = max(abs(e_true), 0.5 * M * vel * vel)
    hatol[YH_WORK_EFFECTS] = rtol * e_scale
    hatol[YH_WORK_SLIDE] = rtol * e_scale
    hatol[YH_WORK_SPIN] = rtol * e_scale
    mode = MODE_SLIDING if (slip_u != 0.0 or slip_v != 0.0) else MODE_ROLLING
    if mode == MODE_ROLLING:
        E0 = energy(y0, p, effects)
        scale = max(abs(E0), kinetic_energy(y0, p))
    else:
        E0 = hybrid_energy(model, y[YH_R], y[YH_U], y[YH_V], y[YH_P1], y[YH_P2], y[YH_W], hp)
        scale = max(abs(E0), E0 - hybrid_energy(model, y[YH_R], 0.0, 0.0, 0.0, 0.0, 0.0, hp))
    stuck = spin == 1 and y[YH_W] == 0.0 and spin_hold_margin(model, y, hp) <= 0.0
    hi[HI_MODE] = mode
    hi[HI_EPISODES] = 1 if mode == MODE_SLIDING else 0
    hi[HI_STUCK] = 1 if stuck else 0
    hi[HI_ARMED] = 0
    hi[HI_STEPS] = 0
    hi[HI_RESTARTS] = 0
    hi[HI_FATE] = -1
    hi[HI_NEV] = 0
    hs[HS_T] = 0.0
    hs[HS_SLIDE] = 0.0
    hs[HS_E0] = E0
    hs[HS_SCALE] = scale
    hs[HS_FE] = math.nan
    hs[HS_FH] = math.nan
    hs[HS_FL] = math.nan
    if mode == MODE_ROLLING:
        hs[HS_FE] = orbit[0]
        hs[HS_FH] = orbit[1]
        hs[HS_FL] = orbit[2]
    hs[HS_ENERGY] = orbit[0]
    hs[HS_H] = orbit[1]
    hs[HS_LZ] = orbit[2]
    return -1


@kernel
def story_runs_out(max_steps, hi):
    """Whether the story has used its step budget or restarts (then its fate is FAILED)."""
    if hi[HI_STEPS] >= max_steps or hi[HI_RESTARTS] > MAX_RESTARTS:
        hi[HI_FATE] = FAILED
        return True
    return False


@kernel
def rolling_stretch(effects, model, p, y, y0, atol, rtol, hs, hi, yr, ra):
    """The start of the story's next rolling stretch without spin friction, a fate run
    (:func:`.fate.fate_run`): its state into yr, its tolerances into ra (the launch's own where
    it has not slipped yet). Returns the stretch's orbit (calE, h, L_z)."""
    nr = yr.shape[0]
    if hi[HI_EPISODES] == 0:
        for j in range(nr):
            yr[j] = y0[j]
            ra[j] = atol[j]
        return hs[HS_ENERGY], hs[HS_H], hs[HS_LZ]
    for j in range(nr):
        yr[j] = 0.0
    yr[Y_R] = y[YH_R]
    yr[Y_THETA] = y[YH_THETA]
    yr[Y_U] = y[YH_U]
    yr[Y_V] = y[YH_V]
    yr[Y_W] = y[YH_W]
    if effects & DISSIPATIVE:  # the rolling state's work: the effects' forces'
        yr[nr - 1] = y[YH_WORK_EFFECTS]
    return resume_rolling(model, effects, p, yr, rtol, ra)


@kernel
def rolled(effects, f, dt, yr, st, y, hs, hi, ev_t, ev_kind, ev_y):
    """The story after a rolling stretch that ended with fate f, dt [s] and st steps after its
    start in the state yr: a slip starts sliding; any other end is the story's."""
    nr = yr.shape[0]
    hs[HS_T] += dt
    hi[HI_STEPS] += st
    y[YH_R] = yr[Y_R]
    y[YH_THETA] = yr[Y_THETA]
    y[YH_U] = yr[Y_U]
    y[YH_V] = yr[Y_V]
    y[YH_P1] = -yr[Y_V]
    y[YH_P2] = yr[Y_U]
    y[YH_W] = yr[Y_W]
    if effects & DISSIPATIVE:  # the rolling state's work: the effects' forces'
        y[YH_WORK_EFFECTS] = yr[nr - 1]
    t = hs[HS_T]
    if f != FATE_SLIPPED:
        hi[HI_FATE] = f
        if f == FATE_SPILLED:
            hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_RIM, y)
        elif f == FATE_VERTEX:
            hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_VERTEX, y)
        elif f == FATE_LIFTED_OFF:
            hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_LIFTOFF, y)
        elif f == FATE_REST:
            hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_REST, y)
            if y[YH_W] != 0.0:  # the centre is held at rest, the sphere spins on in place
                hi[HI_FATE] = SPINNING
        return
    hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_SLIP, y)
    hi[HI_MODE] = MODE_SLIDING
    hi[HI_EPISODES] += 1
    hi[HI_ARMED] &= ARMED_SPIN


@kernel
def hybrid_stretch(method, model, p, y, hp, rtol, hatol, t_horizon, max_steps, K, ytmp, ynew, yev,
                   hs, hi, ev_t, ev_kind, ev_y):  # fmt: skip
    """One segment of the story on the hybrid steps (sliding, or rolling with spin friction:
    :func:`.hybrid_step.segment`) and the switch at its end; the story's fate where it ends."""
    mode = hi[HI_MODE]
    stuck = hi[HI_STUCK] != 0
    end, t, st, dt, armed = segment(method, model, y, hp, mode, stuck, hi[HI_ARMED], hs[HS_T],
                                    t_horizon, rtol, hatol, max_steps - hi[HI_STEPS], K, ytmp, ynew,
                                    yev)  # fmt: skip
    hs[HS_T] = t
    hi[HI_ARMED] = armed
    hi[HI_STEPS] += st
    if mode == MODE_SLIDING:
        hs[HS_SLIDE] += dt
    if end == SEG_FAILED:
        hi[HI_FATE] = FAILED
        return
    if end == SEG_TIME or end == EV_THETA:
        hi[HI_FATE] = SLIDING if mode == MODE_SLIDING else ROLLING
        if end == EV_THETA:
            hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, end, y)
        return
    if end == EV_REST:  # the stop: the next stretch starts within the rest threshold, where
        return  # .story_switches.stretch_start carries it to zero speed (and what follows)
    if end == EV_STICK:
        # the sphere rolls again if static friction holds the rolling, or if the impulse
        # leaves it rolling within the rest threshold where rolling resistance holds a sphere
        # at rest (it has slid to a stop: the next stretch starts at rest); otherwise it slides
        # on, and that is no ``roll``: an EV_NO_HOLD, recorded for the sampled trajectory only
        yt = y.copy()
        stick(yt, hp)
        speed = math.sqrt(yt[YH_U] * yt[YH_U] + yt[YH_V] * yt[YH_V])
        stops = hp[P_CRR] > 0.0 and holds_at_rest(model, p, yt) and speed <= hp[P_V_REST]
        if stops or hold_margin(model, yt, hp) <= 0.0:
            stick(y, hp)
            hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_STICK, y)
            hi[HI_MODE] = MODE_ROLLING
            fe, fh, fl = rolling_orbit(model, y[YH_R], y[YH_U], y[YH_V], y[YH_W], hp)
            hs[HS_FE] = fe
            hs[HS_FH] = fh
            hs[HS_FL] = fl
            hi[HI_ARMED] &= ARMED_SPIN
        else:
            hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_NO_HOLD, y)
            hi[HI_ARMED] &= ARMED_SPIN | ARMED_ROT
        return
    if end == EV_ROT_STOP:  # (p1, p2) down to the threshold: the rest of it to the resistance
        y[YH_WORK_EFFECTS] += 0.5 * hp[P_K] * hp[P_M] * (y[YH_P1] * y[YH_P1] + y[YH_P2] * y[YH_P2])
        y[YH_P1] = 0.0
        y[YH_P2] = 0.0
        hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, end, y)  # (the state after)
        hi[HI_ARMED] &= ARMED_ROLL | ARMED_SPIN
        return
    hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, end, y)
    if end == EV_RIM:
        hi[HI_FATE] = FATE_SPILLED
    elif end == EV_LIFTOFF:
        hi[HI_FATE] = FATE_LIFTED_OFF
    elif end == EV_VERTEX:
        hi[HI_FATE] = FATE_VERTEX
    elif end == EV_SLIP:
        hi[HI_MODE] = MODE_SLIDING
        hi[HI_EPISODES] += 1
        hi[HI_ARMED] &= ARMED_SPIN
    elif end == EV_SPIN_STOP:  # |w| down to the threshold: the rest of it to spin friction
        y[YH_WORK_SPIN] += 0.5 * hp[P_K] * hp[P_M] * y[YH_W] * y[YH_W]
        y[YH_W] = 0.0
        hi[HI_STUCK] = 1 if spin_hold_margin(model, y, hp) <= 0.0 else 0
        hi[HI_ARMED] &= ARMED_ROLL | ARMED_ROT
    elif end == EV_SPIN_GO:
        hi[HI_STUCK] = 0
        release_spin(y, hp)
        hi[HI_ARMED] &= ARMED_ROLL | ARMED_ROT


@kernel
def story_result(effects, model, spin, p, y, y0, hp, hs, hi, out):
    """The rows :data:`HYBRID_ROWS` of the ended story into ``out``; returns its fate."""
    mode = hi[HI_MODE]
    episodes = hi[HI_EPISODES]
    fe = hs[HS_FE]
    fh = hs[HS_FH]
    fl = hs[HS_FL]
    if mode == MODE_SLIDING:
        fe = math.nan
        fh = math.nan
        fl = math.nan
    E1 = mode_energy(model, y, hp, mode)
    if mode == MODE_ROLLING and episodes == 0 and spin == 0:
        yr = y0.copy()
        yr[Y_R] = y[YH_R]
        yr[Y_U] = y[YH_U]
        yr[Y_V] = y[YH_V]
        yr[Y_W] = y[YH_W]
        E1 = energy(yr, p, effects)
    if hi[HI_FATE] == FATE_REST or hi[HI_FATE] == SPINNING:  # its state at rest
        fe, fh, fl = rolling_orbit(model, y[YH_R], y[YH_U], y[YH_V], y[YH_W], hp)
    E0 = hs[HS_E0]
    work = y[YH_WORK_EFFECTS] + y[YH_WORK_SLIDE] + y[YH_WORK_SPIN]
    out[0] = hs[HS_T]
    out[1] = y[YH_R]
    out[2] = y[YH_THETA]
    out[3] = abs(y[YH_THETA]) / (2.0 * math.pi)
    out[4] = E0 - E1
    out[5] = abs(E1 + work - E0) / hs[HS_SCALE]
    out[6] = hs[HS_SLIDE]
    out[7] = episodes
    out[8] = math.sqrt(y[YH_U] * y[YH_U] + y[YH_V] * y[YH_V])
    out[9] = fe
    out[10] = fh
    out[11] = fl
    out[12] = y[YH_WORK_EFFECTS]
    out[13] = y[YH_WORK_SLIDE]
    out[14] = y[YH_WORK_SPIN]
    out[15] = y[YH_W]
    return hi[HI_FATE]

"""What the story of a launch (:mod:`.story_parts`) decides between its stretches, on the state
at a stretch's start rather than on a crossing within its steps: the centre's stop by rolling
resistance (carried to zero speed) and what follows it (a restart, a slip at rest, the spin
stopping in place, or spinning on), a slip where static friction cannot hold a rolling start,
a stuck spin released at once (docs/physics.md "Where the run goes", "Rest").
"""

from __future__ import annotations

import math

from .._jit import kernel
from .contact import contact_frame, holds_at_rest, leaves_contact, rest_spin_rate, rolling_orbit
from .fate import FATE_LIFTED_OFF, FATE_REST, ROLLING
from .hybrid_step import (
    ARMED_ROLL,
    ARMED_ROT,
    ARMED_SPIN,
    EV_LIFTOFF,
    EV_REST,
    EV_SLIP,
    EV_SPIN_GO,
    EV_SPIN_STOP,
    release_spin,
)
from .layouts import P_CRR, P_K, P_M, P_MU, P_V_REST
from .protocol import push_event
from .sliding import (
    H_C_SPIN,
    MODE_ROLLING,
    MODE_SLIDING,
    YH_P1,
    YH_P2,
    YH_R,
    YH_THETA,
    YH_U,
    YH_V,
    YH_W,
    YH_WORK_EFFECTS,
    YH_WORK_SPIN,
    hold_margin,
    rolling_rates,
    spin_hold_margin,
)
from .story_parts import (
    HI_ARMED,
    HI_EPISODES,
    HI_FATE,
    HI_MODE,
    HI_NEV,
    HI_RESTARTS,
    HI_STUCK,
    HS_FE,
    HS_FH,
    HS_FL,
    HS_T,
    SPINNING,
    mode_energy,
)


@kernel
def _push_slip(t, y, hi, ev_t, ev_kind, ev_y):
    """A slip at t [s]: the story slides from state y."""
    hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_SLIP, y)
    hi[HI_MODE] = MODE_SLIDING
    hi[HI_EPISODES] += 1
    hi[HI_ARMED] &= ARMED_SPIN


@kernel
def story_rest(model, p, y, hp, t_horizon, hs, hi, ev_t, ev_kind, ev_y):
    """The centre's stop by rolling resistance (rolling at most at the rest threshold: the rest
    event, or a stretch that starts there) and what follows it (docs/physics.md "Rest").

    The stop is carried on to zero speed at the deceleration there, as a fate map carries it
    (:func:`.fate.come_to_rest`; the energy the motion left is booked to the resistance and
    the spin friction's share of the interval to spin friction). A ``rest`` event records the
    centre at rest. If the resistance cannot hold the sphere it starts again from rest; if
    friction cannot (cot(alpha) > mu) it slips. Otherwise the centre stays, and the story
    ends when the spin has stopped too: at once if it has (fate ``rest``); without spin
    friction never (fate ``spinning``, the spin kept); with it after k |w| / (c_spin g
    sin(alpha)) (N = M g sin(alpha) at rest: a ``spin_stop`` event and fate ``rest``), or at
    the horizon if that comes first (fate ``rolling``, the spin part way down)."""
    stuck = hi[HI_STUCK] != 0
    u = y[YH_U]
    v = y[YH_V]
    speed = math.sqrt(u * u + v * v)
    if speed > 0.0:
        d = rolling_rates(model, y[YH_R], u, v, y[YH_W], stuck, hp)
        decel = -(u * d[YH_U] + v * d[YH_V]) / speed
        dt = speed / decel if decel > 0.0 else 0.0
        half = 0.5 * dt
        e_moving = mode_energy(model, y, hp, MODE_ROLLING)
        y[YH_R] += u * half
        y[YH_THETA] += d[YH_THETA] * half
        y[YH_W] += d[YH_W] * half
        w_spin = d[YH_WORK_SPIN] * half
        y[YH_WORK_SPIN] += w_spin
        y[YH_U] = 0.0
        y[YH_V] = 0.0
        y[YH_P1] = 0.0
        y[YH_P2] = 0.0
        y[YH_WORK_EFFECTS] += e_moving - mode_energy(model, y, hp, MODE_ROLLING) - w_spin
        hs[HS_T] += dt
    t = hs[HS_T]
    if not holds_at_rest(model, p, y):  # it starts again from rest (y[YH_R] is its Y_R)
        hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_REST, y)
        hi[HI_RESTARTS] += 1
        return
    if hold_margin(model, y, hp) > 0.0:  # friction cannot hold it at rest: the whole slope's pull
        _push_slip(t, y, hi, ev_t, ev_kind, ev_y)
        return
    hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_REST, y)
    w = y[YH_W]
    if w != 0.0 and hp[H_C_SPIN] == 0.0:
        hi[HI_FATE] = SPINNING
        return
    hi[HI_FATE] = FATE_REST
    if w != 0.0:  # spin friction stops the spin in place at a constant rate
        rate = rest_spin_rate(model, hp[H_C_SPIN], y[YH_R], hp)
        kM = hp[P_K] * hp[P_M]
        t_stop = t + abs(w) / rate
        if t_stop > t_horizon:  # still spinning down at the horizon
            w1 = w - math.copysign(rate * (t_horizon - t), w)
            y[YH_WORK_SPIN] += 0.5 * kM * (w * w - w1 * w1)
            y[YH_W] = w1
            hs[HS_T] = t_horizon
            hi[HI_FATE] = ROLLING
        else:
            y[YH_WORK_SPIN] += 0.5 * kM * w * w
            y[YH_W] = 0.0
            hs[HS_T] = t_stop
            hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t_stop, EV_SPIN_STOP, y)
    # the sphere at rest: its last rolling state
    fe, fh, fl = rolling_orbit(model, y[YH_R], y[YH_U], y[YH_V], y[YH_W], hp)
    hs[HS_FE] = fe
    hs[HS_FH] = fh
    hs[HS_FL] = fl


@kernel
def stretch_start(model, p, y, hp, t_horizon, hs, hi, ev_t, ev_kind, ev_y):
    """Transitions decided on the state at the start of a stretch, before it runs (the events
    of a stretch fire on crossings within its steps; docs/physics.md "Where the run goes"):
    rolling with rolling resistance within the rest threshold is the stop (:func:`story_rest`;
    a sphere exactly at rest only where the resistance holds it: elsewhere it moves off, as a
    restart from rest does); rolling where static friction cannot hold the rolling is a slip
    at once; a stuck spin whose holding couple exceeds its limit is released at once; on a
    model whose normal force can vanish, a state without it (N < 0) has left the surface. The
    same for the scalar kernel and the lanes (the loop of :func:`.hybrid.hybrid_fate_of` calls
    it before every stretch), in every effect set."""
    t = hs[HS_T]
    if leaves_contact(model) and contact_frame(model, y[YH_R], y[YH_U], y[YH_V], hp)[1] < 0.0:
        hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_LIFTOFF, y)
        hi[HI_FATE] = FATE_LIFTED_OFF
        return
    if hi[HI_MODE] == MODE_ROLLING:
        speed = math.sqrt(y[YH_U] * y[YH_U] + y[YH_V] * y[YH_V])
        rests = speed > 0.0 or holds_at_rest(model, p, y)
        if hp[P_CRR] > 0.0 and speed <= hp[P_V_REST] and rests:
            story_rest(model, p, y, hp, t_horizon, hs, hi, ev_t, ev_kind, ev_y)
            return
        if hp[P_MU] < math.inf and hold_margin(model, y, hp) > 0.0:
            _push_slip(t, y, hi, ev_t, ev_kind, ev_y)
    if hi[HI_STUCK] != 0 and spin_hold_margin(model, y, hp) > 0.0:
        hi[HI_NEV] = push_event(ev_t, ev_kind, ev_y, hi[HI_NEV], t, EV_SPIN_GO, y)
        hi[HI_STUCK] = 0
        release_spin(y, hp)
        hi[HI_ARMED] &= ARMED_ROLL | ARMED_ROT

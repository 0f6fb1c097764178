"""What follows a fate run (engine.kernels.fate.next_run): the one restart rule of the scalar
fate runs and of every lane's, checked on its own against the physics of a stop and the budget
the rule promises (the lanes' and the scalar kernel's maps are compared bit for bit in
tests/kernels/test_lanes_fate.py)."""

import math

import numba
import numpy as np

from engine.kernels import fate
from engine.kernels.fate import MAX_RESTARTS
from engine.kernels.layouts import Y_R, Y_U, Y_V, state_size_of
from engine.kernels.protocol import MAX_STEPS, OK, RESTED, SPILLED
from engine.scene import Scene


@numba.njit
def next_run(effects, status, y, p, t, restarts, steps, max_steps):
    return fate.next_run(numba.literally(effects), status, y, p, t, restarts, steps, max_steps)


def stopped(alpha, c_rr):
    """A sphere stopped by rolling resistance on a cone of half-aperture alpha (at rest at
    r = 1 m, no spin): the scene's effects, parameters and state."""
    scene = Scene(c_rr=c_rr)
    effects = scene.effects_mask
    y = np.zeros(state_size_of(effects))
    y[Y_R] = 1.0
    return effects, scene.params(alpha), y


def test_a_stop_the_resistance_cannot_hold_restarts_within_the_budget():
    """On a steep cone (cot alpha = 0.64 > c_rr = 0.05) the sphere rolls down again: a
    restart, at the time the run stopped (it stopped at zero speed: nothing to carry on)."""
    effects, p, y = stopped(1.0, 0.05)
    ended, status, t = next_run(effects, RESTED, y, p, 2.5, 0, 100, 1000)
    assert (ended, status, t) == (False, OK, 2.5)


def test_a_stop_the_resistance_holds_ends_at_rest_whatever_the_budget():
    """On a nearly flat cone (cot alpha = 0.1 < c_rr = 0.3) the sphere stays: the fate is
    rest, even with the budget spent (an ending is not a restart)."""
    effects, p, y = stopped(math.atan(10.0), 0.3)
    assert next_run(effects, RESTED, y, p, 2.5, MAX_RESTARTS - 1, 1000, 1000) == (
        True,
        RESTED,
        2.5,
    )


def test_a_restart_beyond_the_steps_or_the_restarts_ends_the_run():
    """The restart the steps (steps >= max_steps) or the restarts (the MAX_RESTARTS-th) have
    no room for ends the run with status MAX_STEPS at the stop's time; one short of either
    still restarts."""
    effects, p, y = stopped(1.0, 0.05)
    assert next_run(effects, RESTED, y, p, 2.5, 0, 1000, 1000) == (True, MAX_STEPS, 2.5)
    assert next_run(effects, RESTED, y, p, 2.5, MAX_RESTARTS - 1, 0, 1000) == (
        True,
        MAX_STEPS,
        2.5,
    )
    assert next_run(effects, RESTED, y, p, 2.5, MAX_RESTARTS - 2, 999, 1000) == (False, OK, 2.5)


def test_a_stop_above_zero_speed_is_carried_to_rest_before_the_restart():
    """A stop at the rest threshold (u = 1e-6 m/s up the slant) is carried to zero speed at
    the deceleration of a rolling sphere there, (g cos alpha + c_rr g sin alpha) / (1 + k)
    (gravity along the slant and the couple c_rr N a, N = M g sin alpha at rest): the time
    moves on by u / deceleration, the centre by half that times u; then it restarts."""
    effects, p, y = stopped(1.0, 0.05)
    u = 1e-6
    y[Y_U] = u
    ended, status, t = next_run(effects, RESTED, y, p, 2.5, 0, 0, 1000)
    scene = Scene(c_rr=0.05)
    decel = scene.g * (math.cos(1.0) + 0.05 * math.sin(1.0)) / (1.0 + scene.k)
    assert (ended, status) == (False, OK)
    assert math.isclose(t - 2.5, u / decel, rel_tol=1e-9)
    assert y[Y_U] == 0.0 and y[Y_V] == 0.0
    assert abs(y[Y_R] - (1.0 + 0.5 * u * u / decel)) <= 2 * np.spacing(1.0)  # r's rounding


def test_any_other_ending_is_the_runs():
    """A run that ended otherwise (spilled) ends with its status and time, state untouched."""
    effects, p, y = stopped(1.0, 0.05)
    y[Y_U] = 0.7
    assert next_run(effects, SPILLED, y, p, 2.5, 0, 1000, 1000) == (True, SPILLED, 2.5)
    assert y[Y_U] == 0.7

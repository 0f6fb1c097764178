"""The effects' forces and couples: what each effect of the effects table does to the sphere.

An effect acts through a force f on the centre and a couple T on the sphere. Every model asks
the same function of the effects in every mode, rolling or sliding, and turns the answer into
its rates (docs/physics.md "Effects as forces and couples"); the hybrid model
(:mod:`.sliding`) asks it of every such effect but rolling resistance, whose rules at zero
tangential spin it writes itself (``contact.APPLIED``):

    (f1, f2, t1, t2, t3) = effect_terms(effects, p, u, v, p1, p2, w, N, pull_u, pull_v)

f1, f2 [N] along (e1, e2), the tangent frame of the surface at the contact; t1, t2, t3 = T/a
[N] about (e1, e2, nu). The state's velocities: the centre's (u, v), the sphere's angular
velocity as speeds a omega = (p1, p2, w) (rolling: p1 = -v, p2 = u); N the normal force;
(pull_u, pull_v) [m/s^2] the centre's acceleration without the effects (rolling resistance
at rest holds against it). A rolling sphere then moves by

    udot += (f1 + t2) / (M (1 + k)),  vdot += (f2 - t1) / (M (1 + k)),  wdot += t3 / (k M),

a sliding one by udot += f1 / M, vdot += f2 / M, (p1, p2, w)dot += (t1, t2, t3) / (k M). The
power the effects take from the sphere, -(f1 u + f2 v + t1 p1 + t2 p2 + t3 w) [W], is the rate
of the work state whatever the effects are (:func:`taken_power`; the hybrid state's
``W_effects`` in both modes), so the work of every effect is booked. A new effect is one row
of the effects table, its terms here under its bit (its parameters read by slot,
:mod:`.layouts`) and its Scene field.

``effects`` reaches these kernels as a numba literal: an effect that is off costs nothing.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from .effects import EFFECT_BITS, EFFECTS, FORCE_EFFECTS
from .layouts import MODEL_BASE, P_CRR, P_INV_M1K

ROLLING_RESISTANCE = EFFECT_BITS["rolling_resistance"]
__all__ = ["FORCE_EFFECTS", "effect_terms", "taken_power"]


@kernel
def effect_terms(effects, p, u, v, p1, p2, w, N, pull_u, pull_v):
    """(f1, f2, t1, t2, t3) [N] of the scene's effects (module docstring)."""
    f1 = 0.0
    f2 = 0.0
    t1 = 0.0
    t2 = 0.0
    t3 = 0.0
    if effects & ROLLING_RESISTANCE:
        # A couple c_rr N a against the tangential angular velocity (p1, p2) / a. Rolling at
        # rest (p1 = p2 = 0) it holds against the pull, up to c_rr N.
        pt = math.sqrt(p1 * p1 + p2 * p2)
        cn = p[P_CRR] * N
        if pt > 0.0:
            t1 -= cn * p1 / pt
            t2 -= cn * p2 / pt
        else:
            # A rolling sphere's pull (pull_u, pull_v) needs the couple M (1 + k) |pull|.
            m1k = 1.0 / p[P_INV_M1K]
            pull = math.sqrt(pull_u * pull_u + pull_v * pull_v)
            held = min(cn / max(pull * m1k, 1e-300), 1.0) * m1k
            t2 -= held * pull_u
            t1 += held * pull_v
    return f1, f2, t1, t2, t3


@kernel
def taken_power(f1, f2, t1, t2, t3, u, v, p1, p2, w):
    """The power [W] the effects take from the sphere: -(f . V + T . omega)."""
    return -(f1 * u + f2 * v + t1 * p1 + t2 * p2 + t3 * w)


def _check_terms() -> None:
    """Every effect the table says acts through forces has terms here, and no other does: each
    effect's terms evaluated alone (in Python) on a moving, rolling sphere with every slot 1."""
    p = np.ones(MODEL_BASE)
    for effect in EFFECTS:
        terms = effect_terms.py_func(effect.bit, p, 0.3, 0.4, -0.4, 0.3, 0.2, 1.0, 0.1, 0.2)
        acts = any(t != 0.0 for t in terms)
        if acts != effect.forces:
            raise ValueError(
                f"effect {effect.name!r}: the effects table says forces={effect.forces}, but "
                f"kernels/forces.py gives it {'terms' if acts else 'no terms'}"
            )


_check_terms()

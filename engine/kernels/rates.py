"""The right-hand side of the state every model shares: the model's rolling rates
(:func:`.model.motion_rates`), then, with the attitude effect, the quaternion's rate from the
model's angular velocity, and, with a dissipative effect, the power the effects take (the work
state's rate). :func:`rhs` writes it into a row of an array; ``rates5`` .. ``rates10`` return it
as scalars for the straight-line steps (:mod:`.rk_codegen`, :mod:`.lanes_step`)."""

from __future__ import annotations

from .._jit import kernel
from .effects import DISSIPATIVE
from .layouts import ATTITUDE, state_size
from .model import dissipated_power, motion_rates, omega_fixed


@kernel
def quaternion_rate(r, theta, u, v, w, q0, q1, q2, q3, p, effects):
    """qdot = 1/2 (0, omega) * q: q maps body axes to the fixed frame, omega in the fixed frame."""
    wx, wy, wz = omega_fixed(r, theta, u, v, w, p, effects)
    return (
        0.5 * (-wx * q1 - wy * q2 - wz * q3),
        0.5 * (wx * q0 + wy * q3 - wz * q2),
        0.5 * (wy * q0 + wz * q1 - wx * q3),
        0.5 * (wz * q0 + wx * q2 - wy * q1),
    )


@kernel
def rates5(y0, y1, y2, y3, y4, p, effects):
    """dy/dt of a 5-component state given as scalars (a tuple)."""
    return motion_rates(y0, y2, y3, y4, p, effects)


@kernel
def rates6(y0, y1, y2, y3, y4, y5, p, effects):
    """dy/dt of the state with the work the effects took (y5)."""
    a, b, c, d, e = motion_rates(y0, y2, y3, y4, p, effects)
    return a, b, c, d, e, dissipated_power(y0, y2, y3, y4, p, effects)


@kernel
def rates9(y0, y1, y2, y3, y4, y5, y6, y7, y8, p, effects):
    """dy/dt of a 9-component state (with the attitude quaternion) given as scalars."""
    a, b, c, d, e = motion_rates(y0, y2, y3, y4, p, effects)
    q0, q1, q2, q3 = quaternion_rate(y0, y1, y2, y3, y4, y5, y6, y7, y8, p, effects)
    return a, b, c, d, e, q0, q1, q2, q3


@kernel
def rates10(y0, y1, y2, y3, y4, y5, y6, y7, y8, y9, p, effects):
    """dy/dt of the state with the attitude quaternion and the work the effects took."""
    a, b, c, d, e = motion_rates(y0, y2, y3, y4, p, effects)
    q0, q1, q2, q3 = quaternion_rate(y0, y1, y2, y3, y4, y5, y6, y7, y8, p, effects)
    return a, b, c, d, e, q0, q1, q2, q3, dissipated_power(y0, y2, y3, y4, p, effects)


@kernel
def rhs(y, p, effects, out, row):
    """dy/dt of the scene ``effects`` into the row ``row`` of the 2-D array ``out``."""
    a, b, c, d, e = motion_rates(y[0], y[2], y[3], y[4], p, effects)
    out[row, 0] = a
    out[row, 1] = b
    out[row, 2] = c
    out[row, 3] = d
    out[row, 4] = e
    if effects & ATTITUDE:
        q0, q1, q2, q3 = quaternion_rate(y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8], p,
                                         effects)  # fmt: skip
        out[row, 5] = q0
        out[row, 6] = q1
        out[row, 7] = q2
        out[row, 8] = q3
    if effects & DISSIPATIVE:
        out[row, state_size(effects) - 1] = dissipated_power(y[0], y[2], y[3], y[4], p, effects)

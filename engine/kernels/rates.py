"""The right-hand side of the state every model shares: the model's rolling rates
(:func:`.model.motion_rates`), then, with the attitude effect, the quaternion's rate from the
model's angular velocity, and, with a dissipative effect, the power the effects take (the work
state's rate). :func:`rhs` writes it into a row of an array; ``rates5`` .. ``rates10`` return it
as scalars for the straight-line steps (:mod:`.rk_codegen`, :mod:`.lanes_step`)."""

from __future__ import annotations

from .._jit import kernel
from .effects import DISSIPATIVE
from .layouts import ATTITUDE, Y_QUAT, Y_R, Y_THETA, Y_U, Y_V, Y_W, state_size
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
    a, b, c, d, e = motion_rates(y[Y_R], y[Y_U], y[Y_V], y[Y_W], p, effects)
    out[row, Y_R] = a
    out[row, Y_THETA] = b
    out[row, Y_U] = c
    out[row, Y_V] = d
    out[row, Y_W] = e
    if effects & ATTITUDE:
        q = Y_QUAT
        q0, q1, q2, q3 = quaternion_rate(y[Y_R], y[Y_THETA], y[Y_U], y[Y_V], y[Y_W], y[q],
                                         y[q + 1], y[q + 2], y[q + 3], p, effects)  # fmt: skip
        out[row, q] = q0
        out[row, q + 1] = q1
        out[row, q + 2] = q2
        out[row, q + 3] = q3
    if effects & DISSIPATIVE:
        out[row, state_size(effects) - 1] = dissipated_power(
            y[Y_R], y[Y_U], y[Y_V], y[Y_W], p, effects
        )

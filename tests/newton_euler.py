"""Newton and Euler for a sphere whose centre moves on a surface of revolution, in the fixed
frame, for the tests (nothing from engine/): the reference the hybrid model's equations in the
meridian frame are held to (tests/kernels/test_sliding.py, tests/kernels/test_contact.py)."""

from __future__ import annotations

import math

import numpy as np


def newton_euler(meridian, t, theta, u, v, P, f, T, M, k, g, a):
    """The rates (du/dt, dv/dt, dp1/dt, dp2/dt, dw/dt) and N of a sphere whose centre moves on
    the surface of revolution of ``meridian`` at (t, theta) with speeds (u, v) along (e1, e2),
    angular velocity a omega = P (fixed frame), under gravity, the contact force f (fixed
    frame) plus N nu, and the couple a T: Newton for the centre with its constraint to the
    surface solved as a 3x3 linear system, Euler about the centre, the frame's turning by the
    derivatives of its vectors. No formula of the engine is used."""
    rho, z, rt, zt, rtt, ztt = meridian(t)
    c, s = math.cos(theta), math.sin(theta)
    sig = math.hypot(rt, zt)
    X_t = np.array([rt * c, rt * s, zt])
    X_th = np.array([-rho * s, rho * c, 0.0])
    X_tt = np.array([rtt * c, rtt * s, ztt])
    X_tth = np.array([-rt * s, rt * c, 0.0])
    X_thth = np.array([-rho * c, -rho * s, 0.0])
    e1, e2 = X_t / sig, np.array([-s, c, 0.0])
    nu = np.cross(e1, e2)
    td, thd = u / sig, v / rho
    known = M * (X_tt * td * td + 2.0 * X_tth * td * thd + X_thth * thd * thd)
    rhs = np.array([0.0, 0.0, -M * g]) + f - known
    tdd, thdd, N = np.linalg.solve(np.column_stack([M * X_t, M * X_th, -nu]), rhs)
    sig_t = (rt * rtt + zt * ztt) / sig
    udot = sig_t * td * td + sig * tdd
    vdot = rt * td * thd + rho * thdd
    Pdot = (np.cross(-a * nu, f) + a * T) / (k * M * a)  # a domega/dt
    e1dot = (X_tt * sig - X_t * sig_t) / sig**2 * td + X_tth / sig * thd
    e2dot = np.array([-c, -s, 0.0]) * thd
    nudot = np.cross(e1dot, e2) + np.cross(e1, e2dot)
    rates = (udot, vdot, Pdot @ e1 + P @ e1dot, Pdot @ e2 + P @ e2dot, Pdot @ nu + P @ nudot)
    return rates, N, (e1, e2, nu)

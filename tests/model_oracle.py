"""Plain-Python statements of the model (docs/physics.md), written independently of the numba
kernels, for tests that compare the engine against them: equations of motion, invariants, the
state on an orbit with given invariants, the contact forces."""

import math


def coefficients(alpha, h, Lz, M, g, k):
    """A [J m^2], B [J m], C [J/m] of V(r) = A/r^2 + B/r + C r."""
    s, c = math.sin(alpha), math.cos(alpha)
    kk = k / (1.0 + k)
    A = Lz**2 / (2.0 * M * s**2) * (1.0 + kk * (c / s) ** 2)
    return A, kk * h * Lz * c / s**2, M * g * c / (1.0 + k)


def potential(r, A, B, C):
    """V(r) = A/r^2 + B/r + C r [J]."""
    return A / r**2 + B / r + C * r


def invariants(r, u, v, w, alpha, M, g, k):
    """(E [J], L_z [kg m^2/s], h [m/s]) of the state (r, u, v, w)."""
    s = math.sin(alpha)
    c = math.cos(alpha)
    Lz = M * r * v * s
    h = w - Lz * c / (M * r * s * s)
    E = 0.5 * (1.0 + k) * M * (u * u + v * v) + 0.5 * k * M * w * w + M * g * r * c
    return E, Lz, h


def total_energy(energy, h, M, k):
    """Total energy E [J] from the radial energy calE [J] (inverse of :func:`radial_energy`)."""
    return (1.0 + k) * energy + 0.5 * k * M * h * h


def state_from_invariants(r, energy, h, Lz, alpha, M, g, k, outward):
    """(u, v, w) at radius r of the orbit with invariants (calE, h, Lz).

    ``outward`` picks the sign of u (True: u >= 0). u is 0 where calE <= V(r).
    """
    s = math.sin(alpha)
    c = math.cos(alpha)
    A, B, C = coefficients(alpha, h, Lz, M, g, k)
    v = Lz / (M * r * s)
    w = h + Lz * c / (M * r * s * s)
    ke = energy - potential(r, A, B, C)
    u = math.sqrt(2.0 * ke / M) if ke > 0.0 else 0.0
    if not outward:
        u = -u
    return u, v, w


def rhs(r, u, v, w, alpha, g, k):
    """Equations of motion: (rdot, thetadot, udot, vdot, wdot) of the conservative scene."""
    s = math.sin(alpha)
    c = math.cos(alpha)
    kappa = c / (r * s)
    kk = k / (1.0 + k)
    rdot = u
    thdot = v / (r * s)
    udot = v * v / r + kk * kappa * v * w - g * c / (1.0 + k)
    vdot = -u * v / r
    wdot = -kappa * u * v
    return rdot, thdot, udot, vdot, wdot


def contact_forces(r, v, w, alpha, M, g, k):
    """(F [N], N [N]): friction along e1 needed to roll, and the normal force (> 0 inside)."""
    s = math.sin(alpha)
    c = math.cos(alpha)
    kappa = c / (r * s)
    N = M * (g * s + v * v * c / (r * s))
    F = k / (1.0 + k) * M * (g * c + kappa * v * w)
    return F, N

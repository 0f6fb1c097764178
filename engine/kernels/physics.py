"""Physics of the rolling sphere (see the README's physics section); SI units, angles in rad.

State: r [m] along the generatrix of the centre's cone, theta [rad] azimuth, u = rdot [m/s],
v = r sin(alpha) thetadot [m/s], w = a * omega_normal [m/s]. Inertia factor k = I/(M a^2).
"""

from __future__ import annotations

import math

from .._jit import kernel

#: Orbit classes, stored as int8 ``orbit_class`` (CF flag_values 0..5).
FORBIDDEN = 0
BOUNDED = 1
CIRCULAR = 2
HYPERBOLIC = 3
RADIAL = 4
SPILLS = 5
CLASS_NAMES = ("forbidden", "bounded", "circular", "hyperbolic", "radial", "spills")


@kernel
def coefficients(alpha, h, Lz, M, g, k):
    """A [J m^2], B [J m], C [J/m] of V(r) = A/r^2 + B/r + C r."""
    s = math.sin(alpha)
    c = math.cos(alpha)
    s2 = s * s
    kk = k / (1.0 + k)
    cot = c / s
    A = Lz * Lz / (2.0 * M * s2) * (1.0 + kk * cot * cot)
    B = kk * h * Lz * c / s2
    C = M * g * c / (1.0 + k)
    return A, B, C


@kernel
def radial_energy(E, h, M, k):
    """Radial energy calE [J] from the total energy E [J] and spin invariant h [m/s]."""
    return E / (1.0 + k) - k / (2.0 * (1.0 + k)) * M * h * h


@kernel
def total_energy(energy, h, M, k):
    """Total energy E [J] from the radial energy calE [J] (inverse of :func:`radial_energy`)."""
    return (1.0 + k) * energy + 0.5 * k * M * h * h


@kernel
def potential(r, A, B, C):
    """Effective potential V(r) = A/r^2 + B/r + C r [J]."""
    return A / (r * r) + B / r + C * r


@kernel
def potential_d1(r, A, B, C):
    """V'(r) [J/m]."""
    return -2.0 * A / (r * r * r) - B / (r * r) + C


@kernel
def potential_d2(r, A, B, C):
    """V''(r) [J/m^2]."""
    return 6.0 * A / (r * r * r * r) + 2.0 * B / (r * r * r)


@kernel
def invariants(r, u, v, w, alpha, M, g, k):
    """(E [J], L_z [kg m^2/s], h [m/s]) of the state (r, u, v, w)."""
    s = math.sin(alpha)
    c = math.cos(alpha)
    Lz = M * r * v * s
    h = w - Lz * c / (M * r * s * s)
    E = 0.5 * (1.0 + k) * M * (u * u + v * v) + 0.5 * k * M * w * w + M * g * r * c
    return E, Lz, h


@kernel
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


@kernel
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


@kernel
def contact_forces(r, v, w, alpha, M, g, k):
    """(F [N], N [N]): friction along e1 needed to roll, and the normal force (> 0 inside)."""
    s = math.sin(alpha)
    c = math.cos(alpha)
    kappa = c / (r * s)
    N = M * (g * s + v * v * c / (r * s))
    F = k / (1.0 + k) * M * (g * c + kappa * v * w)
    return F, N

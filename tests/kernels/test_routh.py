"""Routh's reduction's kernels (engine.kernels.routh, routh_well): the linear meridian system
against the rolling equations of the surface model, the potential's derivatives against finite
differences of the potential, each surface's table against an independent ODE solve (scipy),
and the exact properties: Phi = I on the cone, the spin conserved on the bowl (Routh)."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from engine.kernels import meridian as mer
from engine.kernels import routh as K
from engine.kernels.layouts import SLOTS
from engine.kernels.model import make_params
from engine.kernels.routh_well import circular_q, value, well
from engine.kernels.surface import pull
from engine.kernels.surface_starts import set_point
from engine.routh import build_table

#: Surfaces (kind, shape1, shape2) and a range of q inside each (the cone's alpha, the bowl's
#: radius, the paraboloid's radius, the funnel's scale and hole, a power law z = 0.3 rho^3).
SURFACES = {
    "cone": (mer.CONE, 0.7, 0.0, (0.5, 3.0)),
    "bowl": (mer.BOWL, 1.0, 0.0, (0.05, 1.4)),
    "paraboloid": (mer.PARABOLOID, 0.8, 0.0, (0.05, 2.0)),
    "funnel": (mer.FUNNEL, 0.5, 0.05, (0.08, 20.0)),
    "power_law": (mer.POWER_LAW, 0.3, 3.0, (0.05, 2.0)),
}
K_INERTIA, A_RADIUS, G = 0.4, 0.02, 9.81


def surface(name, rim=math.inf, k=K_INERTIA):
    kind, s1, s2, _ = SURFACES[name]
    p = make_params(1.3, G, k, A_RADIUS, np.array([SLOTS["rim"], SLOTS["mu"]], np.int64),
                    np.array([rim, math.inf]))  # fmt: skip
    p[mer.P_KIND] = kind
    set_point(p, np.array([[s1], [s2], [0.1], [0.0], [0.0]]), 0)
    return p


def _qs(name, n=7):
    lo, hi = SURFACES[name][3]
    return np.linspace(lo, hi, n)


@pytest.mark.parametrize("name", SURFACES)
def test_linear_system_is_the_rolling_equations(name):
    """d(L, w)/dt from the surface model's rolling equations (kernels.surface.pull, L = rho v)
    equals the linear system's A(q) (L, X) dq/dt, in both of the table's variables."""
    p = surface(name)
    rng = np.random.default_rng(3)
    for q in _qs(name):
        rho, z, cb, sb, kap, sig, fit = mer.centre(p, q)
        u, v, w = rng.normal(size=3)
        udot, vdot, wdot, N, sig2, irho = pull(q, u, v, w, p)
        L = rho * v
        dL = u * cb * v + rho * vdot  # d(rho v)/dt, drho/dt = u cos b
        for mode in (K.MODE_HAT, K.MODE_LW):
            A = np.empty((5, 1))
            K.ode_coefficients(p, mode, np.array([q]), A)
            X, dX = w, wdot
            if mode == K.MODE_HAT:  # X = w - L tan(b)/rho, d tan(b)/dt = kappa u / cos^2 b
                X = w - L * sb / (cb * rho)
                dX = wdot - (dL * sb / (cb * rho) + L * kap * u / (cb * cb * rho)
                             - L * sb * u / (rho * rho))  # fmt: skip
            qdot = u / sig
            scale = abs(dL) + abs(L * u) + abs(w * u) + 1e-300
            assert (A[0, 0] * L + A[1, 0] * X) * qdot == pytest.approx(dL, abs=1e-13 * scale)
            assert (A[2, 0] * L + A[3, 0] * X) * qdot == pytest.approx(dX, abs=1e-13 * scale)


@pytest.mark.parametrize("name", SURFACES)
def test_potential_derivatives(name):
    """dU/ds from kernels.routh.potential is U's derivative along the meridian (central
    differences of U itself), d^2U/ds^2 (potential_ss) is dU/ds's; and -dU/ds/2 is the
    meridian acceleration of the surface model (kernels.surface.pull) at the orbit's state."""
    p = surface(name)
    t = build_table(p, 50.0)
    c1, c2 = 0.3, -0.7

    def at(q):
        rho, z, sb, cb, kap, sig, L, dw = K.along(p, t.edges, t.coef, t.meta, c1, c2, q)
        U, Us, sc = K.potential(p, rho, z, sb, cb, L, dw, c2)
        return U, Us, K.potential_ss(p, rho, sb, cb, kap, L, c2 + dw), sig, rho, L, c2 + dw

    for q in _qs(name, 5):
        U, Us, Uss, sig, rho, L, w = at(q)
        h = 1e-4 * q
        (Up, Usp, *_), (Um, Usm, *_) = at(q + h), at(q - h)
        assert (Up - Um) / (2 * h) / sig == pytest.approx(Us, rel=1e-6, abs=1e-9)
        assert (Usp - Usm) / (2 * h) / sig == pytest.approx(Uss, rel=1e-6, abs=1e-9)
        udot = pull(q, 0.0, L / rho, w, p)[0]
        assert -0.5 * Us == pytest.approx(udot, rel=1e-13, abs=1e-13)


@pytest.mark.parametrize("name", ["bowl", "paraboloid", "funnel", "power_law"])
def test_table_is_the_fundamental_solution(name):
    """Phi from the table (Phi(q_ref) = I) against scipy's DOP853 at rtol 1e-13 on the linear
    system from q_ref (the funnel's q_ref = inf: in x = 1/q from x = 1e-12), and det Phi = 1
    (the system's trace is 0) to the rounding of its products."""
    p = surface(name)
    t = build_table(p, 50.0)
    assert t.error <= 1e-14
    mode = int(t.meta[K.MODE])
    tail = math.isinf(t.meta[K.Q_REF])

    def rhs(x, y):
        A = np.empty((5, 1))
        K.ode_coefficients(p, mode, np.array([1.0 / x if tail else x]), A)
        dq = -1.0 / (x * x) if tail else 1.0
        return (dq * A[:4, 0].reshape(2, 2) @ y.reshape(2, 2)).ravel()

    qs = _qs(name)
    xs = 1.0 / qs[::-1] if tail else qs
    x0 = 1e-12 if tail else t.meta[K.Q_REF] + 1e-12
    sol = solve_ivp(rhs, (x0, xs[-1]), np.eye(2).ravel(), method="DOP853", rtol=1e-13,
                    atol=1e-15, t_eval=xs)  # fmt: skip
    for j, x in enumerate(xs):
        D = np.array(K.phi(t.edges, t.coef, t.meta, 1.0 / x if tail else x)).reshape(2, 2)
        Phi = D + np.eye(2)
        assert Phi == pytest.approx(sol.y[:, j].reshape(2, 2), rel=1e-11, abs=1e-11)
        size = abs(Phi[0, 0] * Phi[1, 1]) + abs(Phi[0, 1] * Phi[1, 0])
        assert np.linalg.det(Phi) == pytest.approx(1.0, abs=2e-14 * size)


def test_cone_phi_is_identity_and_integrals_are_Lz_and_h():
    """On the cone kappa = 0: the table is Phi = I exactly (no coefficient), and the launch's
    integrals are L_z = M rho v and h = w - L_z cos(alpha)/(M r sin^2 alpha) of docs/physics.md
    "Invariants" (r = rho/sin(alpha), the centre's slant distance)."""
    p = surface("cone")
    t = build_table(p)
    assert t.meta[K.FLAT] == 1.0 and not np.any(t.coef)
    alpha = SURFACES["cone"][1]
    s, c = math.sin(alpha), math.cos(alpha)
    M = p[SLOTS["M"]]
    for q0, v0, w0 in ((0.7, 1.3, -0.4), (2.5, -0.2, 3.0)):
        ok, c1, c2, IL, Iw = K.integrals(p, t.edges, t.coef, t.meta, q0, v0, w0)
        r = mer.centre(p, q0)[0] / s
        Lz = M * r * v0 * s
        assert ok
        assert IL == pytest.approx(Lz, rel=1e-15)
        assert Iw == pytest.approx(w0 - Lz * c / (M * r * s * s), rel=1e-14)


def test_bowl_spin_about_the_normal_is_conserved():
    """On a spherical bowl sin(b)/rho = kappa: w is constant along the meridian (Routh), and
    L = L_axis - k' w (R - a)(1 - cos q) (dL/ds = -k' kappa rho w, rho = (R - a) sin q)."""
    p = surface("bowl")
    t = build_table(p)
    R, a, kk = SURFACES["bowl"][1], A_RADIUS, K_INERTIA / (1 + K_INERTIA)
    for q in _qs("bowl"):
        D11, D12, D21, D22 = K.phi(t.edges, t.coef, t.meta, q)
        assert abs(D21) <= 1e-14 and abs(D22) <= 1e-14 and abs(D11) <= 1e-14
        assert D12 == pytest.approx(-kk * (R - a) * (1 - math.cos(q)), rel=1e-13)


def test_well_is_the_potential():
    """The well of a narrow orbit (routh_well): H(q) = U(q) - U(q_c) equals the direct
    difference of the potential where that has no cancellation, and q_c is where dU/ds = 0."""
    p = surface("paraboloid")
    t = build_table(p, 50.0)
    c1, c2 = 0.4, 0.1

    def U(q):
        rho, z, sb, cb, kap, sig, L, dw = K.along(p, t.edges, t.coef, t.meta, c1, c2, q)
        return K.potential(p, rho, z, sb, cb, L, dw, c2)[:2]

    qc = circular_q(p, t.edges, t.coef, t.meta, c1, c2, 0.1, 1.5)
    assert abs(U(qc)[1]) <= 1e-14 * abs(U(0.1)[1])
    hw = 0.05 * qc
    H, g, S, R, tail = well(p, t.edges, t.coef, t.meta, c1, c2, qc, hw, False)
    assert tail <= 1e-14
    for x in (-1.0, -0.5, 0.3, 0.9):
        q = qc + hw * x
        assert value(H, x) == pytest.approx(U(q)[0] - U(qc)[0], rel=1e-11)
        assert value(g, x) == pytest.approx(U(q)[1], rel=1e-11)
        assert value(S, x) == pytest.approx(mer.centre(p, q)[5], rel=1e-14)

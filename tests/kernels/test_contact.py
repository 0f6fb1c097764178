"""The sliding contact's interface (engine/kernels/contact.py): the meridian frame and the height
a surface gives the hybrid model, held to geometry and mechanics written here.

- A spherical bowl of radius R: the centre moves on the sphere of radius R - a about the bowl's
  centre, so its frame has closed forms (N = M (g cos q + (u^2 + v^2)/(R - a)), the textbook
  normal force on a sphere); a cylinder of radius R: the centre on the cylinder R - a.
- A paraboloid, a funnel and a power law: the hybrid model's whole sliding right-hand side on
  the surface (kinetic friction against the slip, spin friction against the spin) against
  Newton-Euler in the fixed frame (tests/newton_euler.py) on the centre's meridian computed
  here: the touching meridian (t, f(t)) offset by a along its normal, its derivatives by
  mpmath's numerical differentiation at 30 digits. The engine's q is the touching point's
  distance from the axis t on these surfaces, so dq/dt = u / |dX/dt| is compared too.
"""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest
from newton_euler import newton_euler

from engine.kernels import contact
from engine.kernels.contact import contact_key
from engine.kernels.meridian import P_SHAPE1, P_SHAPE2
from engine.kernels.model import CONE, MODEL_SHIFT, MODELS, SURFACE, Model
from engine.kernels.sliding import hybrid_energy, hybrid_params, sliding_rates
from engine.scene import Scene
from engine.surface_maps import surface_params
from engine.surfaces import Bowl, Cylinder, Funnel, Paraboloid, PowerLaw

#: The surface model's contact key without applied effects (the hybrid kernels' ``model``).
SURFACE_KEY = contact_key(SURFACE, 0)

M, K, G, A = 1.3, 0.4, 9.81, 0.02


def _hp(surface, mu_k=0.0, c_spin=0.0):
    p = surface_params(Scene(M=M, g=G, k=K, a=A, mu=0.5), surface)
    p[P_SHAPE1], p[P_SHAPE2] = surface.shape
    return hybrid_params(p, mu_k, c_spin)


def test_the_bowls_frame_is_the_centres_sphere():
    R = 0.8
    hp = _hp(Bowl(R))
    rc = R - A
    rng = np.random.default_rng(3)
    for _ in range(40):
        q, u, v = rng.uniform(0.05, 1.4), *rng.uniform(-2.0, 2.0, 2)
        thd, N, gsb, cr, kappa, sr, dqds = contact.contact_frame(SURFACE_KEY, q, u, v, hp)
        rho = rc * math.sin(q)
        want = (v / rho, M * (G * math.cos(q) + (u * u + v * v) / rc), G * math.sin(q),
                math.cos(q) / rho, 1.0 / rc, math.sin(q) / rho, 1.0 / rc)  # fmt: skip
        assert (thd, N, gsb, cr, kappa, sr, dqds) == pytest.approx(want, rel=1e-13)
        z = R - rc * math.cos(q)  # the centre's height, the bowl's bottom at z = 0
        assert contact.height_energy(SURFACE_KEY, q, hp) == pytest.approx(M * G * z, rel=1e-13)


def test_the_cylinders_frame():
    R = 0.5
    hp = _hp(Cylinder(R))
    for q, u, v in ((0.3, 0.5, 1.2), (-2.0, -1.0, 0.4), (4.0, 0.0, -3.0)):
        frame = contact.contact_frame(SURFACE_KEY, q, u, v, hp)
        rc = R - A
        assert frame == pytest.approx((v / rc, M * v * v / rc, G, 0.0, 0.0, 1.0 / rc, 1.0),
                                      rel=1e-14, abs=1e-15)  # fmt: skip


#: Touching meridians z = f(t) (t the touching point's distance from the axis, the engine's q):
#: (surface, f', where to look).
GRAPHS = {
    "paraboloid": (Paraboloid(0.7), lambda t: t / 0.7, (0.05, 1.5)),
    "funnel": (Funnel(0.05, 0.03), lambda t: 0.05 / t**2, (0.15, 1.2)),
    "power law": (PowerLaw(0.4, 3.0), lambda t: 1.2 * t**2, (0.05, 1.0)),
}
FS = {
    "paraboloid": lambda t: t * t / 1.4,
    "funnel": lambda t: -0.05 / t,
    "power law": lambda t: 0.4 * t**3,
}


def _centre_meridian(name):
    """(rho, z, rho', z', rho'', z'') of the centre's meridian at t, from the touching one."""
    f, df = FS[name], GRAPHS[name][1]

    def rho(t):
        return t - A * df(t) / mp.sqrt(1 + df(t) ** 2)

    def z(t):
        return f(t) + A / mp.sqrt(1 + df(t) ** 2)

    def meridian(t):
        with mp.workdps(30):
            tt = mp.mpf(t)
            out = (rho(tt), z(tt), mp.diff(rho, tt), mp.diff(z, tt), mp.diff(rho, tt, 2),
                   mp.diff(z, tt, 2))  # fmt: skip
        return tuple(float(x) for x in out)

    return meridian


@pytest.mark.parametrize("name", sorted(GRAPHS))
def test_sliding_on_a_surface_is_newton_and_euler(name):
    surface, _, spot = GRAPHS[name]
    mu_k, c_spin = 0.3, 0.02
    hp = _hp(surface, mu_k, c_spin)
    meridian = _centre_meridian(name)
    rng = np.random.default_rng(17)
    worst = 0.0
    for _ in range(25):
        t = rng.uniform(*spot)
        theta = rng.uniform(-3.0, 3.0)
        u, v, p1, p2, w = rng.uniform(-1.5, 1.5, 5)
        rho, z, rt, zt, _, _ = meridian(t)
        e1, e2, nu = newton_euler(meridian, t, theta, 0.0, 0.0, np.zeros(3), np.zeros(3),
                                  np.zeros(3), M, K, G, A)[2]  # fmt: skip
        P = p1 * e1 + p2 * e2 + w * nu
        _, N, _ = newton_euler(meridian, t, theta, u, v, P, np.zeros(3), np.zeros(3), M, K, G, A)
        S = u * e1 + v * e2 - np.cross(P, nu)  # the contact point's velocity, a omega x (-a nu)
        f = -mu_k * N * S / np.linalg.norm(S)
        T = -c_spin * N * math.copysign(1.0, w) * nu
        want, N2, _ = newton_euler(meridian, t, theta, u, v, P, f, T, M, K, G, A)
        got = sliding_rates.py_func(SURFACE_KEY, t, u, v, p1, p2, w, False, hp)
        sig = math.hypot(rt, zt)
        assert got[0] == pytest.approx(u / sig, rel=1e-12)  # dq/dt
        assert got[1] == pytest.approx(v / rho, rel=1e-12)
        assert got[8] == pytest.approx(mu_k * N2 * np.linalg.norm(S), rel=1e-11)  # friction power
        assert got[9] == pytest.approx(c_spin * N2 * abs(w), rel=1e-11)
        scale = G + 3.0 / rho + 3.0 / (K * M)
        worst = max(worst, max(abs(x - y) for x, y in zip(got[2:7], want, strict=True)) / scale)
        E = hybrid_energy.py_func(SURFACE_KEY, t, u, v, p1, p2, w, hp)
        E_want = 0.5 * M * (u * u + v * v) + 0.5 * K * M * (p1 * p1 + p2 * p2 + w * w) + M * G * z
        assert E == pytest.approx(E_want, rel=1e-12, abs=1e-12 * M * G)
    assert worst < 1e-10  # mpmath's derivatives to ~1e-20; the rest is float64 rounding


def test_a_model_id_that_does_not_exist_is_refused():
    hp = _hp(Bowl(1.0))
    with pytest.raises(ValueError, match="no model with id 7"):
        contact.contact_frame(7 << MODEL_SHIFT, 0.3, 0.0, 0.0, hp)
    assert contact.contact_frame(CONE, 0.3, 0.0, 0.0, Scene().params(0.5)) is not None


def test_the_contact_key_holds_the_model_and_the_applied_effects_only():
    """The hybrid kernels compile once per model and applied effect set: the contact key drops
    the scene's other effects (rolling resistance's rules are the hybrid model's own), and a
    number that is not a contact key (a bare effect mask, a model id below its place) is
    refused rather than read as the cone."""
    from engine.kernels.effects import ALL_EFFECTS, EFFECT_BITS, FORCE_EFFECTS
    from engine.kernels.model import model_of_key, scene_key

    assert contact.APPLIED == FORCE_EFFECTS & ~EFFECT_BITS["rolling_resistance"]
    assert contact.contact_key(SURFACE, ALL_EFFECTS) == scene_key(SURFACE, contact.APPLIED)
    assert contact.contact_key(CONE, EFFECT_BITS["rolling_resistance"]) == CONE
    assert model_of_key(SURFACE_KEY) == SURFACE
    hp = _hp(Bowl(1.0))
    with pytest.raises(ValueError, match="not a contact key"):
        contact.contact_frame(SURFACE, 0.3, 0.0, 0.0, hp)  # the id, not its key
    assert contact.contact_frame(SURFACE_KEY, 0.3, 0.0, 0.0, hp)[1] > 0.0


def test_a_model_offering_sliding_contact_must_give_its_frame():
    cone = MODELS[0]
    lacking = Model("bare", 0, object(), cone.starts, cone.offers, cone.lacks)
    with pytest.raises(ValueError, match="offers sliding contact but lacks"):
        contact.check_contact((lacking,))
    contact.check_contact(MODELS)


@pytest.mark.parametrize("model", [CONE, SURFACE_KEY])
def test_the_compiled_call_picks_the_models_frame(model):
    """The hybrid right-hand side compiled for each model (the literal model id) gives what the
    plain-Python call to that model's frame gives."""
    from engine.kernels.sliding import (
        MODE_ROLLING,
        MODE_SLIDING,
        N_HYBRID,
        hybrid_rhs,
        rolling_rates,
    )

    hp = _hp(Paraboloid(0.7), 0.3, 0.02) if model == SURFACE_KEY else hybrid_params(
        Scene(M=M, g=G, k=K, a=A, mu=0.5).params(0.6), 0.3, 0.02)  # fmt: skip
    y = np.array([0.4, 0.1, 0.3, -0.7, 0.2, 0.5, -0.4, 0.0, 0.0, 0.0])
    out = np.empty(N_HYBRID)
    for mode in (MODE_SLIDING, MODE_ROLLING):
        hybrid_rhs(model, y, hp, mode, False, out)
        if mode == MODE_SLIDING:
            want = sliding_rates.py_func(model, y[0], y[2], y[3], y[4], y[5], y[6], False, hp)
        else:
            want = rolling_rates.py_func(model, y[0], y[2], y[3], y[6], False, hp)
        assert np.allclose(out, want, rtol=1e-14, atol=0.0), (mode, out, want)


@pytest.mark.parametrize("surface", [Bowl(0.8), Paraboloid(0.7), Funnel(0.05, 0.03)])
def test_rolling_on_the_hybrid_steps_is_the_surface_models_rolling(surface):
    """Without spin friction the hybrid model's rolling mode on a surface is the surface model's
    rolling equations (engine/kernels/surface.py, checked against the rigid-body model in
    tests/test_surface_oracle.py), and keeps the rolling constraint (p1, p2) = (-v, u)."""
    from engine.kernels import surface as surface_model
    from engine.kernels.sliding import rolling_rates

    hp = _hp(surface)
    rng = np.random.default_rng(23)
    for _ in range(20):
        q = rng.uniform(0.3, 0.9)
        u, v, w = rng.uniform(-1.5, 1.5, 3)
        got = rolling_rates.py_func(SURFACE_KEY, q, u, v, w, False, hp)
        want = surface_model.motion_rates.py_func(q, u, v, w, hp, 0)
        assert (got[0], got[1], got[2], got[3], got[6]) == pytest.approx(want, rel=1e-13, abs=1e-13)
        assert (got[4], got[5]) == (-got[3], got[2])

"""The rolling-and-sliding rigid-body model on surfaces of revolution
(tests/surface_slide_oracle.py) checked on its own: against the cone's model
(tests/hybrid_oracle.py) event by event, the energy balance with the friction works on a bowl,
a paraboloid and a funnel, the textbook slide on a nearly flat surface, the conservation laws
of frictionless sliding, leaving the wall, and the spin's stick and release on a funnel (each
event consistent with its rule, the energy balanced)."""

import math

import numpy as np
import pytest
from hybrid_oracle import Oracle, start_state
from surface_oracle import Bowl, Cone, Funnel, Paraboloid
from surface_slide_oracle import EPS, SlideOracle, cone_state

A = 0.01
K = 0.4
G = 9.81

# ------------------------------------------------------------------ against the cone's model
#: (alpha, mu, mu_k, c_spin, r0, u0, v0, w0, slip_u, slip_v, horizon): each slips (a rolling
#: launch) or is thrown sliding, and returns to rolling; with and without spin friction (spin
#: stops, reversals, a stick and its release), narrow to wide cones.
CONE_LAUNCHES = {
    "rolling, slips later, returns": (0.6, 0.3, 0.2, 0.0, 0.15, 0.0, 0.5, -3.0, 0.0, 0.0, 0.5),
    "the same with spin friction": (0.6, 0.3, 0.2, 0.01, 0.15, 0.0, 0.5, -3.0, 0.0, 0.0, 0.5),
    "slips twice": (0.3, 0.3, 0.2, 0.0, 0.15, 0.0, 0.5, -3.0, 0.0, 0.0, 0.5),
    "slips twice, spin stops": (0.3, 0.3, 0.2, 0.01, 0.15, 0.0, 0.5, -3.0, 0.0, 0.0, 0.5),
    "wide cone, spin friction": (1.0, 0.3, 0.2, 0.01, 0.15, 0.0, 0.5, -3.0, 0.0, 0.0, 0.5),
    "thrown, spin stick and release": (0.25, 0.6, 0.5, 0.2, 0.3, 0.5, 0.8, -0.3, 0.5, 0.0, 0.2),
    "thrown in, wide cone": (1.35, 0.6, 0.5, 0.0, 0.4, -1.0, 0.7, -1.0, -1.0, 0.7, 0.3),
}  # fmt: skip


@pytest.mark.parametrize("name", list(CONE_LAUNCHES))
def test_on_a_cone_the_story_is_the_cone_models(name):
    """The same events (kinds in order, times within 1e-7 relative) and the same fate as
    hybrid_oracle.Oracle, both at rtol 1e-12 (measured: the times agree within 7e-11
    relative, mostly ~1e-12; 1e-7 is the engine comparisons' tolerance). The launch converted:
    hybrid_oracle's centre lies on the cone z = rho cot(alpha) through the origin at slant r0;
    surface_oracle's Cone(alpha) is the touching cone, its centre's cone a/sin(alpha) higher,
    so the centre is at rho = r0 sin(alpha); its rim (the centre at slant 1 - a cot(alpha))
    is the contact point at rho = sin(alpha)."""
    al, mu, mu_k, c_spin, r0, u0, v0, w0, su, sv, horizon = CONE_LAUNCHES[name]
    mode = "sliding" if (su, sv) != (0.0, 0.0) else "rolling"
    speed = max(abs(u0), abs(v0), abs(w0), abs(su), abs(sv))
    ref = Oracle(al, 1.0, G, A, K, mu, mu_k, c_spin=c_spin, rim_centre=1.0 - A / math.tan(al))
    y0_ref = start_state(al, r0, u0, v0, w0, su, sv, A)
    ev_ref, _, _ = ref.run(y0_ref, mode, horizon, speed)
    o = SlideOracle(Cone(al), 1.0, G, A, K, mu, mu_k, c_spin=c_spin, rim_rho=math.sin(al))
    y0 = o.launch(r0 * math.sin(al), u0, v0, w0, su, sv)
    assert np.allclose(y0, cone_state(y0_ref, al, A), rtol=1e-14, atol=1e-13)
    ev, _, _ = o.run(y0, mode, horizon, speed)
    kinds = [e[0] for e in ev]
    assert "roll" in kinds  # every launch returns to rolling
    assert kinds == [e[0] for e in ev_ref]
    for (kind, t, _), (_, t_ref, _) in zip(ev, ev_ref, strict=True):
        assert t == pytest.approx(t_ref, rel=1e-7, abs=1e-12), kind
    assert o.fate == ref.fate
    assert o.t_fate == pytest.approx(ref.t_fate, rel=1e-7)


# ------------------------------------------------------------------ the energy balance
#: (surface, friction, launch, horizon): thrown sliding with spin, spin friction on.
BALANCE = {
    "bowl": (Bowl(0.5), dict(mu=0.3, mu_k=0.2, c_spin=0.02),
             dict(rho0=0.2, u0=0.3, v0=0.8, w0=1.5, slip_u=0.6, slip_v=-0.4), 1.0),
    "paraboloid": (Paraboloid(0.3), dict(mu=0.3, mu_k=0.2, c_spin=0.02),
                   dict(rho0=0.15, u0=-0.3, v0=0.9, w0=-2.0, slip_u=-0.5, slip_v=0.5), 0.5),
    "funnel": (Funnel(0.05, 0.02), dict(mu=0.3, mu_k=0.1, c_spin=0.02),
               dict(rho0=0.2, u0=0.2, v0=1.5, w0=1.0, slip_u=0.3, slip_v=0.6), 1.0),
}  # fmt: skip


@pytest.mark.parametrize("name", list(BALANCE))
def test_energy_plus_the_friction_works_is_conserved(name):
    """E(t) + W_slide(t) + W_spin(t) = E(0) at every step, within 1e-9 of the energy scale
    (the kinetic energy plus M g |z| at the launch: E's zero is the surface's arbitrary z = 0,
    on the funnel E(0) < 0). The works integrate the powers -f . S and -T . Omega along with
    the motion, so the balance is broken only by the integration's error (rtol 1e-12 over a
    few hundred steps; measured 2e-14..1e-11) and the constraint's drift; leaving out either
    work breaks it by far more than 1e-9 (each is > 2 % of the scale here). The sticking
    impulse's loss, at |S| = 1e-9 of the speed, is ~1e-19 of the scale, too small to see here:
    the next test checks its booking."""
    surface, kw, launch, horizon = BALANCE[name]
    o = SlideOracle(surface, a=A, k=K, **kw)
    y0 = o.launch(**launch)
    ev, y_end, _ = o.run(y0, "sliding", horizon)
    scale = o.energy(y0) - o.M * o.g * y0[2] + o.M * o.g * abs(y0[2])
    w_slide, w_spin = o.works(y_end)
    assert w_slide > 0.02 * scale and w_spin > 0.02 * scale
    assert "roll" in [e[0] for e in ev] or name == "funnel"
    balance = np.array([o.balance(s) for s in o.states])
    assert np.abs(balance - o.energy(y0)).max() <= 1e-9 * scale
    assert o.balance(y_end) == pytest.approx(o.energy(y0), abs=1e-9 * scale)


def test_the_sticking_impulse_is_booked_to_the_sliding_work():
    """The return's impulse J = -k M S_t/(1+k) takes the tangential slip to zero and loses
    exactly k M |S_t|^2/(2(1+k)), which W_slide gains (to rounding)."""
    o = SlideOracle(Bowl(0.5), a=A, k=K, mu=0.3, mu_k=0.2)
    y = o.launch(rho0=0.2, u0=0.3, v0=0.8, w0=1.5, slip_u=0.6, slip_v=-0.4)
    s = o.slip(y[0:3], y[3:6], y[6:9])
    ys = o.stick(y)
    assert np.abs(o.slip(ys[0:3], ys[3:6], ys[6:9])).max() < 1e-15 * np.linalg.norm(s) + 1e-15
    loss = K * o.M * (s @ s) / (2 * (1 + K))
    assert o.energy(y) - o.energy(ys) == pytest.approx(loss, rel=1e-12)
    assert o.balance(ys) == pytest.approx(o.balance(y), rel=1e-14)


# ------------------------------------------------------------------ the flat limit
def test_a_throw_on_a_nearly_flat_surface_is_the_textbook_slide():
    """Thrown sliding without spin (Omega = 0, S = V) on Paraboloid(1e6): friction mu_k M g
    slows the centre and spins the ball up until rolling, at t = k v0/((1+k) mu_k g) with the
    speed v0/(1+k), the sliding work k M v0^2/(2(1+k)). Within 1e-6: the curvature left
    changes the contact's normal and tangential forces by relative amounts of the slope reached,
    rho/R = 0.125 m/1e6 m ~ 1e-7 (measured 1.7e-7 for the time, 9e-8 for the speed, scaling as
    1/R: 1.7e-6 at R = 1e5, 1.8e-8 at 1e7); the return's threshold |S| = 1e-9 v0 moves the time
    by 1e-9 relative."""
    v0, mu_k = 1.0, 0.2
    o = SlideOracle(Paraboloid(1e6), a=A, k=K, mu=0.3, mu_k=mu_k)
    y0 = o.launch(rho0=1e-3, v0=v0, slip_v=v0)
    assert np.all(y0[6:9] == 0.0)
    ev, y_end, _ = o.run(y0, "sliding", 0.2)
    assert [e[0] for e in ev] == ["roll"] and o.fate == "rolling"
    t_roll, y_roll = ev[0][1], ev[0][2]
    assert t_roll == pytest.approx(K * v0 / ((1 + K) * mu_k * G), rel=1e-6)
    assert np.linalg.norm(y_roll[3:6]) == pytest.approx(v0 / (1 + K), rel=1e-6)
    assert o.works(y_end)[0] == pytest.approx(K * v0**2 / (2 * (1 + K)), rel=1e-6)


# ------------------------------------------------------------------ frictionless sliding
def test_frictionless_sliding_conserves_energy_angular_momentum_and_omega():
    """With mu_k = 0 and no spin friction the contact force is N n, through the centre and in
    the meridian plane: Omega stays constant (exactly: its derivative is 0), and the energy and
    L_z = M (X x V)_z + k M a^2 Omega_z of the whole motion are conserved, within 1e-9 relative
    (the integration's error at rtol 1e-12; measured ~5e-13). The slip stays large (no return
    to rolling), the orbit moves in rho (not a trivial circle)."""
    o = SlideOracle(Bowl(0.5), a=A, k=K, mu=0.5, mu_k=0.0)
    y0 = o.launch(rho0=0.2, u0=0.3, v0=0.6, w0=0.5, slip_u=0.3, slip_v=0.2)
    ev, y_end, mode = o.run(y0, "sliding", 1.0)
    assert ev == [] and mode == "sliding" and o.fate == "sliding"
    st = o.states
    assert np.ptp(np.hypot(st[:, 0], st[:, 1])) > 0.05
    assert min(np.linalg.norm(o.slip(s[0:3], s[3:6], s[6:9])) for s in st) > 0.1
    E = np.array([o.energy(s) for s in st])
    L = np.array([o.L_ball(s) for s in st])
    assert np.abs(E - E[0]).max() <= 1e-9 * abs(E[0])
    assert np.abs(L - L[0]).max() <= 1e-9 * abs(L[0])
    assert np.abs(st[:, 6:9] - y0[6:9]).max() <= 1e-9 * np.linalg.norm(y0[6:9])
    assert o.works(y_end) == (0.0, 0.0)


# ------------------------------------------------------------------ leaving the wall
@pytest.mark.parametrize(
    "kw, launch, mode, kinds",
    [
        (dict(mu=math.inf), dict(rho0=0.3, u0=-1.0), "rolling", ["left_surface"]),
        (dict(mu=0.3, mu_k=0.1), dict(rho0=0.3, u0=-1.0, slip_u=-0.5), "sliding",
         ["left_surface"]),
        (dict(mu=0.3, mu_k=0.1), dict(rho0=0.3, u0=-1.0), "rolling", ["slip", "left_surface"]),
    ],
    ids=["rolling", "sliding", "rolling then sliding"],
)  # fmt: skip
def test_down_the_funnels_throat_the_ball_leaves_the_wall(kw, launch, mode, kinds):
    """Straight down the funnel z = -c/rho (concave down: the wall falls away faster than the
    ball's fall bends), rolling or sliding, N falls to zero: `left_surface`, N = 0 there (to
    rounding of M g), not at the launch (N > 0 there)."""
    o = SlideOracle(Funnel(0.05, 0.02), a=A, k=K, **kw)
    y0 = o.launch(**launch)
    assert o.evaluate(y0)["N"] > 0.5 * o.M * o.g * o.evaluate(y0)["n"][2]
    ev, y_end, _ = o.run(y0, mode, 1.0)
    assert [e[0] for e in ev] == kinds
    assert o.fate == "left_surface" and 0.0 < o.t_fate < 0.2
    assert abs(o.evaluate(y_end)["N"]) < 1e-12 * o.M * o.g


def test_rolling_resistance_is_refused():
    with pytest.raises(ValueError, match="c_rr"):
        SlideOracle(Bowl(0.5), c_rr=0.01)


# ------------------------------------------------------------------ the funnel's spin stick
#: Thrown on Funnel(0.05, 0.03) (kappa < 0 everywhere, |dn/dt| large): each returns to rolling,
#: and its spin about the normal then stops, sticks and is released every ~0.1 s.
FUNNEL_FRICTION = dict(M=1.0, a=0.02, k=0.4, mu=0.3, mu_k=0.2, c_spin=0.02)
FUNNEL_LAUNCHES = {
    "along the parallel, no spin": dict(rho0=0.3, u0=0.0, v0=0.5, w0=0.0, slip_u=0.0, slip_v=0.5),
    "up, with spin": dict(rho0=0.15, u0=0.5, v0=0.6, w0=0.3, slip_u=0.5, slip_v=0.6),
    "up, no spin": dict(rho0=0.3, u0=0.2, v0=0.35, w0=0.0, slip_u=0.6, slip_v=0.35),
    "down, with spin": dict(rho0=0.2, u0=-0.3, v0=0.6, w0=0.5, slip_u=-0.3, slip_v=0.0),
}  # fmt: skip


def _spin_state(o, y):
    """The spin's state a stretch starts with (the model's rule): 0 stuck, else the way it
    turns, -sign(T_hold) from zero."""
    if o.spin(y) != 0.0:
        return math.copysign(1.0, o.spin(y))
    if not o.spin_moves(y):
        return 0
    return -math.copysign(1.0, o.spin_hold(y[0:3], y[3:6], y[6:9]))


@pytest.mark.parametrize("name", list(FUNNEL_LAUNCHES))
def test_on_the_funnel_the_spin_sticks_and_goes_consistently(name):
    """Thrown on Funnel(0.05, 0.03) to 2 s: the run ends (the spin stops where it must stick
    used to crawl along Omega . n = 0 until the step budget ran out), and

    - E + W_slide + W_spin = E(0) at every step within 1e-9 of the energy scale (measured
      2.4e-10..6.1e-10, nearly all the normal force's power on the constraint's drift V . n);
    - at `spin_stop` a Omega . n = 0 (projected: rounding, ~1e-16 of the speed); the spin
      turned the stretch's way before it; it then sticks if |T_hold| <= c_spin a N, else it is
      a reversal (|T_hold| > c_spin a N, -T_hold against the old way);
    - at `spin_go` a Omega . n = 0, |T_hold| = c_spin a N (1 + 1e-9) (located), and after it
      the holding couple exceeds the limit and the spin turns the way -T_hold points;
    - stuck, a Omega . n stays 0 (the integration's error) and |T_hold| <= c_spin a N; turning,
      Omega . n keeps the stretch's sign;
    - at `roll` the tangential slip was EPS and is 0 after the impulse, and static friction
      holds (|f| <= mu N); rolling, it stays ~0 (the integration's drift, measured <= 4e-10
      of the speed) and |f| <= mu N; at `slip` |f| = mu N; sliding, |S_t| >= EPS once it has
      exceeded 2 EPS."""
    o = SlideOracle(Funnel(0.05, 0.03), **FUNNEL_FRICTION)
    y0 = o.launch(**FUNNEL_LAUNCHES[name])
    ev, y_end, _ = o.run(y0, "sliding", 2.0, max_steps=5000)  # a correct stretch: < 300
    kinds = [e[0] for e in ev]
    assert o.fate == "rolling" and "roll" in kinds
    assert kinds.count("spin_go") >= 2 and kinds.count("spin_stop") >= 3
    scale = o.energy(y0) - o.M * o.g * y0[2] + o.M * o.g * abs(y0[2])
    balance = np.array([o.balance(s) for s in o.states])
    assert np.abs(balance - o.energy(y0)).max() <= 1e-9 * scale
    speed, eps = o.scale, EPS * o.scale

    def hold(y):
        e = o.evaluate(y)
        return o.spin_hold(y[0:3], y[3:6], y[6:9], e), o.spin_limit(y[0:3], y[3:6], e)

    def margin(y):  # |f| / (mu N) of the rolling force
        return 1.0 + o._slip_margin(y) / (o.mu * o.evaluate(y)["N"])

    mode, spin, t_prev, armed = "sliding", _spin_state(o, y0), 0.0, True
    for kind, t, y in [*ev, ("end", 2.0, y_end)]:
        # the stretch (t_prev, t): its accepted steps, not its ends
        inside = [s for ts, s in zip(o.times, o.states, strict=True) if t_prev < ts < t]
        for s in inside:
            if mode == "rolling":
                assert o._slip_size(s) <= 1e-9 * speed and margin(s) <= 1.0
            elif armed:
                assert o._slip_size(s) >= eps
            else:  # from zero at a slip: the return is armed beyond 2 EPS
                armed = o._slip_size(s) > 2 * eps
            if spin == 0:
                h, lim = hold(s)
                assert abs(o.spin(s)) <= 1e-12 * speed and abs(h) <= lim
            else:
                assert spin * o.spin(s) > 0.0
        if kind == "end":
            break
        if kind == "spin_stop":
            assert spin != 0 and abs(o.spin(y)) <= 1e-14 * speed
            h, lim = hold(y)
            spin = 0 if abs(h) <= lim else -spin
            assert spin == 0 or spin == -math.copysign(1.0, h)
        elif kind == "spin_go":
            assert spin == 0 and abs(o.spin(y)) <= 1e-14 * speed
            h, lim = hold(y)
            assert abs(h) == pytest.approx(lim, rel=1e-9)
            spin = -math.copysign(1.0, h)
            after = [s for ts, s in zip(o.times, o.states, strict=True) if ts > t][:3]
            for s in after:
                h, lim = hold(s)
                assert abs(h) > lim and spin * o.spin(s) > 0.0
        elif kind == "roll":
            assert mode == "sliding"
            before = o.states[list(o.times).index(t)]  # as located, before the impulse
            assert o._slip_size(before) == pytest.approx(eps, rel=1e-6)
            assert o._slip_size(y) <= 1e-14 * speed and margin(y) <= 1.0
            mode = "rolling"
        else:
            assert kind == "slip" and mode == "rolling"
            assert margin(y) == pytest.approx(1.0, rel=1e-9) or t == t_prev
            mode, armed = "sliding", False
        t_prev = t

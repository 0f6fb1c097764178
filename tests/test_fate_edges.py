"""The edges of the fate maps (issue 18 a-g): the vertex region without rolling resistance,
the fates either side of c_rr = 0, agreement with the closed form's classes, circular
launches where V_min is near 0, starting and stopping at zero speed, static friction at rest,
and the horizon as the last event of a trajectory.

Expected values come from formulas written here (uniform acceleration along a generatrix,
the docs' launch relations) or from an independent scipy integration, never from the engine."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import engine
from engine.kernels.fate import FATE_NAMES
from engine.kernels.geometry import CLASS_NAMES
from engine.kernels.protocol import EVENT_NAMES

M, G, K, A_SPHERE = 1.0, 9.81, 0.4, 0.01
KK = K / (1 + K)
R_VERTEX = 0.01 * A_SPHERE  # the vertex region (docs/physics.md)
BIG = 1e6  # a rim or mu that is never reached: the compiled effect sets of tests/test_fates.py
FATE = {name: i for i, name in enumerate(FATE_NAMES)}
CLS = {name: i for i, name in enumerate(CLASS_NAMES)}


def _launch(alpha, r0, v0, w0, scene, rtol=1e-12, horizon_time=5.0):
    ds = engine.launch_survey([alpha], [r0], [v0], [w0], scene=scene, method="rk45", rtol=rtol,
                              horizon_time=horizon_time)  # fmt: skip
    assert ds.attrs["map_kind"] == "fate"
    return ds.squeeze()


def _name(ds):
    return FATE_NAMES[int(ds.fate)]


def _fall_time(r0, accel):
    """Time to fall from rest at r0 to the vertex region at constant acceleration ``accel``."""
    return math.sqrt(2.0 * (r0 - R_VERTEX) / accel)


# ----------------------------------------------------------------------------- a, b: the vertex
def test_a_radial_release_reaches_the_vertex_without_rolling_resistance():
    """Released at rest (L_z = 0) with a rim and mu but no c_rr: it falls along the generatrix
    with acceleration g cos(alpha)/(1+k) and enters the vertex region (it was `failed`)."""
    alpha, r0 = 0.6, 0.5
    ds = _launch(alpha, r0, 0.0, 0.0, engine.Scene(rim=1.0, mu=BIG))
    assert _name(ds) == "vertex"
    t = _fall_time(r0, G * math.cos(alpha) / (1 + K))
    assert float(ds.fate_time) == pytest.approx(t, rel=1e-9)
    assert float(ds.fate_r) == pytest.approx(R_VERTEX, rel=1e-6)


def test_b_fate_is_continuous_at_c_rr_zero_for_an_orbit_through_the_vertex_region():
    """An orbit whose r_min lies inside the vertex region enters it whatever c_rr is: the fate
    at c_rr = 0 and at c_rr = 1e-9 is `vertex`, at nearly the same time (it was `rolling` at
    c_rr = 0)."""
    alpha, r0, v0 = 0.6, 0.5, 1e-4
    fates = [_launch(alpha, r0, v0, 0.0, engine.Scene(rim=1.0, mu=BIG, c_rr=c)) for c in (0, 1e-9)]
    assert [_name(ds) for ds in fates] == ["vertex", "vertex"]
    t0, t1 = (float(ds.fate_time) for ds in fates)
    assert t1 == pytest.approx(t0, rel=1e-7)
    # nearly a radial fall: the time is the radial one to O(v0^2)
    assert t0 == pytest.approx(_fall_time(r0, G * math.cos(alpha) / (1 + K)), rel=1e-4)


# --------------------------------------------------------------------------- c: the closed form
def test_c_orbit_beyond_the_rim_has_no_orbit_like_the_closed_form_says_off_cone():
    alpha, r0, v0, w0 = 0.6, 1.0, 4.0, 0.0  # launched outward of r_c: r0 is its r_min
    scene = engine.Scene(rim=0.8, mu=BIG)
    inv = engine.invariants(alpha, r0, 0.0, v0, w0, scene)
    e, h, lz = (float(inv[n]) for n in ("energy", "h", "Lz"))
    exact = engine.evaluate(alpha, e, h, lz, scene=scene)
    assert CLASS_NAMES[int(exact.orbit_class)] == "off_cone"
    fate = engine.evaluate(alpha, e, h, lz, scene=scene, method="rk45", horizon_time=5.0)
    assert _name(fate) == "no_orbit"
    assert np.isnan(float(fate.fate_time))


def test_c_radial_orbits_leave_the_vertex_as_the_closed_form_says():
    """A radial orbit (L_z = 0) starts at r_min = 0 moving out (the closed form's time runs
    from there): one that reaches the rim spills at the closed form's end_time; one that does
    not comes back and enters the vertex region one period later, less the time it spent in it
    (it was `vertex` at t = 0)."""
    alpha = 0.6
    scene = engine.Scene(rim=1.0, mu=BIG)
    C = M * G * math.cos(alpha) / (1 + K)
    energy = np.array([2.0, 10.0])  # r_max = calE / C: 0.35 (inside the rim) and 1.73
    exact = engine.evaluate(alpha, energy, 0.0, 0.0, scene=scene)
    assert [CLASS_NAMES[c] for c in exact.orbit_class.values] == ["radial", "spills"]
    fate = engine.evaluate(alpha, energy, 0.0, 0.0, scene=scene, method="rk45", rtol=1e-12,
                           horizon_time=5.0)  # fmt: skip
    assert [FATE_NAMES[f] for f in fate.fate.values] == ["vertex", "spilled"]
    # spilled: the closed form's time and place
    assert float(fate.fate_time[1]) == pytest.approx(float(exact.end_time[1]), rel=1e-9)
    assert float(fate.fate_r[1]) == pytest.approx(float(exact.end_r[1]), rel=1e-9)
    # back at the vertex: uniform deceleration C/M from u0 = sqrt(2 calE/M) and back
    u0 = math.sqrt(2 * energy[0] / M)
    u_in = math.sqrt(u0 * u0 - 2 * (C / M) * R_VERTEX)
    t_back = 2 * u0 / (C / M) - (u0 - u_in) / (C / M)
    assert float(fate.fate_time[0]) == pytest.approx(t_back, rel=1e-9)


# ---------------------------------------------------------------- d: circular where V_min ~ 0
def _circular_launch(alpha, r0):
    """(v0, w0) of the circular launch at r0 whose radial energy (= V_min) is 0: u = 0 and
    udot = v^2/r + k/(1+k) cot(alpha)/r v w - g cos(alpha)/(1+k) = 0 (docs/physics.md)."""
    s, c = math.sin(alpha), math.cos(alpha)
    cot, gc = c / s, G * c / (1 + K)

    def state(w):
        b = KK * cot * w
        v = (-b + math.sqrt(b * b + 4 * gc * r0)) / 2
        Lz = M * r0 * v * s
        h = w - Lz * c / (M * r0 * s * s)
        E = 0.5 * (1 + K) * M * v * v + 0.5 * K * M * w * w + M * G * r0 * c
        return v, E / (1 + K) - K / (2 * (1 + K)) * M * h * h

    w0 = brentq(lambda w: state(w)[1], -20.0, -1.0, xtol=1e-15)
    return state(w0)[0], w0


def test_d_circular_launches_with_v_min_near_zero_are_circular():
    """41 circular launches at alpha = 0.7 whose V_min is 0 to rounding: each is circular and
    rolls to the horizon (14 were forbidden, fate no_orbit)."""
    alpha = 0.7
    launches = [_circular_launch(alpha, r0) for r0 in np.linspace(0.3, 0.7, 41)]
    classes, fates = [], []
    for r0, (v0, w0) in zip(np.linspace(0.3, 0.7, 41), launches, strict=True):
        exact = engine.launch_survey([alpha], [r0], [v0], [w0]).squeeze()
        classes.append(CLASS_NAMES[int(exact.orbit_class)])
        fate = _launch(alpha, r0, v0, w0, engine.Scene(rim=BIG, mu=BIG), rtol=1e-10,
                       horizon_time=0.5)  # fmt: skip
        fates.append(_name(fate))
    assert classes == ["circular"] * 41
    assert fates == ["rolling"] * 41


# ------------------------------------------------------------------- e, f: zero speed and rest
HELD = 1.3  # cot = 0.2776: c_rr = 0.3 holds a ball at rest here
STEEP = 0.6  # cot = 1.46: c_rr = 0.3 does not
FIRM = 1.45  # cot = 0.122: c_rr = 0.3 stops a ball launched at 1 m/s within 0.6 s


def test_e_ball_released_at_rest_where_the_resistance_holds_it_rests_at_once():
    ds = _launch(HELD, 0.5, 0.0, 0.0, engine.Scene(c_rr=0.3, rim=BIG, mu=BIG))
    assert _name(ds) == "rest"
    assert float(ds.fate_time) == 0.0  # it was 2e-7 s after 313 chattering steps
    assert float(ds.fate_r) == 0.5
    assert int(ds.n_steps) == 0


def test_e_release_at_rest_on_a_steep_cone_feels_the_resistance_from_the_start():
    """Released at rest where c_rr cannot hold it: it rolls down along the generatrix with the
    constant acceleration g (cos(alpha) - c_rr sin(alpha))/(1+k), and the work of the
    resistance is c_rr M g sin(alpha) times the distance."""
    c_rr, r0 = 0.3, 0.5
    s, c = math.sin(STEEP), math.cos(STEEP)
    ds = _launch(STEEP, r0, 0.0, 0.0, engine.Scene(c_rr=c_rr, rim=BIG, mu=BIG))
    assert _name(ds) == "vertex"
    assert float(ds.fate_time) == pytest.approx(
        _fall_time(r0, G * (c - c_rr * s) / (1 + K)), rel=1e-10
    )
    work = c_rr * M * G * s * (r0 - float(ds.fate_r))
    assert float(ds.energy_lost) == pytest.approx(work, rel=1e-10)
    assert float(ds.invariant_drift) < 1e-11


def _scipy_rest(alpha, r0, v0, w0, c_rr):
    """(t, r) where the ball launched at r0 (u = 0) stops, by scipy from the equations of
    docs/physics.md: integrated to a speed of 1e-7 v0, then the last 1e-7 v0 of speed at the
    deceleration there (the error is of order 1e-14 relative)."""
    s, c = math.sin(alpha), math.cos(alpha)
    cot = c / s

    def rhs(t, y):
        r, th, u, v, w = y
        kappa = cot / r
        speed = math.hypot(u, v)
        f = c_rr * (G * s + v * v * kappa) / (1 + K) / speed
        return [u, v / (r * s), v * v / r + KK * kappa * v * w - G * c / (1 + K) - f * u,
                -u * v / r - f * v, -kappa * u * v]  # fmt: skip

    def slow(t, y):
        return math.hypot(y[2], y[3]) - 1e-7 * v0

    slow.terminal = True
    slow.direction = -1
    sol = solve_ivp(rhs, (0.0, 100.0), [r0, 0.0, 0.0, v0, w0], method="DOP853", rtol=1e-13,
                    atol=1e-16, events=[slow])  # fmt: skip
    t, y = sol.t_events[0][0], sol.y_events[0][0]
    d = rhs(t, y)
    speed = math.hypot(y[2], y[3])
    decel = -(y[2] * d[2] + y[3] * d[3]) / speed
    dt = speed / decel
    return t + dt, y[0] + 0.5 * y[2] * dt


def test_e_rest_time_is_not_early_by_the_rest_threshold():
    """The stop is found where the speed reaches 0, not where it falls below a threshold of
    ~10 rtol of the speed scale (then the rest time was early by ~10-20 rtol)."""
    rtol = 1e-8
    ds = _launch(FIRM, 1.0, 1.0, 0.0, engine.Scene(c_rr=0.3, rim=BIG, mu=BIG), rtol=rtol)
    assert _name(ds) == "rest"
    t, r = _scipy_rest(FIRM, 1.0, 1.0, 0.0, 0.3)
    assert abs(float(ds.fate_time) - t) <= 3 * rtol * t
    assert abs(float(ds.fate_r) - r) <= 3 * rtol * r


def test_f_a_ball_at_rest_needs_static_friction_to_stay():
    """Holding a ball at rest takes a friction force M g cos(alpha), the whole slope pull,
    against mu N = mu M g sin(alpha): released at rest where c_rr >= cot(alpha) holds it, it
    stays only if mu >= cot(alpha), and otherwise slips at once (it was `rest`)."""
    cot = 1 / math.tan(HELD)
    assert 0.27 < cot <= 0.3
    at_rest = [_launch(HELD, 1.0, 0.0, 0.0, engine.Scene(c_rr=0.3, rim=BIG, mu=mu))
               for mu in (0.27, 0.3)]  # fmt: skip
    assert [_name(ds) for ds in at_rest] == ["slipped", "rest"]
    assert [float(ds.fate_time) for ds in at_rest] == [0.0, 0.0]


# ------------------------------------------------------------------------ g: the docs' claims
def test_g_stop_time_on_the_readme_dish_is_not_the_flat_limit():
    """docs/physics.md "The stop time on a wide cone": on the dish (alpha = 1.56, c_rr = 0.02)
    a ball launched at r0 = 0.5 m, v0 = 0.3 m/s stops after 2.366 s, not the flat limit's
    (1+k) v0/(c_rr g) = 2.141 s; far from the vertex (r0 = 10 km) the cone is a uniform slope,
    and the stop time is v0 f/(f^2 - gamma^2) = 3.021 s."""
    alpha, c_rr, v0 = 1.56, 0.02, 0.3
    s, c = math.sin(alpha), math.cos(alpha)
    f, gamma = c_rr * G * s / (1 + K), G * c / (1 + K)
    scene = engine.Scene(c_rr=c_rr, rim=BIG, mu=BIG)
    dish = _launch(alpha, 0.5, v0, 0.0, scene, rtol=1e-10, horizon_time=10.0)
    assert _name(dish) == "rest"
    t_dish = _scipy_rest(alpha, 0.5, v0, 0.0, c_rr)[0]
    assert float(dish.fate_time) == pytest.approx(t_dish, rel=1e-8)
    assert round(t_dish, 3) == 2.366 and round((1 + K) * v0 / (c_rr * G), 3) == 2.141
    far = _launch(alpha, 1e4, v0, 0.0, scene, rtol=1e-10, horizon_time=10.0)
    assert _name(far) == "rest"
    t_slope = v0 * f / (f * f - gamma * gamma)
    assert round(t_slope, 3) == 3.021
    assert float(far.fate_time) == pytest.approx(t_slope, rel=1e-4)  # O(distance / r0)


def test_g_out_of_range_threshold_scales_like_sqrt_m():
    """docs/physics.md "Classes": out_of_range below L_z ~ 1e-146 sqrt(2 M) sin(alpha)."""
    alpha = 1.0
    s = math.sin(alpha)
    for mass in (1e-6, 1.0, 1e6):  # a threshold ~ M would be 1e-3 or 1e3 times this one
        scene = engine.Scene(M=mass)
        lz = 1e-146 * math.sqrt(2 * mass) * s
        vmin = float(engine.minimum_energy(alpha, 0.0, 2 * lz, scene))
        ds = engine.evaluate(alpha, 2 * vmin, 0.0, [0.5 * lz, 2 * lz], scene=scene)
        classes = [CLASS_NAMES[c] for c in ds.orbit_class.values]
        assert classes == ["out_of_range", "bounded"], mass


def test_g_rolling_resistance_slows_v_not_w():
    """docs/physics.md: h = w - v cot(alpha) does not decay; at rest h = w."""
    tr = engine.simulate(FIRM, 30.0, 1.0, 0.8, engine.Scene(c_rr=0.3, rim=BIG, mu=BIG),
                         t_end=20.0)  # fmt: skip
    assert EVENT_NAMES[int(tr.event_kind[-1])] == "rest"
    h_end = float(tr.h_drift[-1]) + tr.attrs["h0"]
    assert h_end == pytest.approx(float(tr.w[-1]), abs=1e-12)
    assert abs(h_end) > 0.5 * abs(tr.attrs["h0"])


# ------------------------------------------------------------------------ g: the last event
def test_g_simulate_records_the_horizon_as_the_last_event():
    tr = engine.simulate(0.5, 20.0, 1.0, 0.8, t_end=1.0)
    assert EVENT_NAMES[int(tr.event_kind[-1])] == "horizon"
    assert float(tr.event_time[-1]) == 1.0
    assert float(tr.event_r[-1]) == float(tr.r[-1])

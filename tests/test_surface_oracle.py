"""The test oracles for surfaces of revolution checked against each other, against the cone's
shared reference data and against closed forms: the Cartesian rigid-body model
(tests/surface_oracle.py, scipy DOP853 at rtol 1e-12) and Routh's reduction at 40 digits
(tests/routh_reference.py), on the launches of tests/surface_cases.py.

Tolerances: the model's outputs carry its integration error, 100 rtol = 1e-10 relative (the
factor covers the growth of the local errors over the ~10^2 steps of a period, as in
tests/cases.py; measured: at most ~7e-12 on these launches); the reduction's carry its own
estimate `err` (<= 1e-31 on every case; its linear and logarithmic quadrature maps agree to
5e-33), and it meets the cone's 34-digit reference data to 1e-28."""

import json
import math
from pathlib import Path

import mpmath as mp
import pytest
import surface_cases as sc
from routh_reference import WORK, Reduction, transport
from surface_oracle import (
    Bowl,
    Cone,
    Funnel,
    Paraboloid,
    PowerLaw,
    SurfaceOracle,
)

RTOL_ORACLE = 1e-10
#: The cone's shared reference data, found as tests/cases.py finds it (not imported from there:
#: cases.py imports the engine, and these oracles stay independent of it).
REF = Path(__file__).resolve().parents[2] / "shared" / "reference" / "public.json"
if not REF.exists():
    REF = Path(__file__).resolve().parents[1] / "data" / "reference_public.json"
SHARED = json.loads(REF.read_text())


def rel(a, b):
    return abs(float(a) / float(b) - 1.0)


# --------------------------------------------------------------------------- the surfaces
@pytest.mark.parametrize("name", sorted(sc.SURFACES))
def test_meridian_derivatives(name):
    """Each meridian's R', Z', R'', Z'' are the derivatives of its R, Z (mpmath.diff at 40
    digits): the geometry both oracles share is right."""
    S = sc.SURFACES[name]()
    lo = S.q_lo if math.isfinite(S.q_lo) else -1.0
    hi = S.q_hi if math.isfinite(S.q_hi) else 1.0
    with mp.workdps(WORK):
        for f in (0.3, 0.55, 0.8):
            q = mp.mpf(lo + f * (hi - lo))
            at = S.at(q)
            for i in (0, 1):
                d1 = mp.diff(lambda x, i=i: S.at(x)[i], q)
                d2 = mp.diff(lambda x, i=i: S.at(x)[i], q, 2)
                assert abs(d1 - at[2 + i]) <= mp.mpf(10) ** -25 * (1 + abs(d1))
                assert abs(d2 - at[4 + i]) <= mp.mpf(10) ** -25 * (1 + abs(d2))


# --------------------------------------------------------------------------- the cone
def _cone_launch(case):
    """The shared reference case as a launch at its pericentre r1 (slant, centre's cone):
    rho0 = r1 sin(alpha), v0 = L_z/(M rho0), w0 = h + v0 cot(alpha) (h = w - v cot alpha)."""
    i = case["inputs"]
    with mp.workdps(WORK):
        al = mp.mpf(i["alpha"])
        rho0 = mp.mpf(case["outputs_hp"]["r1"]) * mp.sin(al)
        v0 = mp.mpf(i["Lz"]) / (mp.mpf(i["M"]) * rho0)
        return rho0, v0, mp.mpf(i["h"]) + v0 / mp.tan(al)


#: Bounded shared cases for the model: typical, free fall (g = 0), near-circular, a thin shell
#: (each ~0.1-0.5 s; the model needs k > 0, I = k M a^2 divides).
CONE_ORACLE = ("P002", "P005", "P013", "P015", "P021", "P026")
CONE_FAST = ("P003", "P030")
CONE_BOUNDED = tuple(c["id"] for c in SHARED if c["outputs"]["class"] == "bounded")


def _shared(cid):
    return next(c for c in SHARED if c["id"] == cid)


@pytest.mark.parametrize("cid", CONE_ORACLE)
def test_model_on_the_cone_meets_the_shared_reference(cid):
    """The Cartesian model on Cone(alpha) against the cone's 34-digit reference data (closed
    form, tests/oracle.py's quadratures): turning points, radial period, apsidal angle."""
    case = _shared(cid)
    i, hp = case["inputs"], case["outputs_hp"]
    rho0, v0, w0 = (float(x) for x in _cone_launch(case))
    o = SurfaceOracle(Cone(i["alpha"]), M=i["M"], g=i["g"], a=0.01, k=i["k"])
    r = o.run(o.launch(rho0, v0, w0), 1e6, periods=1)
    s = math.sin(i["alpha"])
    assert r.fate == "rolling"
    assert rel(r.period, hp["T_r"]) <= RTOL_ORACLE
    assert rel(abs(r.apsidal_angle), hp["psi"]) <= RTOL_ORACLE  # psi: the angle's size
    assert rel(r.rho_min / s, hp["r1"]) <= RTOL_ORACLE
    assert rel(r.rho_max / s, hp["r2"]) <= RTOL_ORACLE


def _reduction_on_the_cone(cid):
    case = _shared(cid)
    i, hp = case["inputs"], case["outputs_hp"]
    out = Reduction(Cone(i["alpha"]), i["M"], i["g"], 0.01, i["k"], *_cone_launch(case)).solve()
    with mp.workdps(WORK):
        s = mp.sin(mp.mpf(i["alpha"]))
        for mine, ref in (("period", "T_r"), ("apsidal_angle", "psi")):
            assert abs(abs(out[mine]) / mp.mpf(hp[ref]) - 1) <= 1e-28, (mine, out[mine], hp[ref])
        assert abs(out["rho_max"] / s / mp.mpf(hp["r2"]) - 1) <= 1e-28
        assert out["err"] <= 1e-30


@pytest.mark.parametrize("cid", CONE_FAST)
def test_reduction_on_the_cone_meets_the_shared_reference(cid):
    """Routh's reduction applied to Cone(alpha) reproduces the 34-digit reference data."""
    _reduction_on_the_cone(cid)


@pytest.mark.parametrize("cid", sorted(set(CONE_BOUNDED) - set(CONE_FAST)))
def test_reduction_on_the_cone_meets_every_shared_case(cid):
    """Slow (tests/conftest.py SLOW): every bounded shared case, 2-10 s each."""
    _reduction_on_the_cone(cid)


# --------------------------------------------------------------------------- limits
@pytest.mark.parametrize("a,k", [(0.01, 0.4), (0.1, 2 / 3)])
def test_bowl_small_planar_oscillations(a, k):
    """Released at rest near the bottom of a spherical bowl of radius R, the ball swings
    through the axis at omega^2 = g/((1+k)(R-a)): apocentre to apocentre on the same side is
    one period 2 pi/omega (amplitude 1e-3 (R - a): the pendulum's correction theta0^2/16 =
    6.25e-8, measured 6.25e-8)."""
    R, g = 1.0, 9.81
    o = SurfaceOracle(Bowl(R), g=g, a=a, k=k)
    r = o.run(o.launch(1e-3 * (R - a), 0.0, 0.0), 100.0, periods=2)
    apo = [tp[1] for tp in r.turns if tp[0] == "apo"]
    omega = math.sqrt(g / ((1 + k) * (R - a)))
    assert rel(apo[2] - apo[0], 2 * math.pi / omega) <= 1e-6
    assert rel(apo[1] - apo[0], math.pi / omega) <= 1e-6


def test_bowl_conserves_the_spin_about_the_normal():
    """On a spherical bowl the spin a Omega . n is conserved (Routh), on the model's orbit and in
    the reduction; on a paraboloid it is not (the check can fail)."""
    case = sc.BY_ID["bowl-2"]
    o = case.oracle()
    r = o.run(case.launch(o), 100.0, periods=1)
    spins = [o.spin(y) for y in r.y]
    assert max(abs(w - case.w0) for w in spins) <= 1e-10 * abs(case.w0)
    ref = sc.stored("bowl-2")
    assert ref["w_peri"] == ref["w_apo"] == mp.mpf(case.w0)
    par = sc.stored("paraboloid-1")
    assert abs(par["w_apo"] - par["w_peri"]) > 1e-3


@pytest.mark.parametrize("cid", ["cylinder-1", "cylinder-2"])
def test_cylinder_height_oscillates_at_sqrt_k_over_1_plus_k_of_the_azimuthal_rate(cid):
    """On a vertical wall the height oscillates harmonically at sqrt(k/(1+k)) times the azimuthal
    rate v0/rho (exactly: L_z is constant, w linear in z), between z0 and
    z0 + 2 (K k2 v w0 - g/(1+k))/(K k2^2 v^2), K = k/(1+k), k2 = 1/rho."""
    case = sc.BY_ID[cid]
    rho = 0.5 - case.a
    K = case.k / (1 + case.k)
    period = 2 * math.pi / (math.sqrt(K) * abs(case.v0) / rho)
    psi = math.copysign(math.pi / math.sqrt(K), case.v0)
    k2, v = 1 / rho, case.v0
    low = 2 * (K * k2 * v * case.w0 - case.g / (1 + case.k)) / (K * k2 * k2 * v * v)
    o = case.oracle()
    r = o.run(case.launch(o), 100.0, periods=1)
    assert rel(r.period, period) <= RTOL_ORACLE
    assert rel(r.apsidal_angle, psi) <= RTOL_ORACLE
    assert rel(min(tp[3] for tp in r.turns), low) <= RTOL_ORACLE
    ref = sc.stored(cid)
    for got, want in ((ref["period"], period), (ref["apsidal_angle"], psi), (ref["z_min"], low)):
        assert rel(got, want) <= 1e-15


def _advance(S, slope, rho0=0.3, a=1e-3, k=0.4):
    """Azimuth [deg] from one pericentre to the next of a near-circular orbit (1 % above the
    small-slope circular speed, v^2 = g rho tan(b)/(1+k))."""
    o = SurfaceOracle(S, a=a, k=k)
    v = math.sqrt(9.81 * rho0 * slope / (1 + k)) * 1.01
    r = o.run(o.launch(rho0, v, 0.0), 1e4, periods=1)
    return 2 * math.degrees(r.apsidal_angle)


SMALL_SLOPE = {
    2: lambda s: Paraboloid(0.3 / s),
    1: lambda s: Cone(math.pi / 2 - math.atan(s)),
    -1: lambda s: Funnel(s * 0.3**2, 1e-3),
    3: lambda s: PowerLaw(s / (3 * 0.3**2), 3),
}


@pytest.mark.parametrize("n", sorted(SMALL_SLOPE))
def test_near_circular_orbits_advance_360_over_sqrt_n_plus_2_at_small_slope(n):
    """On z ~ rho^n with slope s at the orbit, near-circular orbits advance 360/sqrt(n+2) degrees
    from one pericentre to the next as s -> 0 (paraboloid 180, cone 207.8, funnel 360): within
    1e-4 at s = 0.005, and closer than at s = 0.01 (slope^2 and a s/rho corrections)."""
    limit = 360 / math.sqrt(n + 2)
    dev = [abs(_advance(SMALL_SLOPE[n](s), s) / limit - 1) for s in (0.01, 0.005)]
    assert dev[1] <= 1e-4
    assert dev[1] <= 0.6 * dev[0]


# --------------------------------------------------------------------------- model vs reduction
@pytest.mark.parametrize("cid", [c.id for c in sc.PERIODIC])
def test_model_meets_the_reduction(cid):
    """The Cartesian model against Routh's reduction: turning points (rho, or z on the
    cylinder), radial period, apsidal angle, L_z and spin at the turning points; the model keeps
    its energy, its constraint and the rolling."""
    case = sc.BY_ID[cid]
    ref = sc.stored(cid)
    o = case.oracle()
    y0 = case.launch(o)
    r = o.run(y0, 100.0, periods=1)
    assert r.fate == "rolling"
    assert rel(r.period, ref["period"]) <= RTOL_ORACLE
    assert rel(r.apsidal_angle, ref["apsidal_angle"]) <= RTOL_ORACLE
    key = 3 if case.surface == "cylinder" else 2
    lo = min(r.turns, key=lambda tp: tp[key])
    hi = max(r.turns, key=lambda tp: tp[key])
    for tp, which in ((lo, "min"), (hi, "max")):
        want = ref[("z_" if key == 3 else "rho_") + which]
        assert abs(tp[key] - float(want)) <= RTOL_ORACLE * max(abs(float(want)), 0.5)
    for tp in (lo, hi):
        end = "peri" if tp is lo else "apo"
        L_ref, w_ref = float(ref["Lz_" + end]), float(ref["w_" + end])
        assert abs(o.Lz(tp[5]) - L_ref) <= RTOL_ORACLE * case.M * 0.5 * max(abs(case.v0), 1)
        assert abs(o.spin(tp[5]) - w_ref) <= RTOL_ORACLE * max(abs(case.v0), abs(case.w0), 1)
    E0 = o.energy(y0)
    assert abs(E0 - float(ref["E"])) <= 1e-15 * abs(float(ref["E"])) + 1e-15
    terms = max(o.energy(y) - case.M * case.g * y[2] + abs(case.M * case.g * y[2]) for y in r.y)
    assert max(abs(o.energy(y) - E0) for y in r.y) <= RTOL_ORACLE * terms
    assert max(abs(o.offset(y)) for y in r.y) <= RTOL_ORACLE * 0.5
    speed = math.sqrt(2 * terms / case.M)
    assert max(max(abs(c) for c in o.slip(y)) for y in r.y) <= RTOL_ORACLE * speed


@pytest.mark.parametrize("cid", [c.id for c in sc.FATES])
def test_model_fates_meet_the_reduction(cid):
    """Rim, hole, friction limit, and leaving an overhanging wall (the loop on a whole sphere):
    the model's fate, time, azimuth and place against the reduction's leg to where the rim or
    hole lies, or where mu N - |F| or N reaches zero."""
    case = sc.BY_ID[cid]
    ref = sc.stored(cid)
    o = case.oracle()
    r = o.run(case.launch(o), 100.0)
    assert r.fate == case.fate
    assert rel(r.fate_time, ref["fate_time"]) <= RTOL_ORACLE
    assert rel(r.fate_state[9], ref["fate_azimuth"]) <= RTOL_ORACLE
    assert rel(math.hypot(*r.fate_state[:2]), ref["fate_rho"]) <= RTOL_ORACLE


def test_rolling_resistance_stops_a_swing_as_a_coulomb_oscillator():
    """Small planar swings in a bowl with rolling resistance: the centre moves as if a force
    c_rr N ~ c_rr M g opposed it with mass M (1+k), a harmonic oscillator with Coulomb friction:
    each half swing lasts pi/omega and loses 2 x_f of amplitude (x_f = c_rr (R - a), where the
    slope's pull equals the resistance), and the ball is held at the first stop within x_f.
    From 5.5 x_f: stops at pi/omega and 2 pi/omega that do not hold, held at 3 pi/omega at
    0.5 x_f from the axis (corrections ~ (amplitude/R)^2/16 ~ 6e-6)."""
    R, a, k, g = 1.0, 0.01, 0.4, 9.81
    Rc = R - a
    A = 0.01 * Rc
    c_rr = A / 5.5 / Rc
    o = SurfaceOracle(Bowl(R), g=g, a=a, k=k, c_rr=c_rr)
    r = o.run(o.launch(A, 0.0, 0.0), 100.0)
    half = math.pi * math.sqrt((1 + k) * Rc / g)
    assert r.fate == "rest"
    assert len(r.rests) == 2
    for j, t in enumerate(r.rests, start=1):
        assert rel(t, j * half) <= 2e-5  # measured 3.4e-6, 3.8e-6
    assert rel(r.fate_time, 3 * half) <= 2e-5  # 3.0e-6
    assert rel(math.hypot(*r.fate_state[:2]), 0.5 * c_rr * Rc) <= 2e-4  # 2.8e-5


def test_a_launch_where_the_ball_does_not_fit_ends_at_once():
    """At the bottom of a trough narrower than the ball (curvature 1/0.005 > 1/a) the model does
    not roll: fate no_fit at t = 0; on the trough's wall it rolls (until it nears the bottom,
    the fate case "gutter")."""
    o = SurfaceOracle(sc.gutter(), a=0.01)
    r = o.run(o.launch(q0=0.3, v0=0.1), 1.0)
    assert (r.fate, r.fate_time) == ("no_fit", 0.0)
    r = o.run(o.launch(0.32, 0.5, 0.0), 0.01)
    assert (r.fate, r.t[-1]) == ("rolling", 0.01)


def test_reduction_legs_and_transport_agree_with_its_period():
    """The reduction's pieces agree with each other to 1e-30: the legs from either turning point
    to the midpoint add up to half the period and to the apsidal angle; transporting
    (L_z, w) from the pericentre to the apocentre gives the apocentre's values."""
    case = sc.BY_ID["paraboloid-2"]
    r = case.reduction()
    out = r.solve()
    peri, apo = (out["Lz_peri"], out["w_peri"]), (out["Lz_apo"], out["w_apo"])
    with mp.workdps(WORK):
        mid = (out["q1"] + out["q2"]) / 2
        t1, p1 = r.leg(out["q1"], peri, mid)
        t2, p2 = r.leg(out["q2"], apo, mid)
        assert abs((t1 + t2) / (out["period"] / 2) - 1) <= 1e-30
        assert abs((p1 + p2) / out["apsidal_angle"] - 1) <= 1e-30
        S = case.meridian()
        y = transport(S, case.M, case.a, case.k, out["q1"], out["q2"], *peri)
        assert abs(y[0] - apo[0]) <= 1e-30 * abs(apo[0])
        assert abs(y[1] - apo[1]) <= 1e-30 * abs(apo[1])


# --------------------------------------------------------------------------- the table
@pytest.mark.parametrize("cid", ["bowl-1", "log_well-2"])
def test_stored_reference_is_what_the_reduction_computes(cid):
    """The table the engine's tests read is the reduction's output (two cases here; every case
    in the slow test below)."""
    _check_table(cid)


@pytest.mark.parametrize("cid", [c.id for c in sc.CASES if c.id not in ("bowl-1", "log_well-2")])
def test_stored_reference_every_case(cid):
    """Slow (tests/conftest.py SLOW): the whole table, 1-10 s a case."""
    _check_table(cid)


def _check_table(cid):
    got, want = sc.reference(cid), sc.stored(cid)
    assert set(got) == set(want)
    for key in got:
        if key != "err":
            assert abs(got[key] - want[key]) <= 1e-30 * max(1, abs(want[key])), key
    assert got["err"] <= 1e-31


def test_enough_cases():
    """At least 20 launches over bowl, paraboloid, funnel and a smooth profile."""
    kinds = ("bowl", "paraboloid", "funnel", "log_well")
    assert sum(c.surface in kinds for c in sc.PERIODIC) >= 20
    assert {c.surface for c in sc.PERIODIC} >= set(kinds)

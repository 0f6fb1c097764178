"""Exact orbit maps on surfaces of revolution (engine.routh): the cone through the general path
against its closed form (engine.evaluate) on the shared reference cases, the limits of the
issue (the bowl's planar swing, the cylinder's height oscillation, the apsides of near-circular
orbits on z ~ rho^n), the classes at each kind of end, and one table per surface."""

import math

import mpmath as mp
import numpy as np
import pytest
import surface_cases as sc
from cases import CASES
from routh_reference import Reduction
from scipy.special import ellipk
from surface_oracle import Bowl, Funnel

import engine
from engine import routh
from engine.kernels import meridian as mer
from engine.kernels.layouts import SLOTS
from engine.kernels.model import make_params
from engine.kernels.routh import CLASS_NAMES
from engine.kernels.surface_starts import launch_q, set_point
from engine.scene import Scene

TOL = 1e-12
EPS = 2.220446049250313e-16


def params(kind, M=1.0, g=9.81, k=0.4, a=0.01, rim=math.inf):
    p = make_params(M, g, k, a, np.array([SLOTS["rim"], SLOTS["mu"]], np.int64),
                    np.array([rim, math.inf]))  # fmt: skip
    p[mer.P_KIND] = kind
    return p


def orbits(kind, shape, launches, **kw):
    """The exact map of launches (rho0, v0, w0, u0) on one surface: a list of dicts."""
    X = np.array([[*shape, *launch] for launch in launches], dtype=float).T
    out = routh.exact_map(params(kind, **kw), X)
    return [{"class": CLASS_NAMES[out["orbit_class"][i]], **{r: out[r][i] for r in out}}
            for i in range(X.shape[1])]  # fmt: skip


def _cone_invariants(alpha, M, g, k, rho0, v0, w0, u0):
    """(calE, h, L_z) of a launch on the cone, at 40 digits from the double inputs
    (docs/physics.md "Invariants"), rounded once."""
    with mp.workdps(40):
        alpha, M, g, k, rho0, v0, w0, u0 = map(mp.mpf, (alpha, M, g, k, rho0, v0, w0, u0))
        s, c = mp.sin(alpha), mp.cos(alpha)
        r = rho0 / s
        Lz = M * r * v0 * s
        h = w0 - Lz * c / (M * r * s * s)
        E = (1 + k) / 2 * M * (u0**2 + v0**2) + k / 2 * M * w0**2 + M * g * r * c
        return float(E / (1 + k) - k * M * h * h / (2 * (1 + k))), float(h), float(Lz)


def _cone_launches(case):
    """Launches of a reference orbit at r1, r2 (u0 = 0) and half-way (u0 > 0 from the energy)."""
    i, hp, aux = case["inputs"], case["outputs_hp"], case["aux"]
    s, c = math.sin(i["alpha"]), math.cos(i["alpha"])
    radii = [("r1", float(hp["r1"]))]
    if hp.get("r2") is not None:
        radii += [("r2", float(hp["r2"])), ("mid", 0.5 * (float(hp["r1"]) + float(hp["r2"])))]
    out = []
    for where, r in radii:
        with mp.workdps(40):
            A, B, C = (mp.mpf(aux[x]) for x in "ABC")
            V = A / r**2 + B / r + C * r
            u0 = float(mp.sqrt(2 * (i["calE"] - V) / i["M"])) if where == "mid" else 0.0
        v0 = i["Lz"] / (i["M"] * r * s)
        w0 = i["h"] + i["Lz"] * c / (i["M"] * r * s * s)
        out.append((r * s, v0, w0, u0))
    return out


def _rel(x, y):
    return abs(x - y) / abs(y)


#: P019 is parabolic (calE = 0): its class is decided by the rounding of its launch.
CONE_CASES = [c for c in CASES if c["id"] != "P019"]


@pytest.mark.parametrize("a", [0.0, 0.01])
def test_cone_through_the_general_path_is_the_closed_form(a):
    """Every shared reference orbit (but the parabolic one), launched at its pericentre, its
    apocentre and half-way moving out, on the cone as a surface of radius-a spheres: class,
    turning points (rho = r sin(alpha), r the centre's slant distance), period and apsidal
    angle within 1e-12 relative of engine.evaluate on the launch's own invariants, and the
    Routh integrals are the cone's L_z and h."""
    for case in CONE_CASES:
        i = case["inputs"]
        scene = Scene(M=i["M"], g=i["g"], k=i["k"])
        launches = _cone_launches(case)
        got = orbits(mer.CONE, (i["alpha"], 0.0), launches, M=i["M"], g=i["g"], k=i["k"], a=a)
        s = math.sin(i["alpha"])
        for launch, o in zip(launches, got, strict=True):
            E, h, Lz = _cone_invariants(i["alpha"], i["M"], i["g"], i["k"], *launch)
            ref = engine.evaluate(i["alpha"], E, h, Lz, scene)
            where = (case["id"], launch)
            assert o["class"] == engine.CLASS_NAMES[int(ref.orbit_class)], where
            assert o["routh_L"] == pytest.approx(Lz, rel=1e-14), where
            assert o["routh_w"] == pytest.approx(h, rel=1e-13, abs=1e-14 * abs(launch[2])), where
            assert _rel(o["rho_min"] / s, float(ref.r_min)) <= TOL, where
            if o["class"] == "bounded":
                for mine, theirs in ((o["rho_max"] / s, ref.r_max), (o["period"], ref.period),
                                     (o["apsidal_angle"], ref.apsidal_angle)):  # fmt: skip
                    assert _rel(mine, float(theirs)) <= TOL, where


def test_cone_radial_orbit_and_rim():
    """A launch with L_z = 0 passes through the axis (radial; its period the closed form's,
    pericentre to pericentre), and a launch that reaches the rim spills there."""
    alpha, k = 0.6, 0.4
    s = math.sin(alpha)
    o = orbits(mer.CONE, (alpha, 0.0), [(0.8 * s, 0.0, 0.5, 0.3)], a=0.0)[0]
    E, h, Lz = _cone_invariants(alpha, 1.0, 9.81, k, 0.8 * s, 0.0, 0.5, 0.3)
    ref = engine.evaluate(alpha, E, h, Lz, Scene())
    assert o["class"] == "radial" == engine.CLASS_NAMES[int(ref.orbit_class)]
    assert o["rho_min"] == 0.0
    assert _rel(o["rho_max"] / s, float(ref.r_max)) <= TOL
    assert _rel(o["period"], float(ref.period)) <= TOL
    rim = 3.0
    o = orbits(mer.CONE, (alpha, 0.0), [(0.5 * s, 2.0, 0.0, 8.0)], a=0.0, rim=rim)[0]
    E, h, Lz = _cone_invariants(alpha, 1.0, 9.81, k, 0.5 * s, 2.0, 0.0, 8.0)
    ref = engine.evaluate(alpha, E, h, Lz, Scene(rim=rim))
    assert o["class"] == "spills" == engine.CLASS_NAMES[int(ref.orbit_class)]
    assert o["rho_max"] == pytest.approx(rim * s, rel=1e-15)


def test_profile_of_a_cone_is_the_cone():
    """A measured profile that is a cone, z = rho cot(alpha) as a Chebyshev series on
    [0, 2 r2], maps the reference orbits as the closed form does."""
    for case in CONE_CASES[:12]:
        i = case["inputs"]
        hi = 2.0 * float(case["outputs_hp"]["r2"])
        p = params(mer.PROFILE, M=i["M"], g=i["g"], k=i["k"], a=0.01)
        p[mer.P_CHEB] = p[mer.P_CHEB + 1] = 0.5 * hi / math.tan(i["alpha"])
        launches = _cone_launches(case)
        X = np.array([[0.0, hi, *launch] for launch in launches]).T
        out = routh.exact_map(p, X)
        for j, launch in enumerate(launches):
            E, h, Lz = _cone_invariants(i["alpha"], i["M"], i["g"], i["k"], *launch)
            ref = engine.evaluate(i["alpha"], E, h, Lz, Scene(M=i["M"], g=i["g"], k=i["k"]))
            assert CLASS_NAMES[out["orbit_class"][j]] == "bounded", case["id"]
            assert _rel(out["period"][j], float(ref.period)) <= TOL, case["id"]
            assert _rel(out["apsidal_angle"][j], float(ref.apsidal_angle)) <= TOL, case["id"]


def test_bowl_planar_swing_is_the_pendulum():
    """A ball swinging through the bottom of a spherical bowl (v0 = w0 = 0) is a pendulum of
    the centre's radius R - a with omega^2 = g/((1 + k)(R - a)): its period through the axis
    and back (pericentre to pericentre: half the swing) is 2 K(sin^2(phi0/2))/omega. The
    tolerance: heights carry an absolute rounding eps (R + a) (kernels.meridian), a relative
    eps/phi0^2 of the swing's drop (measured: ~4 eps/phi0^2)."""
    R, a, k, g = 0.5, 0.02, 0.4, 9.81
    om = math.sqrt(g / ((1 + k) * (R - a)))
    for phi0 in (0.01, 0.1, 0.8, 1.5):
        rho0 = (R - a) * math.sin(phi0)
        o = orbits(mer.BOWL, (R, 0.0), [(rho0, 0.0, 0.0, 0.0)], a=a, k=k)[0]
        assert o["class"] == "radial"
        assert o["rho_max"] == pytest.approx(rho0, rel=1e-15)
        tol = max(TOL, 50 * EPS / phi0**2)
        assert _rel(o["period"], 2 * ellipk(math.sin(phi0 / 2) ** 2) / om) <= tol


def test_bowl_near_planar_orbits_close_to_the_swing():
    """Small orbits near the bottom of a bowl without spin are the isotropic oscillator's
    ellipses (semi-axes rho0 and v0/omega): apsidal angle pi/2, period pi/omega (to the
    amplitude's square, ~1e-7 at 1e-3 of the radius)."""
    R, a, k, g = 1.0, 0.01, 0.4, 9.81
    om = math.sqrt(g / ((1 + k) * (R - a)))
    for v0 in (1e-6, 1e-5, 1e-3):
        o = orbits(mer.BOWL, (R, 0.0), [(1e-3, v0, 0.0, 0.0)], a=a, k=k)[0]
        assert o["class"] == "bounded"
        assert o["rho_min"] == pytest.approx(v0 / om, rel=1e-6)
        assert o["apsidal_angle"] == pytest.approx(math.pi / 2, rel=1e-6)
        assert o["period"] == pytest.approx(math.pi / om, rel=1e-6)


def test_cylinder_height_oscillates_at_root_k_prime_times_the_azimuthal_rate():
    """On a vertical cylinder the centre's height oscillates harmonically at sqrt(k/(1+k))
    times its azimuthal rate v/rho, about the height where k/(1+k) v w/rho = g/(1+k) (w =
    w0 - v (z - z0)/rho): launched at rest in height at z0, it turns at z0 and 2 z_e - z0."""
    Rc, a, k, g = 0.3, 0.02, 0.4, 9.81
    rho = Rc - a
    kk = k / (1 + k)
    for v0, w0, z0 in ((2.0, 0.3, 0.0), (-1.5, 2.0, 1.0), (4.0, -1.0, -3.0)):
        o = orbits(mer.CYLINDER, (Rc, 0.0), [(z0, v0, w0, 0.0)], a=a, k=k)[0]
        om = math.sqrt(kk) * abs(v0) / rho
        ze = z0 + (kk * v0 * w0 / rho - g / (1 + k)) / om**2
        assert o["class"] == "bounded"
        assert _rel(o["period"], 2 * math.pi / om) <= TOL
        assert _rel(o["apsidal_angle"], abs(v0) / rho * math.pi / om) <= TOL
        lo, hi = sorted((z0, 2 * ze - z0))
        assert o["rho_min"] == pytest.approx(lo, rel=TOL, abs=TOL * abs(ze - z0))
        assert o["rho_max"] == pytest.approx(hi, rel=TOL, abs=TOL * abs(ze - z0))


def _circular_speed(p, shape, rho0):
    """v of the circular orbit at rho0 without spin: v^2 cos(b)/rho = g sin(b)/(1+k)."""
    set_point(p, np.array([[*shape, rho0, 0.0, 0.0]]).T, 0)
    rho, z, cb, sb = mer.centre(p, launch_q(p, rho0))[:4]
    return math.sqrt(9.81 * rho * sb / (cb * 1.4))


@pytest.mark.parametrize(
    "kind,shape,rho0,n",
    [
        (mer.PARABOLOID, (1.0, 0.0), 1e-3, 2),
        (mer.CONE, (math.pi / 2 - 1e-3, 0.0), 1.0, 1),
        (mer.FUNNEL, (1.0, 0.01), 100.0, -1),
        (mer.POWER_LAW, (0.01, 3.0), 0.1, 3),
        (mer.POWER_LAW, (0.01, 4.0), 0.3, 4),
    ],
)
def test_near_circular_apsides_on_power_laws(kind, shape, rho0, n):
    """Near-circular orbits on z ~ rho^n in the small-slope limit advance 360/sqrt(n + 2)
    degrees from one pericentre to the next (paraboloid 180, cone 207.8, funnel 360): 2 psi,
    at slopes ~1e-3 and amplitudes ~1e-3, within 1e-5; a launch at the circular speed is
    circular, with the same angle and the radial frequency sqrt(n + 2) times the azimuthal
    rate."""
    p = params(kind, a=1e-6)
    vc = _circular_speed(p.copy(), shape, rho0)
    near, circ = orbits(kind, shape, [(rho0, vc * (1 + 1e-3), 0.0, 0.0), (rho0, vc, 0.0, 0.0)],
                        a=1e-6)  # fmt: skip
    target = math.radians(360 / math.sqrt(n + 2))
    assert near["class"] == "bounded" and circ["class"] == "circular"
    assert 2 * near["apsidal_angle"] == pytest.approx(target, rel=1e-5)
    assert 2 * circ["apsidal_angle"] == pytest.approx(target, rel=1e-5)
    rate = vc / rho0
    assert circ["period"] == pytest.approx(2 * math.pi / (math.sqrt(n + 2) * rate), rel=1e-5)


def test_funnel_escape_speed():
    """Thrown straight up a funnel's wall (L = w = 0 all along) far from the hole, the ball
    escapes to infinity (hyperbolic) if its energy reaches the far field's, (1+k) u0^2/2 + g z0
    >= g a (the centre at height a as rho -> inf), and otherwise comes back; falling in radially
    from there it is fast where the wall curves away from it (kappa < 0): N = M (g cos b +
    kappa u^2) reaches 0 before the throat (at rho = 0.5: g cos b = 2.4 against
    kappa u^2 = -5.3 m/s^2), so its orbit lifts off. Launched falling just outside the hole,
    where the wall is nearly straight, it falls into the hole."""
    c, hole, a, k, g = 1.0, 0.05, 0.01, 0.4, 9.81
    p = params(mer.FUNNEL, a=a)
    X = np.array([[c, hole, 3.0, 0.0, 0.0, 0.0]]).T
    set_point(p, X, 0)
    z0 = mer.centre(p, launch_q(p, 3.0))[1]
    u_esc = math.sqrt(2 * g * (a - z0) / (1 + k))
    throws = [(3.0, 0.0, 0.0, u_esc * (1 + 1e-9)), (3.0, 0.0, 0.0, u_esc * (1 - 1e-9)),
              (0.06, 0.0, 0.0, -0.1)]  # fmt: skip
    up, down, fall = orbits(mer.FUNNEL, (c, hole), throws, a=a)
    assert up["class"] == "hyperbolic" and up["rho_max"] == math.inf
    assert down["class"] == "lifts_off" and fall["class"] == "hole"
    assert fall["rho_min"] == pytest.approx(mer.centre(p, hole)[0], rel=1e-15)
    # the wall's normal force along the fall, in closed form (z = -c/rho, the centre's meridian
    # ignored: a = 1 cm is small here): negative at rho = 0.5 for the returning throw
    rho = 0.5
    zp, zpp = c / rho**2, -2 * c / rho**3
    cb, kappa = 1 / math.sqrt(1 + zp * zp), zpp / (1 + zp * zp) ** 1.5
    u2 = u_esc**2 + 2 * g * (z0 + c / rho) / (1 + k)
    assert g * cb + kappa * u2 < 0


def test_classes_at_the_ends():
    """A bowl's rim spills; a measured trough z = A (rho - 0.5)^2 - B (rho - 0.5)^3 on
    [0.5, 1.5] curves more sharply than the ball near its inner edge (unfit there: the ball
    wedges), while a launch that stays clear of it is bounded; the circular orbits of
    z = -c/rho^3 are unstable; a point particle on a cylinder falls (hyperbolic); a launch off
    the surface or not finite is no orbit."""
    o = orbits(mer.BOWL, (1.0, 0.0), [(0.5, 3.0, 0.0, 0.0)], rim=0.8)[0]
    assert o["class"] == "spills"
    p = params(mer.BOWL, rim=0.8)
    set_point(p, np.array([[1.0, 0.0, 0.5, 0.0, 0.0]]).T, 0)
    assert o["rho_max"] == pytest.approx(mer.centre(p, p[mer.P_Q_HI])[0], rel=1e-15)
    p = params(mer.PROFILE, a=0.1)
    A, B = 10.0, 5.0  # z'' = 2A at the inner edge, above 1/a
    y = np.polynomial.Polynomial([0.5, 0.5])  # rho - 0.5 in x = 2 rho - 2
    poly = A * y**2 - B * y**3
    p[mer.P_CHEB : mer.P_CHEB + 4] = np.polynomial.chebyshev.poly2cheb(poly.coef)
    X = np.array([[0.5, 1.5, 1.0, 0.3, 0.0, -2.0], [0.5, 1.5, 1.0, 6.5, 0.0, 0.0]]).T
    wedged, clear = routh.exact_map(p, X)["orbit_class"]
    assert CLASS_NAMES[wedged] == "unfit" and CLASS_NAMES[clear] == "bounded"
    # z = -c/rho^3 (a profile): its circular orbits are unstable (U'' < 0 where U' = 0)
    p = params(mer.PROFILE, a=0.01)
    lo, hi, c = 0.5, 3.0, 0.05
    fit = np.polynomial.chebyshev.Chebyshev.interpolate(lambda r: -c / r**3, 23, domain=[lo, hi])
    p[mer.P_CHEB : mer.P_CHEB + 24] = fit.coef
    set_point(p, np.array([[lo, hi, 1.0, 0.0, 0.0]]).T, 0)
    rho, z, cb, sb = mer.centre(p, launch_q(p, 1.0))[:4]
    vc = math.sqrt(9.81 * rho * sb / (cb * 1.4))
    X = np.array([[lo, hi, 1.0, vc, 0.0, 0.0]]).T
    assert CLASS_NAMES[routh.exact_map(p, X)["orbit_class"][0]] == "unstable_circular"
    # a point particle on a cylinder (k = 0) falls for ever: no turning point below
    o = orbits(mer.CYLINDER, (0.5, 0.0), [(0.0, 1.0, 0.3, 0.0)], k=0.0)[0]
    assert o["class"] == "hyperbolic" and o["rho_max"] == 0.0
    bad = orbits(mer.BOWL, (1.0, 0.0), [(2.0, 1.0, 0.0, 0.0), (0.3, math.nan, 0.0, 0.0),
                                        (0.0, 1.0, 0.0, 0.0)], rim=0.8)  # fmt: skip
    assert [o["class"] for o in bad] == ["no_orbit"] * 3
    assert all(math.isnan(o["period"]) for o in bad)


def test_one_table_per_surface(monkeypatch):
    """A map over many launches on three surfaces builds three tables, once (the cache), and
    a paraboloid orbit that leaves the first table (built to 4 times the launches' reach) is
    mapped on an extended one as on a table built large at once."""
    built = []
    real = routh.build_table
    monkeypatch.setattr(routh, "build_table", lambda p, q=math.inf: built.append(1) or real(p, q))
    routh._CACHE.clear()
    rng = np.random.default_rng(5)
    n = 600
    X = np.array([rng.choice([0.8, 1.0, 1.3], n), np.zeros(n), rng.uniform(0.05, 0.5, n),
                  rng.uniform(0.2, 1.0, n), rng.uniform(-0.5, 0.5, n)])  # fmt: skip
    first = routh.exact_map(params(mer.BOWL), X)
    assert len(built) == 3
    again = routh.exact_map(params(mer.BOWL), X)
    assert len(built) == 3
    assert np.array_equal(first["period"], again["period"], equal_nan=True)
    far = [(0.01, 0.02, 0.0, 20.0)]  # from near the axis, far up the paraboloid
    routh._CACHE.clear()
    extended = orbits(mer.PARABOLOID, (1.0, 0.0), far)[0]
    assert len(built) > 4  # extended at least once
    p = params(mer.PARABOLOID)
    set_point(p, np.array([[1.0, 0.0, 0.01, 0.0, 0.0]]).T, 0)
    routh._CACHE.clear()
    routh.surface_table(p, 1e3)
    large = orbits(mer.PARABOLOID, (1.0, 0.0), far)[0]
    assert extended["class"] == large["class"] == "bounded"
    for key in ("rho_max", "period", "apsidal_angle"):
        assert extended[key] == pytest.approx(large[key], rel=1e-13)


# ------------------------------------------------- against Routh's reduction at 40 digits
#: The cases' surfaces (tests/surface_cases.py) as the engine's kinds (kind, shape1, shape2).
#: log_well is a profile given by its formula: the engine's 24-term Chebyshev series of it is
#: a different surface (by ~1e-9), so it is not compared here.
KINDS = {
    "bowl": (mer.BOWL, 1.0, 0.0),
    "paraboloid": (mer.PARABOLOID, 0.5, 0.0),
    "funnel": (mer.FUNNEL, 0.05, 0.02),
    "deep_funnel": (mer.FUNNEL, 0.05, 0.1),
    "power3": (mer.POWER_LAW, 0.5, 3.0),
    "power1.5": (mer.POWER_LAW, 1.0, 1.5),
    "cone": (mer.CONE, 0.6, 0.0),
    "cylinder": (mer.CYLINDER, 0.5, 0.0),
}


def _case_orbit(case, rim=math.inf):
    kind, s1, s2 = KINDS[case.surface]
    pos = 0.0 if kind == mer.CYLINDER else case.rho0  # the cylinder's launch: at height 0
    return orbits(kind, (s1, s2), [(pos, case.v0, case.w0, case.u0)], M=case.M, g=case.g,
                  k=case.k, a=case.a, rim=rim)[0]  # fmt: skip


@pytest.mark.parametrize("cid", [c.id for c in sc.PERIODIC if c.surface in KINDS])
def test_periodic_cases_meet_the_40_digit_reduction(cid):
    """Every periodic launch of tests/surface_cases.py on a surface the engine names (bowl,
    paraboloid, funnel, power laws n = 3 and 1.5, cone, cylinder; at a turning point or moving,
    k = 0.4 and 2/3, a = 0.005 to 0.05): turning points, period and apsidal angle within 1e-12
    relative of Routh's reduction at 40 digits (tests/routh_reference.py; measured: <= 1.1e-13)."""
    case = sc.BY_ID[cid]
    ref = sc.stored(cid)
    o = _case_orbit(case)
    assert o["class"] == "bounded"
    lo, hi = ("z_min", "z_max") if case.surface == "cylinder" else ("rho_min", "rho_max")
    span = float(ref[hi]) - float(ref[lo])  # the cylinder's heights: relative to the swing
    assert o["rho_min"] == pytest.approx(float(ref[lo]), rel=TOL, abs=TOL * span)
    assert o["rho_max"] == pytest.approx(float(ref[hi]), rel=TOL, abs=TOL * span)
    assert _rel(o["period"], float(ref["period"])) <= TOL
    assert _rel(o["apsidal_angle"], abs(float(ref["apsidal_angle"]))) <= TOL


def test_rim_and_hole_cases_meet_the_40_digit_reduction():
    """The fate cases "rim" (a bowl whose edge is 0.35 m from the axis) and "hole" (a funnel
    falling into its hole): the exact map's class, and where the centre is when it spills or
    falls (the reduction's fate_rho)."""
    rim, hole = sc.BY_ID["rim"], sc.BY_ID["hole"]
    o = _case_orbit(rim, rim=0.35)  # the touching point's distance from the axis at the edge
    assert o["class"] == "spills"
    assert _rel(o["rho_max"], float(sc.stored("rim")["fate_rho"])) <= TOL
    o = _case_orbit(hole)
    assert o["class"] == "hole"
    assert _rel(o["rho_min"], float(sc.stored("hole")["fate_rho"])) <= TOL


#: Launches at a turning point, wide and narrow, on the bowl and the funnel (the first: a wide
#: orbit launched at its apocentre, once mapped onto the launch itself by the root search).
LAUNCHES = [
    ("bowl", 1.0, 0.02, 0.4336891384883145, 0.6872058485947915, 0.0827262542347943),
    ("bowl", 1.0, 0.02, 0.12358322, 0.41159502, -0.35409848),
    ("bowl", 1.0, 0.02, 0.25294994, 0.69970949, -0.29385757),
    ("funnel", 1.0, 0.01, 0.310082454, 4.609798, -3.3974325e-3),
    ("funnel", 1.0, 0.01, 2.46549876, 1.68931556, -0.28197886),
]


@pytest.mark.parametrize("surface,scale,a,rho0,v0,w0", LAUNCHES)
def test_turning_point_launches_meet_the_40_digit_reduction(surface, scale, a, rho0, v0, w0):
    """Launches at a turning point (u0 = 0), each solved by Routh's reduction at 40 digits
    (1-3 s each): turning points, period and apsidal angle within 1e-12."""
    meridian = Bowl(scale) if surface == "bowl" else Funnel(scale, 0.05)
    ref = Reduction(meridian, 1.0, 9.81, a, 0.4, rho0, v0, w0, 0.0).solve()
    kind, shape = (mer.BOWL, (scale, 0.0)) if surface == "bowl" else (mer.FUNNEL, (scale, 0.05))
    o = orbits(kind, shape, [(rho0, v0, w0, 0.0)], a=a)[0]
    assert o["class"] == "bounded" and ref["cls"] == "bounded"
    for mine, key in (("rho_min", "rho_min"), ("rho_max", "rho_max"), ("period", "period")):
        assert _rel(o[mine], float(ref[key])) <= TOL, key
    assert _rel(o["apsidal_angle"], abs(float(ref["apsidal_angle"]))) <= TOL

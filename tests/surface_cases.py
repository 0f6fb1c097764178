"""Launches of a ball rolling on surfaces of revolution, with reference values, for the tests of
the engine and of tests/surface_oracle.py.

Each `Case` names its surface (`SURFACES`: a builder of the touching surface's meridian, and
`ENGINE` the same surface as the engine's table names it), the scene (M [kg], g [m/s^2],
a [m], k) and the launch in the convention of tests/surface_oracle.py: the centre at
distance rho0 [m] from the axis at azimuth 0, speed v0 [m/s] along the parallel (counter-clockwise
seen from above positive), u0 [m/s] along the meridian (up the wall positive), rolling, spin
w0 = a Omega . n [m/s] with n from the contact point to the centre. On the cylinder rho0 is
R - a and the centre starts at height z0 = 0; on the whole sphere (a parametric meridian) the
launch point is given by its parameter q0.

`reference(id)` computes a case's values by Routh's reduction at 40 digits
(tests/routh_reference.py; 1-3 s a case, cached); `stored(id)` reads the same values from the
table `REFERENCE` below, which `python tests/surface_cases.py` regenerates (a slow test checks it
against `reference`). Values are mpmath numbers:

- periodic cases (`fate` None): rho_min, rho_max, z_min, z_max of the centre [m]; period [s]
  (pericentre to pericentre); apsidal_angle [rad] (azimuth swept from a pericentre to the next
  apocentre); E [J] (M V^2/2 + I Omega^2/2 + M g z, z of the centre, the touching surface's own
  z = 0 origin); Lz_peri, Lz_apo [kg m^2/s] (L_z = M rho v, the centre's angular momentum about
  the axis: on the cone the engine's L_z) and w_peri, w_apo [m/s] (the spin) at the turning
  points. On the cylinder "rho" is fixed and the turning points are those of the height.
- fate cases: the first fate on the way from the launch (a turning point, u0 = 0):
  fate_time [s], fate_azimuth [rad] swept by then, fate_rho [m] of the centre there. The rim
  is the contact point's height rim_z; "slipped" where |F| = mu N; "left_surface" where N = 0;
  "no_fit" where 1 - a kappa (kappa the touching meridian's curvature) falls to 1e-3, the
  margin tests/surface_oracle.py uses before the cusp of the centre's surface.

Nothing is computed at import.
"""

from __future__ import annotations

import functools
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import mpmath as mp
from routh_reference import WORK, Reduction
from surface_oracle import (
    Bowl,
    Cone,
    Cylinder,
    Funnel,
    Graph,
    Paraboloid,
    Parametric,
    PowerLaw,
    SurfaceOracle,
    lift,
    mathlib,
)


def log_well(H=0.2, ell=0.3):
    """z = (H/2) log(1 + rho^2/ell^2): a well that flattens outward (inflection at rho = ell)."""

    def f(q):
        h, e = lift(q, H, ell)
        return h / 2 * mathlib(q).log(1 + (q / e) ** 2)

    def df(q):
        h, e = lift(q, H, ell)
        return h * q / (e**2 + q**2)

    def d2f(q):
        h, e = lift(q, H, ell)
        return h * (e**2 - q**2) / (e**2 + q**2) ** 2

    return Graph(f, df, d2f, name=f"log_well({H}, {ell})")


def sphere(R=0.5):
    """The whole sphere of radius R, bottom at z = 0, as a parametric meridian (rho, z) =
    R (sin t, 1 - cos t), t in [0, pi): above its equator the wall overhangs."""

    def fn(g):
        return lambda t: lift(t, R)[0] * g(t, mathlib(t))

    return Parametric(
        fn(lambda t, L: L.sin(t)),
        fn(lambda t, L: 1 - L.cos(t)),
        fn(lambda t, L: L.cos(t)),
        fn(lambda t, L: L.sin(t)),
        fn(lambda t, L: -L.sin(t)),
        fn(lambda t, L: L.cos(t)),
        q_lo=0.0,
        q_hi=math.pi,
        name=f"sphere({R})",
    )


def gutter(c=0.3, r=0.005):
    """z = (rho - c)^2/(2 r): a ring-shaped trough whose bottom (radius of curvature r) is
    narrower than the ball when r < a."""

    def f(q):
        c_, r_ = lift(q, c, r)
        return (q - c_) ** 2 / (2 * r_)

    def df(q):
        c_, r_ = lift(q, c, r)
        return (q - c_) / r_

    def d2f(q):
        return 1 / lift(q, r)[0]

    return Graph(f, df, d2f, name=f"gutter({c}, {r})")


#: name -> builder of the touching surface's meridian.
SURFACES = {
    "bowl": lambda: Bowl(1.0),
    "paraboloid": lambda: Paraboloid(0.5),
    "funnel": lambda: Funnel(0.05, 0.02),
    "log_well": log_well,
    "power3": lambda: PowerLaw(0.5, 3),
    "power1.5": lambda: PowerLaw(1.0, 1.5),
    "cone": lambda: Cone(0.6),
    "cylinder": lambda: Cylinder(0.5),
    "deep_funnel": lambda: Funnel(0.05, 0.1),
    "sphere": sphere,
    "gutter": gutter,
}

#: The same surfaces as the engine's table names them (kind, parameters); a profile is given
#: by its z = f(rho) (sample `SURFACES[name]().f`).
ENGINE = {
    "bowl": ("Bowl", {"radius": 1.0}),
    "paraboloid": ("Paraboloid", {"radius": 0.5}),
    "funnel": ("Funnel", {"scale": 0.05, "hole": 0.02}),
    "log_well": ("Profile", {"z": "0.1 log(1 + (rho/0.3)^2)"}),
    "power3": ("PowerLaw", {"scale": 0.5, "n": 3}),
    "power1.5": ("PowerLaw", {"scale": 1.0, "n": 1.5}),
    "cone": ("Cone", {"alpha": 0.6}),
    "cylinder": ("Cylinder", {"radius": 0.5}),
    "deep_funnel": ("Funnel", {"scale": 0.05, "hole": 0.1}),
    "sphere": ("Profile", {"rho": "0.5 sin(t)", "z": "0.5 (1 - cos(t))", "t": "[0, pi)"}),
    "gutter": ("Profile", {"z": "(rho - 0.3)^2/(2 0.005)"}),
}


@dataclass(frozen=True)
class Case:
    id: str
    surface: str
    rho0: float
    v0: float
    w0: float
    u0: float = 0.0
    M: float = 1.0
    g: float = 9.81
    a: float = 0.01
    k: float = 0.4
    #: a fate case: the fate expected first, and the scene's limits
    fate: str | None = None
    rim_z: float | None = None
    mu: float = math.inf
    #: the contact point's parameter at the launch, on a parametric meridian (rho0 is then
    #: the centre's distance from the axis there, for information)
    q0: float | None = None

    def meridian(self):
        return SURFACES[self.surface]()

    def oracle(self, **kw) -> SurfaceOracle:
        """The Cartesian model of this case's scene (tests/surface_oracle.py)."""
        return SurfaceOracle(self.meridian(), M=self.M, g=self.g, a=self.a, k=self.k,
                             mu=self.mu, rim_z=self.rim_z, **kw)  # fmt: skip

    def launch(self, oracle: SurfaceOracle):
        if self.q0 is not None:
            return oracle.launch(q0=self.q0, v0=self.v0, w0=self.w0, u0=self.u0)
        return oracle.launch(self.rho0, self.v0, self.w0, self.u0)

    def reduction(self) -> Reduction:
        rho0 = None if self.q0 is not None else self.rho0
        return Reduction(self.meridian(), self.M, self.g, self.a, self.k, rho0, self.v0,
                         self.w0, self.u0, q0=self.q0)  # fmt: skip


K3 = 2 / 3  # a thin spherical shell
CASES = (
    Case("bowl-1", "bowl", 0.3, 1.0, 0.5),
    Case("bowl-2", "bowl", 0.6, 1.2, -1.0),
    Case("bowl-3", "bowl", 0.8, 0.8, 0.0),
    Case("bowl-4", "bowl", 0.4, 1.5, 2.0, a=0.05, k=K3),
    Case("bowl-5", "bowl", 0.2, 0.5, 0.3, u0=0.4),
    Case("bowl-6", "bowl", 0.5, -1.0, 0.5),
    Case("paraboloid-1", "paraboloid", 0.3, 1.2, -0.3),
    Case("paraboloid-2", "paraboloid", 0.1, 0.5, 1.0),
    Case("paraboloid-3", "paraboloid", 0.5, 2.0, 0.0, a=0.02),
    Case("paraboloid-4", "paraboloid", 0.2, 0.3, -2.0, u0=0.5),
    Case("paraboloid-5", "paraboloid", 0.4, 1.0, 0.7, k=K3),
    Case("funnel-1", "funnel", 0.3, 1.2, 0.2),
    Case("funnel-2", "funnel", 0.2, 1.5, -0.5),
    Case("funnel-3", "funnel", 0.5, 0.6, 0.0),
    Case("funnel-4", "funnel", 0.15, 1.8, 1.0, u0=-0.3),
    Case("funnel-5", "funnel", 0.1, 2.2, 0.3, a=0.005),
    Case("log_well-1", "log_well", 0.2, 0.8, 0.3),
    Case("log_well-2", "log_well", 0.4, 0.9, -0.5),
    Case("log_well-3", "log_well", 0.3, 0.6, 1.0),
    Case("log_well-4", "log_well", 0.5, 1.1, 0.0, u0=0.2),
    Case("power3-1", "power3", 0.4, 0.8, 0.2),
    Case("power1.5-1", "power1.5", 0.3, 1.0, 0.0),
    Case("cone-1", "cone", 0.3, 1.0, 0.4),
    Case("cylinder-1", "cylinder", 0.49, 2.0, 0.5, q0=0.0),
    Case("cylinder-2", "cylinder", 0.49, -1.0, -0.3, q0=0.0),
    # fates: from a turning point to the first fate
    Case("rim", "bowl", 0.3, 1.0, 0.5, fate="rim", rim_z=1 - math.sqrt(1 - 0.35**2)),
    Case("hole", "deep_funnel", 0.3, 0.3, 0.0, fate="hole"),
    Case("slip", "paraboloid", 0.5, 2.0, 0.0, fate="slipped", mu=0.165),
    Case("loop", "sphere", 0.1448, 3.0, 0.0, q0=0.3, fate="left_surface"),
    Case("gutter", "gutter", 0.31, 0.2, 0.0, fate="no_fit"),
)
BY_ID = {c.id: c for c in CASES}
PERIODIC = tuple(c for c in CASES if c.fate is None)
FATES = tuple(c for c in CASES if c.fate is not None)


def _fate(case: Case, r: Reduction) -> dict:
    """The first fate of a fate case, from the launch (a turning point) along its first leg."""
    up = r.du2(r.q0, r.y0) > 0
    side = 1 if up else -1
    S = r.S
    if case.fate == "rim":
        q_e = mp.findroot(lambda q: S.at(q)[1] - mp.mpf(case.rim_z), r.q0)
    elif case.fate == "hole":
        q_e = mp.mpf(S.hole)
    end = q_e if case.fate in ("rim", "hole") else None
    turn = r.march(side, end=end)
    if case.fate == "slipped":
        q_e = r.first(lambda q, y: case.mu * r.forces(q, y)[0] - mp.hypot(*r.forces(q, y)[1:]),
                      side)  # fmt: skip
    elif case.fate == "left_surface":
        q_e = r.first(lambda q, y: r.forces(q, y)[0], side)
    elif case.fate == "no_fit":  # where 1 - a kappa = 1e-3 (tests/surface_oracle.py)
        q_e = r.first(lambda q, y: r.geo(q)[5] / mp.hypot(*S.at(q)[2:4]) - mp.mpf("1e-3"), side)
    if q_e is None or (turn is not None and (turn[0] - q_e) * side < 0):
        raise ValueError(f"{case.id}: no {case.fate} before the turning point")
    t, phi = r.leg(r.q0, r.y0, q_e)
    return {"fate_time": t, "fate_azimuth": phi, "fate_rho": r.geo(q_e)[0], "err": r.err}


@functools.cache
def reference(case_id: str) -> dict:
    """A case's reference values, computed (Routh's reduction at 40 digits)."""
    case = BY_ID[case_id]
    with mp.workdps(WORK):
        r = case.reduction()
        if case.fate is not None:
            return _fate(case, r)
        out = r.solve()
        if out["cls"] != "bounded":
            raise ValueError(f"{case_id}: the orbit is {out['cls']}")
        return {k: v for k, v in out.items() if k not in ("cls", "q1", "q2")}


def stored(case_id: str) -> dict:
    """A case's reference values from the table (`REFERENCE`)."""
    with mp.workdps(WORK):
        return {k: mp.mpf(v) for k, v in REFERENCE[case_id].items()}


def _table() -> str:
    lines = ["REFERENCE = {"]
    for c in CASES:
        vals = reference(c.id)
        lines.append(f'    "{c.id}": {{')
        for k, v in vals.items():
            lines.append(f'        "{k}": "{mp.nstr(v, WORK if k != "err" else 3)}",')
        lines.append("    },")
    lines.append("}  # fmt: skip")
    return "\n".join(lines)


# --- generated by `python tests/surface_cases.py` (Routh's reduction at 40 digits) ---
REFERENCE = {
    "bowl-1": {
        "rho_min": "0.2999999999999999888977697537484345957637",
        "rho_max": "0.3726205537030820145891988719015149401459",
        "z_min": "0.05654888838901673259258725023271941497199",
        "z_max": "0.08280104505183360303236719370447285537437",
        "period": "1.199070652013388462574629437978165526219",
        "apsidal_angle": "1.598174997181537883015151142612624282622",
        "E": "1.304744595096254188737350034684593814849",
        "Lz_peri": "0.2999999999999999888977697537484345957637",
        "w_peri": "0.5",
        "Lz_apo": "0.296249691905311864400526961961010628596",
        "w_apo": "0.5",
        "err": "1.12e-41",
    },
    "bowl-2": {
        "rho_min": "0.3822619938988815920212193874534513614454",
        "rho_max": "0.5999999999999999777955395074968691915274",
        "z_min": "0.08677726264593509514185957784321258996695",
        "z_max": "0.212535715095598747552059981629424236548",
        "period": "1.214652134878129343187031273010674902426",
        "apsidal_angle": "1.827011225454837515100252863234935851564",
        "E": "3.292975365087823771679158881357121995262",
        "Lz_peri": "0.6840690135858103303102586878204622404964",
        "w_peri": "-1.0",
        "Lz_apo": "0.7199999999999999467092948179924870457418",
        "w_apo": "-1.0",
        "err": "1.14e-39",
    },
    "bowl-3": {
        "rho_min": "0.2649423684819489045803820842583772459581",
        "rho_max": "0.8000000000000000444089209850062616169453",
        "z_min": "0.04611030963576547978319001525861409876534",
        "z_max": "0.4168190675270667523214817066942962510286",
        "period": "1.252207978725075226314765767458509567487",
        "apsidal_angle": "1.739275484601273860905519987900412214045",
        "E": "4.536995052440525104434586793838226458466",
        "Lz_peri": "0.6400000000000000710542735760100205592647",
        "w_peri": "1.799556560765696099435635461476796795873e-42",
        "Lz_apo": "0.6400000000000000710542735760100205592647",
        "w_apo": "0.0",
        "err": "4.46e-43",
    },
    "bowl-4": {
        "rho_min": "0.4000000000000000222044604925031308084726",
        "rho_max": "0.6142557286868779371664777881899378885757",
        "z_min": "0.1383156030192957143899056150402915498923",
        "z_max": "0.2753001312437316333276665174759550340635",
        "period": "1.31047010707422939590042404283944687669",
        "apsidal_angle": "1.464090556800045946472655504793074823984",
        "E": "4.565209398952624244645478562438298978474",
        "Lz_peri": "0.600000000000000033306690738754696212709",
        "w_peri": "2.0",
        "Lz_apo": "0.4904123774204513018064830708585663954338",
        "w_apo": "2.0",
        "err": "5.06e-36",
    },
    "bowl-5": {
        "rho_min": "0.1339062582163383586121372335600162870241",
        "rho_max": "0.2819843164100571015275519720966153899981",
        "z_min": "0.01909780609354363855921283435877772486039",
        "z_max": "0.0510085114719137794045054579037120450396",
        "period": "1.18838714908934619391392807803693161031",
        "apsidal_angle": "1.568097856767931631531868477441521533472",
        "E": "0.6033462210822665515885582518060819425781",
        "Lz_peri": "0.100969827377060760691667296712384855107",
        "w_peri": "0.2999999999999999888977697537484345957637",
        "Lz_apo": "0.0982346240589147486119834392160647052054",
        "w_apo": "0.2999999999999999888977697537484345957637",
        "err": "1.54e-41",
    },
    "bowl-6": {
        "rho_min": "0.342301857276869024813570705030812712704",
        "rho_max": "0.5",
        "z_min": "0.07106004580231021918497256632030570013604",
        "z_max": "0.1455411068986407936083380354099942015846",
        "period": "1.207630313795634853581868148011918179278",
        "apsidal_angle": "-1.731830594901832229707475393608809396808",
        "E": "2.17775825867566627156480731810589364785",
        "Lz_peri": "-0.4893598484148099175176284588664771181067",
        "w_peri": "0.5",
        "Lz_apo": "-0.5",
        "w_apo": "0.5",
        "err": "1.49e-41",
    },
    "paraboloid-1": {
        "rho_min": "0.2999999999999999888977697537484345957637",
        "rho_max": "0.3106502942996880422432245160632246758233",
        "z_min": "0.1016887108684174512449189738639176050062",
        "z_max": "0.1083047113218747510077387185516205938823",
        "period": "0.9727518241062769342904403088049555137082",
        "apsidal_angle": "1.879703592375931005983738953498984387984",
        "E": "2.023566253619175188337734897463437829488",
        "Lz_peri": "0.3599999999999999733546474089962435228709",
        "w_peri": "-0.2999999999999999888977697537484345957637",
        "Lz_apo": "0.3604120929576145674426371649312449080654",
        "w_apo": "-0.3072059649079837232827641203207193261218",
        "err": "1.12e-41",
    },
    "paraboloid-2": {
        "rho_min": "0.1000000000000000055511151231257827021182",
        "rho_max": "0.1396934042765169330191761724393192102117",
        "z_min": "0.02020195904500741248372596980799398629311",
        "z_max": "0.0299045715773739239708062472432219806782",
        "period": "0.8554483965444710537491025257793472869992",
        "apsidal_angle": "1.494944984980925414184304902817796134797",
        "E": "0.5731812182315227403911882449180252114024",
        "Lz_peri": "0.05000000000000000277555756156289135105908",
        "w_peri": "1.0",
        "Lz_apo": "0.04739330908044660743497648185442848487282",
        "w_apo": "0.9981134292485225022488833915193508908459",
        "err": "1.43e-41",
    },
    "paraboloid-3": {
        "rho_min": "0.5",
        "rho_max": "0.5257516321664370071598232156301998837726",
        "z_min": "0.2784870989678896674254451012004134665881",
        "z_max": "0.30564933843930808107589478486775175323",
        "period": "1.179636886136728862019542696932087497185",
        "apsidal_angle": "2.24305951849754340199747219121459038279",
        "E": "5.531958440874997820366427049958985735418",
        "Lz_peri": "1.0",
        "w_peri": "0.0",
        "Lz_apo": "1.000099740999798872052043536436471282932",
        "w_apo": "-0.05509684316733121105641591291097177153217",
        "err": "2.07e-41",
    },
    "paraboloid-4": {
        "rho_min": "0.04177481785848364434113765582474445007566",
        "rho_max": "0.2403911089296316798583618739581243072422",
        "z_min": "0.01178068462752371368409924267451059542608",
        "z_max": "0.0689026653175949741132672962158538340121",
        "period": "0.8679891342658625787686094296389653474939",
        "apsidal_angle": "1.840555404580301798045782695787543082698",
        "E": "1.536194439346538083708662402709267302394",
        "Lz_peri": "0.03952627201065452389890911157727238441434",
        "w_peri": "-1.992427474000444925134142992662185669828",
        "Lz_apo": "0.06859143727317819307541120732279222052576",
        "w_apo": "-2.004082058267484800861712831007006650377",
        "err": "1.14e-40",
    },
    "paraboloid-5": {
        "rho_min": "0.3197136513286316799107767884465215396139",
        "rho_max": "0.4000000000000000222044604925031308084726",
        "z_min": "0.1141157608681035712992016969247761855306",
        "z_max": "0.172845645737319195259225618621631100272",
        "period": "1.132034783760968096534034312883662868013",
        "apsidal_angle": "1.788798043464309422215224835323502698575",
        "E": "2.692282451349768009834921004641676073321",
        "Lz_peri": "0.4111150637056490007433434493700819110919",
        "w_peri": "0.7646361337494272982977245999368677319004",
        "Lz_apo": "0.4000000000000000222044604925031308084726",
        "w_apo": "0.6999999999999999555910790149937383830547",
        "err": "2.36e-41",
    },
    "funnel-1": {
        "rho_min": "0.2999999999999999888977697537484345957637",
        "rho_max": "0.5037007740279308980552134797145638691435",
        "z_min": "-0.1552690443766035356953926962514935493612",
        "z_max": "-0.08907439267782526203947252767119258708542",
        "period": "2.674942545280113524873273370643432415911",
        "apsidal_angle": "3.113311446313267933291300039726620513538",
        "E": "-0.5071893253344808196870145200310219619761",
        "Lz_peri": "0.3599999999999999733546474089962435228709",
        "w_peri": "0.2000000000000000111022302462515654042363",
        "Lz_apo": "0.3575916097273156511849620260028444552807",
        "w_apo": "-0.2629770590281330943430307533037912911055",
        "err": "9.71e-39",
    },
    "funnel-2": {
        "rho_min": "0.2000000000000000111022302462515654042363",
        "rho_max": "0.2518434591874543613369329501634107597371",
        "z_min": "-0.2343484398754717495390715344308596580379",
        "z_max": "-0.1859160970616636434213385405711067118333",
        "period": "1.164206697194824457846209799819394646843",
        "apsidal_angle": "3.423756928177424004810321963220290520507",
        "E": "-0.6739581951783779517829232502981540632375",
        "Lz_peri": "0.3000000000000000166533453693773481063545",
        "w_peri": "-0.5",
        "Lz_apo": "0.2886878519809924217725876573382300658636",
        "w_apo": "-1.072562537487538496086613269605313778677",
        "err": "6.21e-40",
    },
    "funnel-3": {
        "rho_min": "0.1936305582363790253492830191203084747573",
        "rho_max": "0.5",
        "z_min": "-0.2419664675188638018659598331976817909044",
        "z_max": "-0.08980348203603407773939197293704641086956",
        "period": "2.303590140993958449586289494218399831185",
        "apsidal_angle": "3.344939702715803156866018381323690521289",
        "E": "-0.6289721587734943619448274442311574512482",
        "Lz_peri": "0.2742918282818974432321694487078895769332",
        "w_peri": "1.303923819945737281512895206654260550709",
        "Lz_apo": "0.2999999999999999888977697537484345957637",
        "w_apo": "0.0",
        "err": "2.81e-36",
    },
    "funnel-4": {
        "rho_min": "0.1470881947637765936022607122954264953186",
        "rho_max": "0.4642255955496661831628540580599273238168",
        "z_min": "-0.3159727581402863844284010953513878154375",
        "z_max": "-0.09744314987535427153785933175402136963506",
        "period": "1.774294041863684503113089817378510490679",
        "apsidal_angle": "3.466678170642960813067863202038307122236",
        "E": "-0.5111137384591954851671546459093698863004",
        "Lz_peri": "0.2693594646819204125436706797781129729103",
        "w_peri": "1.097889062458557601300484495302032212785",
        "Lz_apo": "0.2307291261602372301204385283492564679828",
        "w_apo": "-1.165941173988728241204247742935381229448",
        "err": "2.91e-36",
    },
    "funnel-5": {
        "rho_min": "0.1000000000000000055511151231257827021182",
        "rho_max": "0.1205163762662287566423121095411613987024",
        "z_min": "-0.4756463608701595834591017631332178233619",
        "z_max": "-0.3975866568742739657693100352088657279847",
        "period": "0.5896853024821288766911024356222793672209",
        "apsidal_angle": "5.394964328694714488508293842949574159394",
        "E": "-1.260090800136265149791100831503003752442",
        "Lz_peri": "0.2200000000000000299760216648792275775142",
        "w_peri": "0.2999999999999999888977697537484345957637",
        "Lz_apo": "0.2182382485454261084220360817223210439209",
        "w_apo": "-1.31298384526330486981952881054321179373",
        "err": "2.72e-38",
    },
    "log_well-1": {
        "rho_min": "0.2000000000000000111022302462515654042363",
        "rho_max": "0.2596252574721575092495558838562060476072",
        "z_min": "0.04723768379517042925499009933837108117316",
        "z_max": "0.06643234629477809034228000981984278590544",
        "period": "1.171752149350154068206917091849681183262",
        "apsidal_angle": "1.797332020308920183634965266207278155742",
        "E": "0.9294016780306219909968799802835545126919",
        "Lz_peri": "0.1600000000000000177635683940025051398162",
        "w_peri": "0.2999999999999999888977697537484345957637",
        "Lz_apo": "0.1596579444150309197749868436459257015921",
        "w_apo": "0.2547674632506589149652805328141283684648",
        "err": "2.05e-41",
    },
    "log_well-2": {
        "rho_min": "0.359981535235479987572475230700383618169",
        "rho_max": "0.4000000000000000222044604925031308084726",
        "z_min": "0.09971672707342698568592390392682539649412",
        "z_max": "0.1126636049869812555971442535560322608119",
        "period": "1.599540337053953832366047832982148694647",
        "apsidal_angle": "1.999323901464438214721903997201201483695",
        "E": "1.722229964922286213190583684596730900663",
        "Lz_peri": "0.3603819368140351224119981770225991963002",
        "w_peri": "-0.4607103709998278832899277629241356675249",
        "Lz_apo": "0.3600000000000000288657986402540705440525",
        "w_apo": "-0.5",
        "err": "7.24e-42",
    },
    "log_well-3": {
        "rho_min": "0.2140987245359731844895425282429550815592",
        "rho_max": "0.2999999999999999888977697537484345957637",
        "z_min": "0.0516527366617541363788850842429448753586",
        "z_max": "0.07985562422476034517947987219090538942157",
        "period": "1.265479463541396748846804265863740563756",
        "apsidal_angle": "1.7674433058781503653451530355080265655",
        "E": "1.235383673644899022376567459136502629801",
        "Lz_peri": "0.1810795599365230201904857298442283325469",
        "w_peri": "1.067554245799956465872848981327714521566",
        "Lz_apo": "0.1799999999999999866773237044981217614355",
        "w_apo": "1.0",
        "err": "2.29e-37",
    },
    "log_well-4": {
        "rho_min": "0.4667113217602191321308755742944971680076",
        "rho_max": "0.6163170007047799688112045049625430122024",
        "z_min": "0.1334188959885496633657516456001053059035",
        "z_max": "0.1755972325073604973853126032762716334596",
        "period": "2.163597877124306058620571990421921626386",
        "apsidal_angle": "2.057685187615398774644021301678895755863",
        "E": "2.281126660740978500661822850239238448098",
        "Lz_peri": "0.5499816912092769561550082160327962996781",
        "w_peri": "0.03291191885603989471348940669672547081115",
        "Lz_apo": "0.5497761024571690276608162864933475853744",
        "w_apo": "-0.08688422343378370288635261881372096635385",
        "err": "6.14e-41",
    },
    "power3-1": {
        "rho_min": "0.392965284055413467858306143218206093735",
        "rho_max": "0.4000000000000000222044604925031308084726",
        "z_min": "0.04060899026225275704367602988607561452424",
        "z_max": "0.04228727888443371125383443220677095708431",
        "period": "1.405495768547931270190932165144929844578",
        "apsidal_angle": "1.431073062675463565712690810588088147145",
        "E": "0.8708382058562947866086454487837207128979",
        "Lz_peri": "0.3201810285621865166753627812399854730682",
        "w_peri": "0.1969168546739101817832085301577324854096",
        "Lz_apo": "0.3200000000000000355271367880050102796323",
        "w_apo": "0.2000000000000000111022302462515654042363",
        "err": "7.24e-42",
    },
    "power1.5-1": {
        "rho_min": "0.2212925775886161672406083443747153423781",
        "rho_max": "0.2999999999999999888977697537484345957637",
        "z_min": "0.1163654089705498990477989261326378256898",
        "z_max": "0.1772866131166956766540076457787869171892",
        "period": "0.9212248340419167103724646335456531952984",
        "apsidal_angle": "2.069703986609494429873152675456001731149",
        "E": "2.439181674674784687256845819647050546276",
        "Lz_peri": "0.3004672569318202054328893268228051505208",
        "w_peri": "0.1888797104050124710884497451674052747947",
        "Lz_apo": "0.2999999999999999888977697537484345957637",
        "w_apo": "0.0",
        "err": "1.56e-36",
    },
    "cone-1": {
        "rho_min": "0.1722505089824435248513634610779146825348",
        "rho_max": "0.2999999999999999888977697537484345957637",
        "z_min": "0.2694881928286551945313963124083863866214",
        "z_max": "0.4562191060903079014445868009421538670168",
        "period": "0.9446493457640471320740714330117366083584",
        "apsidal_angle": "2.703101397033240729464197804984207883019",
        "E": "5.207509430745920756516917504899178964751",
        "Lz_peri": "0.2999999999999999888977697537484345957637",
        "w_peri": "1.484065959309792738040764313002072936621",
        "Lz_apo": "0.2999999999999999888977697537484345957637",
        "w_apo": "0.4000000000000000222044604925031308084726",
        "err": "2.4e-36",
    },
    "cylinder-1": {
        "rho_min": "0.4899999999999999997918331828827831486706",
        "rho_max": "0.4899999999999999997918331828827831486706",
        "z_min": "-2.699226249999999983441249101767667983174",
        "z_max": "0.0",
        "period": "2.879917022842054416441561855876619894989",
        "apsidal_angle": "5.877381679269498811561301414353458208739",
        "E": "2.850000000000000047184478546569152968004",
        "Lz_peri": "0.9799999999999999995836663657655662973411",
        "w_peri": "11.5172499999999999370937225906530475685",
        "Lz_apo": "0.9799999999999999995836663657655662973411",
        "w_apo": "0.5",
        "err": "8.38e-41",
    },
    "cylinder-2": {
        "rho_min": "0.4899999999999999997918331828827831486706",
        "rho_max": "0.4899999999999999997918331828827831486706",
        "z_min": "-11.48290499999999994435374850443310243236",
        "z_max": "0.0",
        "period": "5.759834045684108832883123711753239789977",
        "apsidal_angle": "-5.877381679269498811561301414353458208739",
        "E": "0.7180000000000000107691633388640183928054",
        "Lz_peri": "-0.4899999999999999997918331828827831486706",
        "w_peri": "-23.73449999999999988528967542755766054123",
        "Lz_apo": "-0.4899999999999999997918331828827831486706",
        "w_apo": "-0.2999999999999999888977697537484345957637",
        "err": "1.31e-41",
    },
    "rim": {
        "fate_time": "0.3422838217691405209450288672477602193702",
        "fate_azimuth": "1.019541537457768474644983846774287610658",
        "fate_rho": "0.3464999999999999589487967655964182186537",
        "err": "3.07e-35",
    },
    "hole": {
        "fate_time": "0.4779860789808364572266046821842624468908",
        "fate_azimuth": "1.315899597807904639444347473772866658966",
        "fate_rho": "0.0901941932430908037717184732627131309139",
        "err": "1.57e-34",
    },
    "slip": {
        "fate_time": "0.2785522377463158076548390982875095493633",
        "fate_azimuth": "1.092437339040258643940246074838384378576",
        "fate_rho": "0.5137880361600160060437986715222624636925",
        "err": "2.07e-44",
    },
    "loop": {
        "fate_time": "0.4482354684880328282263026205906301117028",
        "fate_azimuth": "1.975771071884557955413047698685342099359",
        "fate_rho": "0.4791799266322930727264689315962021521614",
        "err": "2.49e-45",
    },
    "gutter": {
        "fate_time": "0.1012362498000717435706948456112902462381",
        "fate_azimuth": "0.06671012427292476567835509887678496692085",
        "fate_rho": "0.297749019404998568749236588876485292142",
        "err": "4.61e-36",
    },
}  # fmt: skip
# --- end of generated table ---


if __name__ == "__main__":
    path = Path(__file__)
    text = path.read_text()
    start = text.index("# --- generated by")
    start = text.index("\n", start) + 1
    end = text.index("# --- end of generated table ---")
    path.write_text(text[:start] + _table() + "\n" + text[end:])
    sys.exit(0)

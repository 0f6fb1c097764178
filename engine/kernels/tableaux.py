"""Butcher tableaux and composition weights, as constant float64 arrays (data, not code).

Runge-Kutta pairs, each stored for the one stepper loop in :mod:`.integrators`:

- ``*_A`` (S, S): stage coefficients of all S stages, in order: the ``n`` main stages, the
  FSAL stage (row ``n`` = the weights b: its stage is f(y_new)) and the extra stages that only the
  dense output needs (DOP853: 3). ``*_C`` (S,): stage times; the rows of A sum to C.
- ``*_B`` (n,): weights of the propagated solution (order ``*_ORDER``), sum 1.
- ``*_E`` (n + 1,): error weights (b - b_hat over the main and FSAL stages), sum 0; DOP853 also
  has ``DOP853_E3`` for its 3rd-order companion estimate (Hairer's stretched error norm).
- ``*_P`` (S, deg): dense output y(t + theta h) = y + h sum_i K_i sum_m P[i, m] theta^(m+1).

Sources: Dormand & Prince (1980) with Shampine's dense output (1986); Hairer, Norsett & Wanner,
*Solving ODEs I* (DOP853 and its 7th-order interpolant), in the form of scipy's
``scipy/integrate/_ivp`` tables. Yoshida (1990) composition weights (HLW 2006, eq. V.3.11).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = [
    "DP5_A",
    "DP5_C",
    "DP5_B",
    "DP5_E",
    "DP5_P",
    "DP5_ORDER",
    "DP5_ERR_ORDER",
    "DP5_N_STAGES",
    "DOP853_A",
    "DOP853_C",
    "DOP853_B",
    "DOP853_E",
    "DOP853_E3",
    "DOP853_P",
    "DOP853_ORDER",
    "DOP853_ERR_ORDER",
    "DOP853_N_STAGES",
    "YOSHIDA4",
    "YOSHIDA6",
    "LEAPFROG",
    "composition_weights",
    "Tableau",
    "RK_TABLEAUX",
]


class Tableau(NamedTuple):
    """An embedded explicit Runge-Kutta pair with dense output: everything the generic stepper of
    :mod:`.rk` needs. Its id in kernels is its position in :data:`RK_TABLEAUX`.

    ``A`` (S, S) all stages (main, FSAL row = b, extra dense-output stages); ``C`` (S,);
    ``E`` (n + 1,) error weights; ``E3`` (n + 1,) weights of a 3rd-order companion estimate
    (all zero: plain RMS norm; else Hairer's stretched norm); ``P`` (S, deg) dense output;
    ``n_stages`` n; ``order`` of the propagated solution; ``error_order`` q (the step-size
    exponent is 1/(q+1)); ``beta`` and ``beta_weight`` of the PI controller
    (k1 = 1/(q+1) - beta_weight beta); ``max_factor`` the largest growth of the step after an
    accepted one (Hairer's codes: 10 for dopri5, 6 for dop853); ``unroll``: generate
    straight-line code per component (fast, more to compile) instead of loops over the
    components; ``name`` and ``title`` for users.
    """

    name: str
    title: str
    A: np.ndarray
    C: np.ndarray
    E: np.ndarray
    E3: np.ndarray
    P: np.ndarray
    n_stages: int
    order: int
    error_order: int
    beta: float
    beta_weight: float
    unroll: bool
    max_factor: float = 10.0

    def controller(self) -> tuple[float, float, float, float]:
        """The step-size controller's constants (k1, k_rej, beta, max_factor): the exponents of
        the error after an accepted step (PI: k1 = 1/(q+1) - beta_weight beta) and after a
        rejected one (1/(q+1)), q the error order."""
        q = self.error_order
        k1 = 1.0 / (q + 1) - self.beta_weight * self.beta
        return (k1, 1.0 / (q + 1), float(self.beta), float(self.max_factor))


# --------------------------------------------------------------------------- Dormand-Prince 5(4)
DP5_N_STAGES = 6
DP5_ORDER = 5
DP5_ERR_ORDER = 4
DP5_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
DP5_A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [1 / 5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [3 / 40, 9 / 40, 0.0, 0.0, 0.0, 0.0, 0.0],
        [44 / 45, -56 / 15, 32 / 9, 0.0, 0.0, 0.0, 0.0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0.0, 0.0, 0.0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0.0, 0.0],
        [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0],
    ]
)
DP5_B = DP5_A[DP5_N_STAGES, :DP5_N_STAGES].copy()
DP5_E = np.array([-71 / 57600, 0.0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
DP5_P = np.array(
    [
        [1.0, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0.0, 0.0, 0.0, 0.0],
        [
            0.0,
            131558114200 / 32700410799,
            -68118460800 / 10900136933,
            87487479700 / 32700410799,
        ],
        [
            0.0,
            -1754552775 / 470086768,
            14199869525 / 1410260304,
            -10690763975 / 1880347072,
        ],
        [
            0.0,
            127303824393 / 49829197408,
            -318862633887 / 49829197408,
            701980252875 / 199316789632,
        ],
        [0.0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0.0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ]
)

# ------------------------------------------------------------------------ Dormand-Prince 8(5,3)
DOP853_N_STAGES = 12
DOP853_ORDER = 8
DOP853_ERR_ORDER = 7
_S8 = 16
DOP853_C = np.array(
    [
        0.0,
        0.526001519587677318785587544488e-01,
        0.789002279381515978178381316732e-01,
        0.118350341907227396726757197510,
        0.281649658092772603273242802490,
        0.333333333333333333333333333333,
        0.25,
        0.307692307692307692307692307692,
        0.651282051282051282051282051282,
        0.6,
        0.857142857142857142857142857142,
        1.0,
        1.0,
        0.1,
        0.2,
        0.777777777777777777777777777778,
    ]
)
_A8 = np.zeros((_S8, _S8))
_A8[1, 0] = 5.26001519587677318785587544488e-2
_A8[2, 0] = 1.97250569845378994544595329183e-2
_A8[2, 1] = 5.91751709536136983633785987549e-2
_A8[3, 0] = 2.95875854768068491816892993775e-2
_A8[3, 2] = 8.87627564304205475450678981324e-2
_A8[4, 0] = 2.41365134159266685502369798665e-1
_A8[4, 2] = -8.84549479328286085344864962717e-1
_A8[4, 3] = 9.24834003261792003115737966543e-1
_A8[5, 0] = 3.7037037037037037037037037037e-2
_A8[5, 3] = 1.70828608729473871279604482173e-1
_A8[5, 4] = 1.25467687566822425016691814123e-1
_A8[6, 0] = 3.7109375e-2
_A8[6, 3] = 1.70252211019544039314978060272e-1
_A8[6, 4] = 6.02165389804559606850219397283e-2
_A8[6, 5] = -1.7578125e-2
_A8[7, 0] = 3.70920001185047927108779319836e-2
_A8[7, 3] = 1.70383925712239993810214054705e-1
_A8[7, 4] = 1.07262030446373284651809199168e-1
_A8[7, 5] = -1.53194377486244017527936158236e-2
_A8[7, 6] = 8.27378916381402288758473766002e-3
_A8[8, 0] = 6.24110958716075717114429577812e-1
_A8[8, 3] = -3.36089262944694129406857109825
_A8[8, 4] = -8.68219346841726006818189891453e-1
_A8[8, 5] = 2.75920996994467083049415600797e1
_A8[8, 6] = 2.01540675504778934086186788979e1
_A8[8, 7] = -4.34898841810699588477366255144e1
_A8[9, 0] = 4.77662536438264365890433908527e-1
_A8[9, 3] = -2.48811461997166764192642586468
_A8[9, 4] = -5.90290826836842996371446475743e-1
_A8[9, 5] = 2.12300514481811942347288949897e1
_A8[9, 6] = 1.52792336328824235832596922938e1
_A8[9, 7] = -3.32882109689848629194453265587e1
_A8[9, 8] = -2.03312017085086261358222928593e-2
_A8[10, 0] = -9.3714243008598732571704021658e-1
_A8[10, 3] = 5.18637242884406370830023853209
_A8[10, 4] = 1.09143734899672957818500254654
_A8[10, 5] = -8.14978701074692612513997267357
_A8[10, 6] = -1.85200656599969598641566180701e1
_A8[10, 7] = 2.27394870993505042818970056734e1
_A8[10, 8] = 2.49360555267965238987089396762
_A8[10, 9] = -3.0467644718982195003823669022
_A8[11, 0] = 2.27331014751653820792359768449
_A8[11, 3] = -1.05344954667372501984066689879e1
_A8[11, 4] = -2.00087205822486249909675718444
_A8[11, 5] = -1.79589318631187989172765950534e1
_A8[11, 6] = 2.79488845294199600508499808837e1
_A8[11, 7] = -2.85899827713502369474065508674
_A8[11, 8] = -8.87285693353062954433549289258
_A8[11, 9] = 1.23605671757943030647266201528e1
_A8[11, 10] = 6.43392746015763530355970484046e-1
_A8[12, 0] = 5.42937341165687622380535766363e-2
_A8[12, 5] = 4.45031289275240888144113950566
_A8[12, 6] = 1.89151789931450038304281599044
_A8[12, 7] = -5.8012039600105847814672114227
_A8[12, 8] = 3.1116436695781989440891606237e-1
_A8[12, 9] = -1.52160949662516078556178806805e-1
_A8[12, 10] = 2.01365400804030348374776537501e-1
_A8[12, 11] = 4.47106157277725905176885569043e-2
_A8[13, 0] = 5.61675022830479523392909219681e-2
_A8[13, 6] = 2.53500210216624811088794765333e-1
_A8[13, 7] = -2.46239037470802489917441475441e-1
_A8[13, 8] = -1.24191423263816360469010140626e-1
_A8[13, 9] = 1.5329179827876569731206322685e-1
_A8[13, 10] = 8.20105229563468988491666602057e-3
_A8[13, 11] = 7.56789766054569976138603589584e-3
_A8[13, 12] = -8.298e-3
_A8[14, 0] = 3.18346481635021405060768473261e-2
_A8[14, 5] = 2.83009096723667755288322961402e-2
_A8[14, 6] = 5.35419883074385676223797384372e-2
_A8[14, 7] = -5.49237485713909884646569340306e-2
_A8[14, 10] = -1.08347328697249322858509316994e-4
_A8[14, 11] = 3.82571090835658412954920192323e-4
_A8[14, 12] = -3.40465008687404560802977114492e-4
_A8[14, 13] = 1.41312443674632500278074618366e-1
_A8[15, 0] = -4.28896301583791923408573538692e-1
_A8[15, 5] = -4.69762141536116384314449447206
_A8[15, 6] = 7.68342119606259904184240953878
_A8[15, 7] = 4.06898981839711007970213554331
_A8[15, 8] = 3.56727187455281109270669543021e-1
_A8[15, 12] = -1.39902416515901462129418009734e-3
_A8[15, 13] = 2.9475147891527723389556272149
_A8[15, 14] = -9.15095847217987001081870187138

DOP853_A = _A8
DOP853_B = _A8[DOP853_N_STAGES, :DOP853_N_STAGES].copy()

_E5_8 = np.zeros(DOP853_N_STAGES + 1)
_E5_8[0] = 0.1312004499419488073250102996e-1
_E5_8[5] = -0.1225156446376204440720569753e1
_E5_8[6] = -0.4957589496572501915214079952
_E5_8[7] = 0.1664377182454986536961530415e1
_E5_8[8] = -0.3503288487499736816886487290
_E5_8[9] = 0.3341791187130174790297318841
_E5_8[10] = 0.8192320648511571246570742613e-1
_E5_8[11] = -0.2235530786388629525884427845e-1
DOP853_E = _E5_8
DOP853_E3 = np.zeros(DOP853_N_STAGES + 1)
DOP853_E3[:-1] = DOP853_B
DOP853_E3[0] -= 0.244094488188976377952755905512
DOP853_E3[8] -= 0.733846688281611857341361741547
DOP853_E3[11] -= 0.220588235294117647058823529412e-1

# Dense output (Hairer's contd8), rows 3..6 of its 7 coefficient vectors.
_D8 = np.zeros((4, _S8))
_D8[0, 0] = -0.84289382761090128651353491142e1
_D8[0, 5] = 0.56671495351937776962531783590
_D8[0, 6] = -0.30689499459498916912797304727e1
_D8[0, 7] = 0.23846676565120698287728149680e1
_D8[0, 8] = 0.21170345824450282767155149946e1
_D8[0, 9] = -0.87139158377797299206789907490
_D8[0, 10] = 0.22404374302607882758541771650e1
_D8[0, 11] = 0.63157877876946881815570249290
_D8[0, 12] = -0.88990336451333310820698117400e-1
_D8[0, 13] = 0.18148505520854727256656404962e2
_D8[0, 14] = -0.91946323924783554000451984436e1
_D8[0, 15] = -0.44360363875948939664310572000e1
_D8[1, 0] = 0.10427508642579134603413151009e2
_D8[1, 5] = 0.24228349177525818288430175319e3
_D8[1, 6] = 0.16520045171727028198505394887e3
_D8[1, 7] = -0.37454675472269020279518312152e3
_D8[1, 8] = -0.22113666853125306036270938578e2
_D8[1, 9] = 0.77334326684722638389603898808e1
_D8[1, 10] = -0.30674084731089398182061213626e2
_D8[1, 11] = -0.93321305264302278729567221706e1
_D8[1, 12] = 0.15697238121770843886131091075e2
_D8[1, 13] = -0.31139403219565177677282850411e2
_D8[1, 14] = -0.93529243588444783865713862664e1
_D8[1, 15] = 0.35816841486394083752465898540e2
_D8[2, 0] = 0.19985053242002433820987653617e2
_D8[2, 5] = -0.38703730874935176555105901742e3
_D8[2, 6] = -0.18917813819516756882830838328e3
_D8[2, 7] = 0.52780815920542364900561016686e3
_D8[2, 8] = -0.11573902539959630126141871134e2
_D8[2, 9] = 0.68812326946963000169666922661e1
_D8[2, 10] = -0.10006050966910838403183860980e1
_D8[2, 11] = 0.77771377980534432092869265740
_D8[2, 12] = -0.27782057523535084065932004339e1
_D8[2, 13] = -0.60196695231264120758267380846e2
_D8[2, 14] = 0.84320405506677161018159903784e2
_D8[2, 15] = 0.11992291136182789328035130030e2
_D8[3, 0] = -0.25693933462703749003312586129e2
_D8[3, 5] = -0.15418974869023643374053993627e3
_D8[3, 6] = -0.23152937917604549567536039109e3
_D8[3, 7] = 0.35763911791061412378285349910e3
_D8[3, 8] = 0.93405324183624310003907691704e2
_D8[3, 9] = -0.37458323136451633156875139351e2
_D8[3, 10] = 0.10409964950896230045147246184e3
_D8[3, 11] = 0.29840293426660503123344363579e2
_D8[3, 12] = -0.43533456590011143754432175058e2
_D8[3, 13] = 0.96324553959188282948394950600e2
_D8[3, 14] = -0.39177261675615439165231486172e2
_D8[3, 15] = -0.14972683625798562581422125276e3


def _dop853_dense() -> np.ndarray:
    """Hairer's contd8 rewritten as polynomial weights P (16 x 7) of the stages.

    contd8: y(theta) - y0 = theta (F0 + (1-theta)(F1 + theta (F2 + (1-theta)(F3 + theta (F4
    + (1-theta)(F5 + theta F6)))))) with F0 = dy, F1 = h f0 - dy, F2 = 2 dy - h (f1 + f0),
    F3..F6 = h D K; every F_m is h G[m] . K, so P = G^T Phi with Phi the monomial coefficients
    of the nested products.
    """
    b = np.zeros(_S8)
    b[:DOP853_N_STAGES] = DOP853_B
    f0 = np.zeros(_S8)
    f0[0] = 1.0
    f1 = np.zeros(_S8)
    f1[DOP853_N_STAGES] = 1.0
    G = np.vstack([b, f0 - b, 2.0 * b - f1 - f0, _D8])
    x = np.polynomial.Polynomial([0.0, 1.0])
    one_minus = np.polynomial.Polynomial([1.0, -1.0])
    phi = []
    acc = np.polynomial.Polynomial([1.0])
    for m in range(7):
        acc = acc * (x if m % 2 == 0 else one_minus)
        phi.append(acc)
    # phi_m multiplies F_m after the nesting: phi_0 = x, phi_1 = x(1-x), phi_2 = x^2 (1-x), ...
    Phi = np.zeros((7, 7))
    for m, poly in enumerate(phi):
        coef = poly.coef
        Phi[m, : coef.size - 1] = coef[1:]
    return G.T @ Phi


DOP853_P = _dop853_dense()

# -------------------------------------------------------------- symmetric composition weights
#: Plain leapfrog (order 2).
LEAPFROG = np.array([1.0])
_Y4 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
#: Yoshida's triple jump (order 4): w1, w0, w1.
YOSHIDA4 = np.array([_Y4, 1.0 - 2.0 * _Y4, _Y4])
_Y6 = (
    0.78451361047755726381949763,
    0.23557321335935813368479318,
    -1.17767998417887100694641568,
)
#: Yoshida's 7-stage solution A (order 6): w3 w2 w1 w0 w1 w2 w3.
YOSHIDA6 = np.array([_Y6[0], _Y6[1], _Y6[2], 1.0 - 2.0 * sum(_Y6), _Y6[2], _Y6[1], _Y6[0]])


def composition_weights(order: int) -> np.ndarray:
    """Symmetric composition weights of the given order (2, 4 or 6)."""
    table = {2: LEAPFROG, 4: YOSHIDA4, 6: YOSHIDA6}
    if order not in table:
        raise ValueError(f"order must be 2, 4 or 6; got {order!r}")
    return table[order]


# ------------------------------------------------------------------------------ the RK pairs
#: Every Runge-Kutta pair the engine offers, in kernel-id order (id = position). Adding a pair
#: here is all it takes: the method registry, the survey file, the CLI and the tests read it.
RK_TABLEAUX: tuple[Tableau, ...] = (
    Tableau(
        name="rk45",
        title="Dormand-Prince 5(4), Shampine's quartic dense output",
        A=DP5_A,
        C=DP5_C,
        E=DP5_E,
        E3=np.zeros(DP5_N_STAGES + 1),
        P=DP5_P,
        n_stages=DP5_N_STAGES,
        order=DP5_ORDER,
        error_order=DP5_ERR_ORDER,
        beta=0.04,  # Hairer's dopri5
        beta_weight=0.75,
        unroll=True,
    ),
    Tableau(
        name="dop853",
        title="Dormand-Prince 8(5,3), Hairer's degree-7 dense output",
        A=DOP853_A,
        C=DOP853_C,
        E=DOP853_E,
        E3=DOP853_E3,
        P=DOP853_P,
        n_stages=DOP853_N_STAGES,
        order=DOP853_ORDER,
        error_order=DOP853_ERR_ORDER,
        beta=0.0,  # Hairer's dop853
        beta_weight=0.2,
        unroll=False,  # 12 stages, few steps: loops compile faster at the same speed
        # Hairer's dop853 (fac2 = 6): with 10, the jump from the first step can let a step's
        # error pass at 3x the tolerance on near-circular orbits (psi 1.3e-10 at rtol 1e-10).
        max_factor=6.0,
    ),
)

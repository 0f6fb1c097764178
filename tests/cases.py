"""Shared test cases: the named hard cases of the integrators, the reference data, helpers.

Accuracy promise of the integrators (documented in engine.integrated): with relative tolerance
rtol the integrated radial period and apsidal angle are within 100 rtol kappa relative, where
kappa = max(1, (A / r1^2) / |calE|) is the amplification of a relative velocity error at the
pericentre into the radial energy (1 for most orbits; (1 + e)/(1 - e) for a free-fall ellipse,
where the period depends on the small binding energy). The factor 100 covers the growth of the
local errors over the ~10^2-10^3 steps of a period.
"""

import json
import math
from pathlib import Path

import numpy as np

import engine
from engine.integrated import evaluate_integrated
from engine.kernels.cone import coefficients
from engine.scene import Scene

METHODS = ("rk45", "dop853", "symplectic")


RTOL = 1e-10
#: Accepted steps per radial period at rtol 1e-10 never exceed these (measured maxima over the
#: hard cases and the reference data: rk45 563, dop853 140, symplectic 937).
STEP_BOUND = {"rk45": 1500, "dop853": 500, "symplectic": 2500}


REF = Path(__file__).resolve().parents[2] / "shared" / "reference" / "public.json"
if not REF.exists():  # CI clones main with shared/ beside it
    REF = Path(__file__).resolve().parents[1] / "data" / "reference_public.json"

CASES = json.loads(REF.read_text())


BOUNDED_REF = [
    c
    for c in CASES
    if c["outputs"]["class"] == "bounded" and c["tag"] in ("typical", "other_k", "freefall")
]


P003 = next(c for c in CASES if c["id"] == "P003")["inputs"]


def vmin(alpha, h, Lz, scene):
    return float(np.asarray(engine.minimum_energy(alpha, h, Lz, scene)).reshape(-1)[0])


def _case(alpha, h, Lz, scene=None, rel=0.5, energy=None):
    scene = scene or Scene()
    if energy is None:
        v = vmin(alpha, h, Lz, scene)
        energy = v + rel * abs(v)
    return {"alpha": alpha, "energy": energy, "h": h, "Lz": Lz, "scene": scene}


def _free_fall(e, alpha=0.6, h=-2.0, Lz=0.5):
    sc = Scene(g=0.0)
    A, B, C = coefficients(alpha, h, Lz, sc.M, 0.0, sc.k)
    assert B < 0
    return _case(alpha, h, Lz, sc, energy=-B * B / (4 * A) * (1 - e * e))


#: The named hard cases of the integrators issue.
HARD = {
    "alpha_1e-3": _case(1e-3, 1.0, 0.5),
    "alpha_pi/2-1e-3": _case(math.pi / 2 - 1e-3, 1.0, 0.5),
    "Lz_1e-7_grazes_axis": _case(0.6, 1.0, 1e-7, energy=1.0),
    "energy_1e-10_above_circular": _case(0.6, 1.0, 0.5, rel=1e-10),
    "free_fall_e_0.999": _free_fall(0.999),
    "spin_dominated_hLz>0": _case(0.6, 50.0, 0.3, rel=0.3),
    "spin_dominated_hLz<0": _case(0.6, -50.0, 0.3, rel=0.3),
    "spin_dominated_hLz<0_Lz<0": _case(0.6, 50.0, -0.3, rel=0.3),
    "M_1e-3": _case(0.6, 1.0, 0.5e-3, Scene(M=1e-3)),
    "M_1e3": _case(0.6, 1.0, 0.5e3, Scene(M=1e3)),
}


def kappa(c):
    """Energy amplification factor of the accuracy promise (module docstring)."""
    sc = c["scene"]
    A, B, C = coefficients(c["alpha"], c["h"], c["Lz"], sc.M, sc.g, sc.k)
    r1 = float(engine.evaluate(c["alpha"], c["energy"], c["h"], c["Lz"], sc).r_min)
    return max(1.0, A / r1**2 / abs(c["energy"]))


def closed_form(c):
    ds = engine.evaluate(c["alpha"], c["energy"], c["h"], c["Lz"], c["scene"])
    assert engine.CLASS_NAMES[int(ds.orbit_class)] == "bounded"
    return float(ds.period), float(ds.apsidal_angle)


def integrate(c, method, rtol=RTOL, **kw):
    res = evaluate_integrated(
        np.array([c["alpha"]]),
        np.array([c["energy"]]),
        np.array([c["h"]]),
        np.array([c["Lz"]]),
        c["scene"],
        method,
        rtol,
        **kw,
    )
    return {k: v[0] for k, v in res.items()}

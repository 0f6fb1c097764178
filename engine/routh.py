"""Exact orbit maps on any surface of revolution: Routh's reduction (docs/physics.md "Any
surface of revolution"; kernels :mod:`engine.kernels.routh` and :mod:`engine.kernels.routh_orbit`).

Per surface, once, :func:`surface_table` builds the fundamental matrix Phi of the linear
meridian system d(L, X)/dq = A(q) (L, X) (Phi(q_ref) = I) to near machine precision: Chebyshev
collocation in integral form on panels (:mod:`engine.kernels.routh_panel`), marched from
q_ref, each panel halved until the last two Chebyshev coefficients of its propagator are below
:data:`PANEL_TOL`.
Where the coefficients decay like 1/q^2 or faster (the cone, where A = 0; the funnel) the
last panels are in x = 1/q up to q = inf; elsewhere the table ends at a finite q (the rim, or
beyond the launches' reach, extended when an orbit reaches it). Tables are cached by the
surface's parameters (:func:`surface_table`), never built per orbit.

:func:`exact_map` maps points (the surface model's points array: shape1, shape2, rho0, v0, w0
[, u0]) grouped by surface.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from .kernels import routh as K
from .kernels.layouts import P_RADIUS
from .kernels.meridian import (
    BOWL,
    CONE,
    CYLINDER,
    FUNNEL,
    P_KIND,
    P_Q_HI,
    P_Q_LO,
    P_SHAPE1,
    P_SHAPE2,
    PARABOLOID,
    POWER_LAW,
    PROFILE,
    centre,
)
from .kernels.routh_orbit import orbit_points
from .kernels.routh_panel import panel
from .kernels.surface_starts import X_POS, launch_q, set_point

#: A panel is accepted when its propagator's last two Chebyshev coefficients are below this.
PANEL_TOL = 2e-15
#: Most panels of a table (a surface singular at an end stops refining there: :attr:`error`).
MAX_PANELS = 4000
#: Tables kept (by the surface's parameters).
CACHE_SIZE = 256


class Table(NamedTuple):
    """A surface's fundamental solution (:mod:`engine.kernels.routh`): ``edges``, ``coef``,
    ``meta``, and ``params``, the surface's parameter array after ``set_point``."""

    edges: np.ndarray
    coef: np.ndarray
    meta: np.ndarray
    params: np.ndarray

    @property
    def error(self) -> float:
        """The largest trailing coefficient left on a panel (relative; <= PANEL_TOL unless the
        surface is singular at an end)."""
        return float(self.meta[K.ERROR])


def _has_tail(p: np.ndarray) -> bool:
    """Whether A(q) decays like 1/q^2 or faster (the table may reach q = inf in x = 1/q)."""
    kind, n = p[P_KIND], p[P_SHAPE2]
    return kind in (CONE, FUNNEL) or (kind == POWER_LAW and (n <= -1.0 or n in (0.0, 1.0)))


def _ends(p: np.ndarray) -> tuple[float, int]:
    """The inner end q_a and its kind: where the centre reaches the axis (rho = 0 found by
    bisection where rho < 0 at Q_LO), a hole (the funnel, a profile's inner edge), the fit
    limit (Q_LO where the sphere stops fitting just below it)."""
    qa = float(p[P_Q_LO])
    if centre(p, qa)[0] < 0.0:
        lo, hi = qa, max(2.0 * qa, 1.0)
        while centre(p, hi)[0] < 0.0:
            hi *= 2.0
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if centre(p, mid)[0] < 0.0 else (lo, mid)
        qa = hi
    kind = p[P_KIND]
    if centre(p, qa - 1e-12 * abs(qa) - 1e-300)[6] <= 0.0:
        return qa, K.END_UNFIT
    if kind == FUNNEL or (kind == PROFILE and p[P_SHAPE1] > 0.0):
        return qa, K.END_HOLE
    return qa, K.END_AXIS


def _march(p, mode, lo, hi, in_x, from_left, start, out):
    """Panels covering [lo, hi] from its start end with Phi = ``start`` there, halved until
    their trailing coefficients are below PANEL_TOL (or too small to halve): appends (lo, hi,
    in_x, coefficients of Phi - I) to ``out``; returns Phi at the far end and the largest
    trailing coefficient accepted."""
    coef, end, tail = panel(p, mode, lo, hi, in_x, from_left, start)
    mid = 2.0 / (1.0 / lo + 1.0 / hi) if in_x else 0.5 * (lo + hi)
    width = (1.0 / lo - 1.0 / hi) * lo if in_x else (hi - lo) / max(abs(lo), abs(hi))
    small = not (lo < mid < hi) or width <= 1e-12
    if tail > PANEL_TOL and not small and len(out) < MAX_PANELS and np.isfinite(tail):
        halves = ((lo, mid), (mid, hi)) if from_left else ((mid, hi), (lo, mid))
        err = 0.0
        for a, b in halves:
            start, e = _march(p, mode, a, b, in_x, from_left, start, out)
            err = max(err, e)
        return start, err
    out.append((lo, hi, in_x, coef))
    return end, tail if np.isfinite(tail) else math.inf


#: Points of the meridian :func:`may_lift` looks at (a profile's convex stretch is wider).
LIFT_PROBES = 2048


def may_lift(p: np.ndarray, q_a: float, q_b: float) -> bool:
    """Whether the normal force of an orbit can fall below zero somewhere on the centre's
    meridian [q_a, q_b] of the surface of ``p``: where it curves away from the ball (kappa < 0),
    falls away outward (sin b < 0: the parallel's term is negative) or overhangs (cos b <= 0);
    elsewhere every term of N is >= 0. The funnel is convex everywhere, a power law z = c rho^n
    where c n (n - 1) < 0 (its slope never falls outward for c, n > 0); the bowl (to its
    equator), paraboloid, cone and cylinder never; a profile is looked at on :data:`LIFT_PROBES`
    points (an infinite range up to 10^6 times its start)."""
    kind = p[P_KIND]
    if kind == FUNNEL:
        return True
    if kind == POWER_LAW:
        return bool(p[P_SHAPE1] * p[P_SHAPE2] * (p[P_SHAPE2] - 1.0) < 0.0)
    if kind in (CYLINDER, CONE, BOWL, PARABOLOID):  # kappa >= 0, cos b > 0, sin b >= 0
        return False
    lo = max(q_a, 0.0) if kind != PROFILE else q_a
    if math.isfinite(q_b):
        qs = np.linspace(lo, q_b, LIFT_PROBES)
    else:
        qs = lo + np.geomspace(1e-6, 1e6, LIFT_PROBES) * max(abs(lo), float(p[P_RADIUS]))
    for q in qs:
        rho, z, cb, sb, kappa = centre(p, float(q))[:5]
        if kappa < 0.0 or cb <= 0.0 or sb < 0.0:
            return True
    return False


def build_table(p: np.ndarray, q_max: float = math.inf) -> Table:
    """The fundamental solution of the surface of ``p`` (a parameter array after
    ``surface_starts.set_point``), to q_max where the surface's own range and its coefficients
    do not end it first (module docstring)."""
    p = np.array(p, dtype=np.float64)
    kind = p[P_KIND]
    meta = np.full(len(K.META), math.nan)
    q_b = float(p[P_Q_HI])
    if kind == CYLINDER:
        rho = centre(p, 0.0)[0]
        meta[[K.MODE, K.N_PANELS, K.N_Q, K.Q_A, K.Q_B, K.INNER, K.RHO_CYL, K.FLAT, K.ERROR,
              K.Q_REF, K.T_REF, K.MAY_LIFT]] = (K.MODE_CYLINDER, 0, 0, -math.inf, q_b, K.END_OPEN,
                                                rho, 1, 0.0, 0.0, 0.0, 0.0)  # fmt: skip
        meta[K.OUTER] = K.END_RIM if math.isfinite(q_b) else K.END_INFINITY
        return Table(np.zeros(1), np.zeros((0, K.NC, 4)), meta, p)
    mode = K.MODE_LW if kind == BOWL else K.MODE_HAT
    q_a, inner = _ends(p)
    outer = K.END_RIM
    tail = _has_tail(p)  # then the table reaches q = inf whatever the rim (q_ref = inf on it)
    if not math.isfinite(q_b):
        if tail:
            outer = K.END_INFINITY
        else:
            q_b = float(q_max) if math.isfinite(q_max) else 1.0
            q_b, outer = max(q_b, 2.0 * q_a), K.END_TABLE
    q_split = q_b
    if tail:
        q_split = min(4.0 * max(q_a, p[P_RADIUS]), q_b)
        q_split = q_split if q_split > 0.0 else min(1.0, q_b)
    panels: list = []
    if kind == FUNNEL and tail:  # q_ref = inf: the tail first, then towards the hole
        start, e1 = _march(p, mode, q_split, math.inf, True, False, np.eye(2), panels)
        _, e2 = _march(p, mode, q_a, q_split, False, False, start, panels)
        q_ref = math.inf
    else:
        start, e1 = _march(p, mode, q_a, q_split, False, True, np.eye(2), panels)
        e2 = 0.0
        if tail:
            _, e2 = _march(p, mode, q_split, math.inf, True, True, start, panels)
        q_ref = q_a
    panels.sort(key=lambda t: t[0])
    edges = np.array([t[0] for t in panels] + [panels[-1][1]])
    coef = np.stack([t[3] for t in panels])
    n_q = sum(1 for t in panels if not t[2])
    flat = not np.any(coef)
    rho_a, _, cb_a, sb_a, kap_a = centre(p, q_a)[:5]
    t_ref = kap_a if inner == K.END_AXIS else sb_a / (cb_a * rho_a)
    q_axis = q_a if kind == CONE else 0.0
    meta[[K.MODE, K.N_PANELS, K.N_Q, K.Q_A, K.Q_B, K.INNER, K.OUTER, K.Q_AXIS, K.T_REF,
          K.FLAT, K.ERROR, K.Q_REF]] = (mode, len(panels), n_q, q_a, q_b, inner, outer, q_axis,
                                        t_ref, float(flat), max(e1, e2), q_ref)  # fmt: skip
    meta[K.MAY_LIFT] = float(may_lift(p, q_a, q_b))
    return Table(edges, np.ascontiguousarray(coef), meta, p)


_CACHE: dict[bytes, Table] = {}


def surface_table(p: np.ndarray, q_max: float = math.inf) -> Table:
    """:func:`build_table`, cached by the surface's parameters (a table built to a larger q_max
    serves a smaller one)."""
    key = np.asarray(p, np.float64).tobytes()
    t = _CACHE.get(key)
    if t is not None and (t.meta[K.OUTER] != K.END_TABLE or t.meta[K.Q_B] >= q_max):
        return t
    t = build_table(p, q_max)
    if len(_CACHE) >= CACHE_SIZE:
        _CACHE.pop(next(iter(_CACHE)))
    _CACHE[key] = t
    return t


def stack_tables(tables: list[Table]) -> tuple[np.ndarray, ...]:
    """(P, edges, coef, meta) of several surfaces, padded, for ``routh_orbit.orbit_points``."""
    ne = max(t.edges.shape[0] for t in tables)
    npan = max(max(t.coef.shape[0] for t in tables), 1)
    P = np.stack([t.params for t in tables])
    edges = np.full((len(tables), ne), math.inf)
    coef = np.zeros((len(tables), npan, K.NC, 4))
    for i, t in enumerate(tables):
        edges[i, : t.edges.shape[0]] = t.edges
        coef[i, : t.coef.shape[0]] = t.coef
    return P, edges, coef, np.stack([t.meta for t in tables])


def exact_map(params: np.ndarray, X: np.ndarray) -> dict[str, np.ndarray]:
    """The exact orbit map of the points ``X`` (columns; rows shape1, shape2, rho0 [m] (the
    cylinder: z0), v0, w0 [m/s][, u0]) on the surface kind and sphere of ``params``: a dict of
    ``orbit_class`` (int8, :data:`engine.kernels.routh.CLASS_NAMES`) and the float64 rows
    :data:`engine.kernels.routh.ROWS`. Points are grouped by their (shape1, shape2): one table
    per surface."""
    X = np.ascontiguousarray(X, np.float64)
    n = X.shape[1]
    if n and (X[0] == X[0, 0]).all() and (X[1] == X[1, 0]).all():  # one surface (most maps)
        shapes, sid = X[:2, :1].T, np.zeros(n, np.int64)
    else:  # a survey sweeping a parameter: one table per (shape1, shape2)
        keys, sid = np.unique(X[0] + 1j * X[1], return_inverse=True)
        shapes = np.stack([keys.real, keys.imag], axis=1)
    sid = np.ascontiguousarray(sid.reshape(-1), np.int64)
    surf, reach = [], []
    for s in range(shapes.shape[0]):
        p = np.array(params, np.float64)
        i = int(np.flatnonzero(sid == s)[0])
        set_point(p, X, i)
        surf.append(p)
        far = launch_q(p, float(np.nanmax(np.append(X[X_POS, sid == s], 0.0))))
        reach.append(4.0 * abs(far) if math.isfinite(far) and far != 0.0 else 1.0)
    cls = np.zeros(n, np.int8)
    f = np.full((len(K.ROWS), n), math.nan)
    todo = np.arange(n)
    for _ in range(40):
        tables = [surface_table(p, r) for p, r in zip(surf, reach, strict=True)]
        P, edges, coef, meta = stack_tables(tables)
        c = np.zeros(todo.shape[0], np.int8)
        out = np.empty((len(K.ROWS), todo.shape[0]))
        orbit_points(np.ascontiguousarray(X[:, todo]), P, sid[todo], edges, coef, meta, c, out,
                     numba.get_num_threads())  # fmt: skip
        cls[todo] = c
        f[:, todo] = out
        again = c == K.EXTEND
        if not again.any():
            break
        todo = todo[again]
        for s in np.unique(sid[todo]):
            reach[s] *= 8.0
    return {"orbit_class": cls, **{name: f[j] for j, name in enumerate(K.ROWS)}}

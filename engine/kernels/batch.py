"""The closed form over arrays of points, in lanes: flat points and survey grids.

Each thread takes chunks of points and evaluates LANES of them at a time, stage by stage:
the energy-independent :func:`.geometry.family` (A, B, C, r_c, V_min, ...), the turning points,
the two complete elliptic integrals, the period, apsidal angle and mu_required. Every stage is a
short loop over the lanes without a data-dependent exit, so the CPU overlaps the lanes'
dependency chains (divisions and square roots, ~15 cycles each) and vectorises what it can. A
lane a stage does not settle (a root not converged after the fixed steps, an orbit that is not
bounded under gravity, a friction maximum inside the orbit, a scene rule) takes the scalar
path of :mod:`.geometry`, which computes the same numbers bit for bit: every number a lane
computes comes from the same scalar helpers, in the same order (tests/kernels/test_batch.py).

On a survey grid the family is the same for every energy of an (alpha, h, L_z) triple:
:func:`orbit_units` computes it once per triple and runs the energies through the lanes. The
callers (:mod:`engine.evaluation`) split the units of work among threads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from .._jit import kernel, parallel_kernel
from .batch_rows import BATCH_ROWS as BATCH_ROWS  # the rows, where they were named before
from .batch_rows import put_rows
from .carlson import cel_pair_lanes
from .ending import mu_required_of
from .geometry import (
    BOUNDED,
    FAMILY_FIELDS,
    FORBIDDEN,
    OUT_OF_RANGE,
    cel_args,
    family,
    family_head,
    orbit_in,
    period_and_angle,
    precession,
    representable,
    scene_point,
    well_or_nan,
)
from .layouts import P_G, P_M, P_MU, P_RIM_SLANT
from .roots import (
    RC_STEPS,
    TP_STEPS,
    circular_radius,
    rc_eligible,
    rc_finish,
    rc_start,
    rc_step,
    tp_accept,
    tp_final,
    tp_safe,
    tp_starts,
    tp_step,
)

#: Points evaluated side by side, and blocks of them per unit of parallel work.
LANES = 32
BLOCKS_PER_CHUNK = 16
#: Energies per unit of parallel work on a grid (each unit computes its triples' families).
GRID_ENERGY_CHUNK = 64
#: Rows of a family table (row i: field i of a family, .geometry.FAMILY_FIELDS; the well's five
#: from F_WELL on).
F_KIND, F_S, F_A, F_B, F_C, F_K, F_RC, F_WELL, F_VMIN, F_C3, F_IGAM, F_NOISE, F_KK = (
    FAMILY_FIELDS.index(n) for n in ("kind", "s", "A", "B", "C", "K", "r_c", "a", "V_min", "c3",
                                     "igam", "noise", "kk"))  # fmt: skip

# Rows of the lanes' scratch table.
(_E, _AL, _H, _LZ, _REG, _RC, _CC, _AA, _DEL, _G1, _G2, _R1, _R2, _D1, _D2, _KC, _P1, _A1, _B1,
 _P2, _A2, _B2, _C1, _C2, _CLS, _T, _PSI, _PREC, _MU, _RCOUT, _ST) = range(31)  # fmt: skip
_NS = _ST + 4  # the last takes four rows (cel_pair_lanes' state)


@kernel
def family_at(F, col):
    """The family (:func:`.geometry.family`) stored in column ``col`` of a family table (row i:
    field i)."""
    f = F[:, col]
    return (int(f[0]), f[1], f[2], f[3], f[4], f[5], f[6], f[7], f[8], f[9], f[10], f[11], f[12],
            f[13], f[14], f[15], f[16], f[17], f[18], f[19], f[20])  # fmt: skip


@kernel
def _store(F, col, row, values):
    """F[row + i, col] = values[i] for a homogeneous tuple of floats."""
    for i in range(len(values)):
        F[row + i, col] = values[i]


@kernel
def families(AL, HH, LZ, m, p, eager, F, R):
    """:func:`.geometry.family` of (AL[j], HH[j], LZ[j]) into column j of F, j < m, with r_c
    over the lanes (RC_STEPS Halley steps side by side). ``R``: float64[3, >= m] scratch."""
    r, dr, ok = R[0], R[1], R[2]
    for j in range(m):
        head = family_head(AL[j], HH[j], LZ[j], p, eager)
        A, B, C = head[F_A], head[F_B], head[F_C]
        F[F_KIND, j] = head[F_KIND]
        _store(F, j, F_S, head[F_S:F_RC])  # the head is the family but r_c and the well
        _store(F, j, F_KK, head[F_RC:])
        ok[j] = 1.0 if LZ[j] != 0.0 and rc_eligible(A, C) else 0.0
        r[j] = rc_start(A, B, C) if ok[j] != 0.0 else 1.0
        dr[j] = math.inf
    for _ in range(RC_STEPS):
        for j in range(m):
            r[j], dr[j] = rc_step(r[j], F[F_A, j], F[F_B, j], F[F_C, j])
    for j in range(m):
        A, B, C = F[F_A, j], F[F_B, j], F[F_C, j]
        if ok[j] != 0.0:
            rc = rc_finish(r[j], dr[j], A, B, C)
        else:
            rc = math.nan if LZ[j] == 0.0 else circular_radius(A, B, C)
        F[F_RC, j] = rc
        _store(F, j, F_WELL, well_or_nan(A, B, C, rc))


@kernel
def select_lanes(F, m, p, circ_tol, S):
    """Which lanes are bounded under gravity (the lanes' path); the others' scalar orbits."""
    for j in range(m):
        e = S[_E, j]
        vmin = F[F_VMIN, j]
        delta = e - vmin
        reg = (F[F_KIND, j] == 0.0 and F[F_C, j] > 0.0 and p[P_G] != 0.0 and delta >= 0.0
               and not abs(e - vmin) <= circ_tol * F[F_NOISE, j])  # fmt: skip
        S[_REG, j] = 1.0 if reg else 0.0
        S[_RC, j] = F[F_RC, j]
        S[_CC, j] = F[F_C, j]
        S[_AA, j] = F[F_WELL, j]
        S[_DEL, j] = delta if reg else 1.0
        if not reg:
            S[_RC, j] = 1.0
            S[_CC, j] = 1.0
            S[_AA, j] = 1.0


@kernel
def turning_lanes(F, m, S):
    """Turning points of the lanes (roots.turning_points_in, side by side)."""
    for j in range(m):
        reg = S[_REG, j] != 0.0
        g1, g2 = tp_starts(S[_RC, j], S[_AA, j], S[_DEL, j], F[F_C3, j], F[F_IGAM, j])
        S[_G1, j] = g1 if reg else 0.5
        S[_G2, j] = g2 if reg else 2.0
        S[_R1, j] = S[_G1, j]
        S[_R2, j] = S[_G2, j]
    for _ in range(TP_STEPS):
        for j in range(m):
            rc, C, a, delta = S[_RC, j], S[_CC, j], S[_AA, j], S[_DEL, j]
            r1, d1 = tp_step(S[_R1, j], rc, C, a, delta)
            r2, d2 = tp_step(S[_R2, j], rc, C, a, delta)
            S[_R1, j] = r1
            S[_R2, j] = r2
            S[_D1, j] = 1.0 if d1 else 0.0
            S[_D2, j] = 1.0 if d2 else 0.0
    for j in range(m):
        if S[_REG, j] == 0.0:
            continue
        rc, C, a, delta = S[_RC, j], S[_CC, j], S[_AA, j], S[_DEL, j]
        r1, r2 = S[_R1, j], S[_R2, j]
        if not tp_accept(r1, S[_D1, j] != 0.0, rc, True):
            r1 = tp_safe(S[_G1, j], rc, C, a, delta, True)
        if not tp_accept(r2, S[_D2, j] != 0.0, rc, False):
            r2 = tp_safe(S[_G2, j], rc, C, a, delta, False)
        e = S[_E, j]
        S[_R1, j], S[_R2, j] = tp_final(
            r1, r2, e, F[F_A, j], F[F_B, j], C, rc, abs(e) + F[F_NOISE, j]
        )


@kernel
def elliptic_lanes(F, m, p, S):
    """Period, apsidal angle and precession rate of the bounded lanes (.geometry.orbit_in):
    the two complete elliptic integrals of every lane in one lock-step loop."""
    for j in range(m):
        r1, r2 = S[_R1, j], S[_R2, j]
        reg = S[_REG, j] != 0.0
        kc, sc = cel_args(F[F_A, j], F[F_C, j], p[P_M], r1, r2)
        S[_KC, j] = kc if reg else 1.0
        S[_P2, j] = r2 / r1 if reg else 1.0
        S[_A1, j] = r1 if reg else 1.0
        S[_B1, j] = r2 if reg else 1.0
        S[_T, j] = sc
        S[_P1, j] = 1.0
        S[_A2, j] = 1.0
        S[_B2, j] = 1.0
    cel_pair_lanes(m, S[_KC], S[_P1], S[_A1], S[_B1], S[_P2], S[_A2], S[_B2], S[_ST:_ST + 4],
                   S[_C1], S[_C2])  # fmt: skip
    for j in range(m):
        T, psi = period_and_angle(S[_T, j], S[_C1, j], S[_C2, j], F[F_K, j], S[_R1, j])
        S[_T, j] = T
        S[_PSI, j] = psi
        S[_PREC, j] = precession(psi, T)
        S[_CLS, j] = BOUNDED
        S[_RCOUT, j] = F[F_RC, j]


@kernel
def friction_lanes(F, m, S):
    """mu_required of the bounded lanes."""
    for j in range(m):
        fr = F[F_KK:, j]  # kk, p0, p2, p3, q0, q3, rs3, fstar
        S[_MU, j] = mu_required_of(S[_R1, j], S[_R2, j], fr[0], fr[1], fr[2], fr[3], fr[4], fr[5],
                                   fr[6], fr[7])  # fmt: skip


@kernel
def scalar_lanes(F, m, p, circ_tol, S):
    """The lanes that are not bounded under gravity, one by one (.geometry.orbit_in)."""
    for j in range(m):
        if S[_REG, j] == 0.0:
            cls, r1, r2, rc, T, psi, prec, mu = orbit_in(family_at(F, j), S[_E, j], p, circ_tol)
            S[_CLS, j], S[_R1, j], S[_R2, j], S[_RCOUT, j] = cls, r1, r2, rc
            S[_T, j], S[_PSI, j], S[_PREC, j], S[_MU, j] = T, psi, prec, mu


@kernel
def store_lanes(m, p, S, out_cls, out_f, oidx):
    """The scene's rules (.geometry.scene_point) and every lane's outputs, to column oidx[j]."""
    plain = not (p[P_RIM_SLANT] < math.inf or p[P_MU] < math.inf)
    for j in range(m):
        o = oidx[j]
        if plain and S[_REG, j] != 0.0 and representable(BOUNDED, S[_R1, j], S[_R2, j], S[_T, j],
                                                          S[_PSI, j], S[_PREC, j]):  # fmt: skip
            out_cls[o] = BOUNDED
            nan = math.nan
            put_rows(out_f, o, (S[_R1, j], S[_R2, j], S[_RCOUT, j], S[_T, j], S[_PSI, j],
                                S[_PREC, j], S[_MU, j], nan, nan, nan))  # fmt: skip
            continue
        res = scene_point(int(S[_CLS, j]), S[_R1, j], S[_R2, j], S[_RCOUT, j], S[_T, j],
                          S[_PSI, j], S[_PREC, j], S[_MU, j], S[_AL, j], S[_E, j], S[_H, j],
                          S[_LZ, j], p)  # fmt: skip
        out_cls[o] = res[0]
        put_rows(out_f, o, res[1:])


#: The stages of :func:`lanes`, as :func:`profile_batch` names them (after ``families``).
STAGES = ("load", "families", "select", "turning points", "elliptic integrals", "mu_required",
          "other classes", "scene and store")  # fmt: skip


@kernel
def lanes(F, m, p, circ_tol, S, out_cls, out_f, oidx):
    """Lanes 0..m-1: lane j is the orbit of family column j of F at energy S[_E, j]
    (alpha S[_AL, j], h S[_H, j], L_z S[_LZ, j] for the scene's rules), written to column
    oidx[j] of the outputs: :func:`.geometry.orbit_point`, bit for bit."""
    select_lanes(F, m, p, circ_tol, S)
    turning_lanes(F, m, S)
    elliptic_lanes(F, m, p, S)
    friction_lanes(F, m, S)
    scalar_lanes(F, m, p, circ_tol, S)
    store_lanes(m, p, S, out_cls, out_f, oidx)


@kernel
def _load(alpha, energy, h, Lz, i0, m, S, oidx):
    """Points i0..i0+m-1 of the flat arrays into the lanes' table."""
    for j in range(m):
        S[_E, j] = energy[i0 + j]
        S[_AL, j] = alpha[i0 + j]
        S[_H, j] = h[i0 + j]
        S[_LZ, j] = Lz[i0 + j]
        oidx[j] = i0 + j


@kernel
def profile_batch(alpha, energy, h, Lz, p, circ_tol, out_cls, out_f, upto):
    """:func:`orbit_units` on flat points, one thread, stopping after stage ``upto`` of
    :data:`STAGES` (a benchmark times each prefix: the stages' cost per point)."""
    n = alpha.shape[0]
    F = np.empty((len(FAMILY_FIELDS), LANES))
    S = np.empty((_NS, LANES))
    R = np.empty((3, LANES))
    oidx = np.empty(LANES, np.int64)
    for i0 in range(0, n, LANES):
        m = min(LANES, n - i0)
        _load(alpha, energy, h, Lz, i0, m, S, oidx)
        if upto >= 1:
            families(S[_AL], S[_H], S[_LZ], m, p, False, F, R)
        if upto >= 2:
            select_lanes(F, m, p, circ_tol, S)
        if upto >= 3:
            turning_lanes(F, m, S)
        if upto >= 4:
            elliptic_lanes(F, m, p, S)
        if upto >= 5:
            friction_lanes(F, m, S)
        if upto >= 6:
            scalar_lanes(F, m, p, circ_tol, S)
        if upto >= 7:
            store_lanes(m, p, S, out_cls, out_f, oidx)
        else:  # keep the stages' results live
            for j in range(m):
                out_f[0][i0 + j] = S[_R1, j] + S[_T, j] + S[_MU, j] + F[F_VMIN, j]


@kernel
def _grid_triples(alpha, h, Lz, ne, t0, m, S, base):
    """Triples t0..t0+m-1 of the grid (Lz fastest) into the lanes' table; base: each at energy 0."""
    nh, nl = h.size, Lz.size
    for j in range(m):
        t = t0 + j
        ia, ih, il = t // (nh * nl), (t // nl) % nh, t % nl
        S[_AL, j] = alpha[ia]
        S[_H, j] = h[ih]
        S[_LZ, j] = Lz[il]
        base[j] = (ia * ne * nh + ih) * nl + il


@kernel
def _grid_energy(energy, ie, relative, nhl, m, F, S, base, oidx, out_energy):
    """Energy ie of the grid for every lane (V_min + offset |V_min| when ``relative``)."""
    for j in range(m):
        e = energy[ie]
        if relative:
            vmin = F[F_VMIN, j]
            e = vmin + e * abs(vmin)
        S[_E, j] = e
        o = base[j] + ie * nhl
        oidx[j] = o
        if out_energy.size:
            out_energy[o] = e


@kernel
def _no_minimum(m, F, S, out_cls, out_f, oidx):
    """Lanes with no V_min: FORBIDDEN (OUT_OF_RANGE if the family is), NaN but r_circ."""
    for j in range(m):
        if math.isnan(S[_E, j]):
            o = oidx[j]
            out_cls[o] = OUT_OF_RANGE if F[F_KIND, j] == OUT_OF_RANGE else FORBIDDEN
            nan = math.nan  # r_circ (row 2) stays
            rc = out_f[2][o] if out_f[2].size else nan
            put_rows(out_f, o, (nan, nan, rc, nan, nan, nan, nan, nan, nan, nan))


@kernel
def orbit_units(u0, u1, alpha, energy, h, Lz, grid, relative, p, circ_tol, out_cls, out_f,
                out_energy):  # fmt: skip
    """Units u0..u1-1 (:func:`.workqueue.work_units`) of :func:`.geometry.orbit_point` in lanes.

    Scene ``p``. Flat (``grid`` False): over 1-D arrays of points, outputs ``out_cls`` int8[n],
    ``out_f`` 10 float64 arrays (rows :data:`BATCH_ROWS`), each [n] or, for a row not wanted,
    [0] (:mod:`.batch_rows`: not written), ``out_energy`` unused. On the grid alpha x energy x
    h x Lz (1-D axes; outputs flat in that C order), each family is computed once per
    (alpha, h, L_z) and a chunk of energies; with ``relative`` the energy axis is an offset:
    the energy is V_min + offset |V_min|; with no V_min a point is :func:`_no_minimum`;
    ``out_energy`` float64[n] receives the absolute energy ([0]: not wanted). Units are
    independent (callers run them on threads; the kernel releases the GIL)."""
    n, nhl = alpha.size, h.size * Lz.size
    ntri = alpha.size * nhl
    nec = (energy.size + GRID_ENERGY_CHUNK - 1) // GRID_ENERGY_CHUNK
    nblk = (n + LANES - 1) // LANES
    F = np.empty((len(FAMILY_FIELDS), LANES))
    S = np.empty((_NS, LANES))
    R = np.empty((3, LANES))
    oidx = np.empty(LANES, np.int64)
    base = np.empty(LANES, np.int64)
    for unit in range(u0, u1):
        m = 0
        if grid:
            t0 = (unit // nec) * LANES
            m = min(LANES, ntri - t0)
            first = (unit % nec) * GRID_ENERGY_CHUNK
            last = min(energy.size, first + GRID_ENERGY_CHUNK)
            _grid_triples(alpha, h, Lz, energy.size, t0, m, S, base)
        else:
            first = unit * BLOCKS_PER_CHUNK
            last = min(nblk, first + BLOCKS_PER_CHUNK)
        for b in range(first, last):
            if grid:
                if b == first:
                    families(S[_AL], S[_H], S[_LZ], m, p, grid, F, R)
                _grid_energy(energy, b, relative, nhl, m, F, S, base, oidx, out_energy)
            else:
                m = min(LANES, n - b * LANES)
                _load(alpha, energy, h, Lz, b * LANES, m, S, oidx)
                families(S[_AL], S[_H], S[_LZ], m, p, grid, F, R)
            lanes(F, m, p, circ_tol, S, out_cls, out_f, oidx)
            if grid and relative:
                _no_minimum(m, F, S, out_cls, out_f, oidx)


@parallel_kernel
def minimum_energy_batch(alpha, h, Lz, p, out):
    """V_min [J] (out[0, i]) and r_c [m] (out[1, i]) of each (alpha, h, Lz) of the scene ``p``;
    NaN where V has no minimum."""
    for i in prange(alpha.shape[0]):
        out[0, i] = out[1, i] = math.nan
        if Lz[i] != 0.0:
            fam = family(alpha[i], h[i], Lz[i], p, False)
            out[0, i], out[1, i] = fam[F_VMIN], fam[F_RC]

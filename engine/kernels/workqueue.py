"""The closed form's units of work taken from a counter the threads share.

:func:`orbit_units_queued` is what each thread of :func:`engine.evaluation.run_units` runs:
it takes the next unit (:func:`work_units`: 512 points, or 32 (alpha, h, L_z) triples
times 64 energies of a grid) with an atomic increment (:func:`.lanes_step.fetch_add`) until
none is left. One call per thread, so the threads start at once and none waits on the Python
interpreter for its next piece, and the split is as fine as a unit: the threads finish within
a unit of each other whatever the points cost (forbidden and circular points are cheap, bounded
ones are not). The results do not depend on which thread computes a unit.

:func:`checked_queued` is the same for the check of the inputs of :func:`engine.evaluate`:
each thread checks chunks of :data:`CHECK_UNIT` points of one input, one pass over each.
"""

from __future__ import annotations

from .._jit import kernel
from .batch import BLOCKS_PER_CHUNK, GRID_ENERGY_CHUNK, LANES, orbit_units
from .lanes_step import fetch_add

#: Points per unit of :func:`checked_queued` (a chunk of one input array).
CHECK_UNIT = 1 << 15


@kernel
def work_units(n, ne, nhl, grid):
    """Units of work of :func:`orbit_units`: chunks of BLOCKS_PER_CHUNK blocks of n points, or
    on a grid (``grid``: n alphas, ne energies, nhl (h, L_z) pairs) a block of LANES triples
    times a chunk of GRID_ENERGY_CHUNK energies."""
    if grid:
        return (n * nhl + LANES - 1) // LANES * ((ne + GRID_ENERGY_CHUNK - 1) // GRID_ENERGY_CHUNK)
    return ((n + LANES - 1) // LANES + BLOCKS_PER_CHUNK - 1) // BLOCKS_PER_CHUNK


@kernel
def orbit_units_queued(queue, n_units, alpha, energy, h, Lz, grid, relative, p, circ_tol, out_cls,
                       out_f, out_energy):  # fmt: skip
    """:func:`.batch.orbit_units` over the units ``queue[0]`` (int64[1], shared by the threads
    and advanced atomically) up to ``n_units``, one at a time. Returns the units this call
    computed."""
    done = 0
    while True:
        u = fetch_add(queue, 1)
        if u >= n_units:
            return done
        orbit_units(u, u + 1, alpha, energy, h, Lz, grid, relative, p, circ_tol, out_cls, out_f,
                    out_energy)  # fmt: skip
        done += 1


@kernel
def checked_queued(queue, n_units, srcs, lo, hi, bad):
    """Set ``bad[j, u]`` (int8[k, units]) to 1 where unit ``u`` of array ``j`` of ``srcs`` (a
    tuple of k C-contiguous float64[n]) holds a value not strictly between ``lo[j]`` and
    ``hi[j]`` (NaN never is; with infinite bounds: a value that is not finite). Units of
    :data:`CHECK_UNIT` points of one array, ``n_units`` = k ceil(n / CHECK_UNIT), taken from
    ``queue`` (int64[1], shared by the threads) until none is left."""
    n = srcs[0].shape[0]
    per = (n + CHECK_UNIT - 1) // CHECK_UNIT
    while True:
        u = fetch_add(queue, 1)
        if u >= n_units:
            return
        j, c = u // per, u % per
        i0 = c * CHECK_UNIT
        i1 = min(n, i0 + CHECK_UNIT)
        src, a, b = srcs[j], lo[j], hi[j]
        n_bad = 0
        for i in range(i0, i1):
            v = src[i]
            n_bad += 1 - ((a < v) & (v < b))
        bad[j, c] = n_bad > 0

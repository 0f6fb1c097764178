"""The closed form's output rows (:mod:`.batch`): one float64 array per row, a row not wanted
of length 0 (neither allocated nor written), and the write of one point's values into them.

Each row is its own array, so a caller hands the kernels the arrays it keeps (a survey block's
buffers, reused from block to block: :func:`engine.evaluation.evaluate_block`) and a map that
does not hold a variable (r_circ in a survey block, the rim's variables on a plain cone) costs
no memory for it. The rows are taken from the tuple by constant indices: a tuple indexed by a
variable is copied to the stack, with a reference count taken, at every write (4x slower).
"""

from __future__ import annotations

import numpy as np

from .._jit import kernel

#: Rows of the float output of :func:`.batch.orbit_units`.
BATCH_ROWS = ("r_min", "r_max", "r_circ", "period", "apsidal_angle", "precession_rate",
              "mu_required", "end_r", "end_time", "end_theta")  # fmt: skip


@kernel
def _put(row, o, value):
    """row[o] = value where the row is wanted (not of length 0)."""
    if row.size:
        row[o] = value


@kernel
def put_rows(out_f, o, v):
    """out_f[i][o] = v[i] for the 10 rows (``v`` a tuple of 10 floats) wanted."""
    r0, r1, r2, r3, r4, r5, r6, r7, r8, r9 = out_f
    _put(r0, o, v[0])
    _put(r1, o, v[1])
    _put(r2, o, v[2])
    _put(r3, o, v[3])
    _put(r4, o, v[4])
    _put(r5, o, v[5])
    _put(r6, o, v[6])
    _put(r7, o, v[7])
    _put(r8, o, v[8])
    _put(r9, o, v[9])


def empty_outputs(n: int, rows=BATCH_ROWS) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """(out_cls, out_f) of :func:`.batch.orbit_units`: int8[n], and for each of
    :data:`BATCH_ROWS` a float64 row, [n] where named in ``rows``, else [0] (not written)."""
    return np.empty(n, np.int8), tuple(np.empty(n if r in rows else 0) for r in BATCH_ROWS)

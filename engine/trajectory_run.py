"""One trajectory's run through the run protocol's kernel (:func:`engine.kernels.trajectory.
solve_restarting`, the fate maps' own loop across stops by rolling resistance), its buffers grown
until they hold the whole run: what :func:`engine.simulate` on the cone and on a surface share."""

from __future__ import annotations

import numpy as np

from ._jit import call_specialized
from .kernels.layouts import ATTITUDE
from .kernels.protocol import BUFFER_FULL, LITERAL
from .kernels.trajectory import solve_restarting

__all__ = ["TrajectoryRun"]


class TrajectoryRun:
    """One trajectory: a sphere that rolling resistance stops and that cannot stay at rest
    starts again from rest, with time running on (the fate maps' own loop,
    :func:`.kernels.fate.run_restarting`)."""

    def __init__(self, kernel_id, effects, p, orbit, rtol, atol, max_steps):
        self.args = (kernel_id, effects, None, p, orbit, rtol, atol)
        self.max_steps = max_steps
        self.n_acc = self.n_rej = 0
        self.t_final = 0.0
        self.y_final = np.empty(0)

    def capacities(self, cap_ev: int, cap_tr: int) -> None:
        self.cap_ev, self.cap_tr = cap_ev, cap_tr

    def follow(self, y0, t_stop, n_apsides, record, dt_out) -> int:
        """Integrate to the end; returns the final status."""
        kid, effects, _, p, orbit, rtol, atol = self.args
        n = y0.shape[0]
        while True:  # integration is deterministic: a run that ran out of room is redone larger
            ev = (np.empty(self.cap_ev), np.empty(self.cap_ev, np.int8),
                  np.empty((self.cap_ev, n)))  # fmt: skip
            tr = (np.empty(self.cap_tr), np.empty((self.cap_tr, n)),
                  np.empty((self.cap_tr if effects & ATTITUDE else 0, n)))  # fmt: skip
            args = (kid, effects, y0, p, orbit, rtol, atol, t_stop, n_apsides, self.max_steps,
                    record, dt_out, *ev, *tr)  # fmt: skip
            res = call_specialized(solve_restarting, args, LITERAL)
            if int(res[0]) != BUFFER_FULL:
                break
            full_ev, full_tr = int(res[5]) >= self.cap_ev - 1, int(res[6]) >= self.cap_tr - 1
            self.cap_ev *= 4 if full_ev or not full_tr else 1
            self.cap_tr *= 4 if full_tr or not full_ev else 1
        status, n_ev, n_tr = int(res[0]), int(res[5]), int(res[6])
        self.n_acc, self.n_rej = int(res[1]), int(res[2])
        self.t_final = float(res[3])
        self.y_final = np.array(res[4], copy=True)
        self.tr = (tr[0][:n_tr], tr[1][:n_tr], tr[2][:n_tr])
        self.ev = (ev[0][:n_ev], ev[1][:n_ev], ev[2][:n_ev])
        return status

    def arrays(self) -> tuple[np.ndarray, ...]:
        return (*self.tr, *self.ev)

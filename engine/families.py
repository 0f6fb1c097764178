"""The values a survey stores on fewer dims than its grid (:func:`engine.schema.variable_dims`):
the potential's minimum V_min and the circular orbit's radius r_c of each (alpha, h, L_z), and
the flat V_min the relative energy axis is measured from. Its own module so that the writers
(:mod:`engine.io.manifest`) can compute them without importing the map evaluation."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Mapping

import numba
import numpy as np

from .kernels.batch import minimum_energy_batch
from .kernels.geometry import ideal_cone
from .precision import at, stored
from .scene import Scene
from .schema import FATE_KINDS, variable_dims

__all__ = ["family_values", "minimum_energy_flat", "well_flat"]


def minimum_energy_flat(alpha: np.ndarray, h: np.ndarray, Lz: np.ndarray, scene: Scene):
    """V_min [J] at each (alpha, h, Lz) of 1-D float64 arrays; NaN where V has no minimum."""
    return well_flat(alpha, h, Lz, scene.params())[0]


def well_flat(alpha: np.ndarray, h: np.ndarray, Lz: np.ndarray, params: np.ndarray) -> np.ndarray:
    """V_min [J] (row 0) and r_c [m] (row 1) at each (alpha, h, Lz) of 1-D float64 arrays, on
    the scene's parameter array ``params``; NaN where V has no minimum."""
    out = np.empty((2, alpha.size))
    minimum_energy_batch(alpha, h, Lz, params, out)
    return out


def family_values(
    dims: tuple[str, ...],
    axes: Mapping[str, np.ndarray],
    scene: Scene,
    kind: str,
    variables: Mapping[str, np.dtype],
) -> dict[str, np.ndarray]:
    """The ``variables`` stored on fewer dims than the grid ``dims``
    (:func:`engine.schema.variable_dims`): on the (alpha, energy, h, L_z) grid r_circ and
    V_min, which depend on (alpha, h, L_z) only, computed once per triple of the axes
    (``axes``: name -> 1-D values), of ``variables``' dtypes, shaped (alpha, h, Lz); {} on
    other grids. r_circ is the family's radius of the circular orbit, NaN where V has no
    minimum (a point out of range at some energy keeps it: its class says so). For a map of
    ``kind`` that follows a scene to its fate, of the ideal cone, as :func:`evaluate_flat`'s
    closed form. Writers and the in-memory survey call it; blocks never hold these."""
    names = [n for n in variables if variable_dims(n, dims) != tuple(dims)]
    if not names:
        return {}
    a, hh, lz = (np.ascontiguousarray(axes[d], np.float64) for d in ("alpha", "h", "Lz"))
    A, H, L = (x.reshape(-1) for x in np.meshgrid(a, hh, lz, indexing="ij"))
    p = scene.params()
    if kind in FATE_KINDS:  # the launch orbit on the ideal cone
        p = ideal_cone(p)
    with _pool_environment():
        well = well_flat(A, H, L, p).reshape(2, a.size, hh.size, lz.size)
    found = {"V_min": well[0], "r_circ": well[1]}
    where = at(("alpha", "h", "Lz"), [a, hh, lz])
    return {n: stored(n, found[n], variables[n], where=where) for n in names}


@contextlib.contextmanager
def _pool_environment() -> Iterator[None]:
    """While a local dask cluster runs, distributed's Nanny writes its workers'
    NUMBA_NUM_THREADS into this process's environment (:mod:`engine.backends`); numba re-reads
    it when it compiles a kernel here and refuses a count other than its running pool's. The
    writers compute :func:`family_values` in this process: the pool's count meanwhile."""
    key, running = "NUMBA_NUM_THREADS", str(numba.config.NUMBA_NUM_THREADS)
    saved = os.environ.get(key)
    if saved is None or saved == running:
        yield
        return
    os.environ[key] = running
    try:
        yield
    finally:
        os.environ[key] = saved

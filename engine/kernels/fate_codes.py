"""The fate vocabulary: what happened to an orbit, the float rows of a fate map, the rest
threshold. Plain data (no numba): the fate kernels (:mod:`.fate`), the models' starts (the
cone's: :mod:`.cone_starts`) and the API read it."""

from __future__ import annotations

#: What happened to an orbit (int8, CF flag_values 0..6).
NO_ORBIT = 0
ROLLING = 1
FATE_SPILLED = 2
FATE_SLIPPED = 3
FATE_REST = 4
FATE_VERTEX = 5
FAILED = 6
FATE_NAMES = ("no_orbit", "rolling", "spilled", "slipped", "rest", "vertex", "failed")
#: The sphere left the surface (its normal force fell to zero: a surface's fate, never the
#: cone's); after the sliding model's codes 7 and 8 (``.story_parts``), so that one code means
#: one fate in every file.
FATE_LIFTED_OFF = 9
#: A model's start that runs (not a fate: the run goes on from the start).
RUNS = -1
#: Rows of the float output of :func:`.fate.fate_points`.
FATE_ROWS = ("fate_time", "fate_r", "fate_theta", "revolutions", "energy_lost", "invariant_drift")
#: The rest threshold in units of rtol times the orbit's speed scale.
REST_SPEED = 10.0

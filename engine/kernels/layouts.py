"""The layouts every model shares: the parameter array's slots, declared once by name, and the
state vector's components.

A scene reaches the kernels as one float64 array ``p``, so sweeping a grid never recompiles:

- the slots every model shares (:data:`SHARED_SLOTS`: the sphere, the thresholds a run sets);
- each effect's slots, in the order of the effects table (:attr:`.effects.Effect.params`: the
  value of the effect's Scene field);
- from :data:`MODEL_BASE` on, the model's own slots (its geometry; each model module declares
  its ``SLOTS``, and :mod:`.model` derives the array's size from the largest).

Kernels read a slot by a module constant (``P_M``, ``P_CRR``, ...), a compile-time integer.
Every name is declared once; an effect row or a model that names a slot twice, or a slot this
layout does not know, fails at import.
"""

from __future__ import annotations

from .._jit import kernel
from .effects import DISSIPATIVE, EFFECT_BITS, EFFECTS

#: The slots every model shares: name -> what it holds.
SHARED_SLOTS: dict[str, str] = {
    "M": "mass [kg]",
    "g": "gravity [m s-2]",
    "k": "inertia factor I/(M a^2)",
    "kk": "k / (1 + k)",
    "radius": "sphere radius a [m]",
    "inv_m1k": "1 / (M (1 + k)) [kg-1]",
    "r_vertex": "the inner end of the surface: the meridian coordinate below which a run ends",
    "rim_level": "the rim: the centre's meridian coordinate where the sphere spills (inf: none)",
    "v_rest": "speed [m/s] below which rolling resistance has stopped the sphere (per orbit)",
    "theta_max": "azimuth [rad] after which a fate run stops (inf: none; REVOLUTIONS runs)",
}


def _layout() -> dict[str, int]:
    names = list(SHARED_SLOTS)
    for effect in EFFECTS:
        for slot in effect.params:
            if slot in names:
                raise ValueError(f"effect {effect.name!r}: parameter slot {slot!r} is taken")
            names.append(slot)
    return {name: i for i, name in enumerate(names)}


#: Slot name -> index, for the shared slots and the effects' slots.
SLOTS: dict[str, int] = _layout()
#: The first slot of a model's own parameters (:mod:`.model`).
MODEL_BASE = len(SLOTS)

P_M = SLOTS["M"]
P_G = SLOTS["g"]
P_K = SLOTS["k"]
P_KK = SLOTS["kk"]
P_RADIUS = SLOTS["radius"]
P_INV_M1K = SLOTS["inv_m1k"]
P_R_VERTEX = SLOTS["r_vertex"]
P_RIM = SLOTS["rim_level"]
P_V_REST = SLOTS["v_rest"]
P_THETA_MAX = SLOTS["theta_max"]
# The effects' slots (their rows in the effects table name them).
P_RIM_SLANT = SLOTS["rim"]  # the rim as a user measures it [m] (inf: none)
P_MU = SLOTS["mu"]  # friction coefficient (inf: no slip check)
P_CRR = SLOTS["c_rr"]  # rolling-resistance coefficient


def model_slots(names: tuple[str, ...]) -> dict[str, int]:
    """A model's own slots (its ``SLOTS``) -> index, from :data:`MODEL_BASE` on."""
    if len(set(names)) != len(names):
        raise ValueError(f"a model names a parameter slot twice: {names}")
    return {name: MODEL_BASE + i for i, name in enumerate(names)}


# ------------------------------------------------------------------------ the state vector
#: The state's components every model has (the model interface, :mod:`.model`): the meridian
#: coordinate (the cone's r) [m], theta [rad], u [m/s] along the meridian, v [m/s] along the
#: parallel, w = a omega_nu [m/s].
STATE = ("r", "theta", "u", "v", "w")
N_BASE = len(STATE)
#: Their places in y (kernels index the state by these names, never by number).
Y_R, Y_THETA, Y_U, Y_V, Y_W = range(N_BASE)
#: The place of the attitude quaternion's first (scalar) component, with ``ATTITUDE``.
Y_QUAT = N_BASE
#: Then, with the attitude effect, the unit quaternion (scalar first) that rotates body axes to
#: the fixed frame (identity at t = 0); with a dissipative effect, last, the work the effects
#: took from the sphere [J].
ATTITUDE = EFFECT_BITS["attitude"]
N_QUATERNION = 4


def state_size_of(effects: int) -> int:
    """Length of the state vector of an effect set."""
    quaternion = N_QUATERNION if effects & ATTITUDE else 0
    return N_BASE + quaternion + (1 if effects & DISSIPATIVE else 0)


@kernel
def state_size(effects):
    """:func:`state_size_of` inside kernels."""
    n = N_BASE
    if effects & ATTITUDE:
        n += N_QUATERNION
    if effects & DISSIPATIVE:
        n += 1
    return n

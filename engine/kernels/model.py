"""The model interface: what the drivers (Runge-Kutta steps, SIMD lanes, events, fate stories)
ask of the physics, and the registry of models that answer.

A model is one kernel module (the cone, :mod:`.cone`, is the first) that declares in one place
its parameter slots (``SLOTS``, after the shared ones of :mod:`.layouts`), its rolling equations
of motion, its invariants, its contact (normal force, the friction rolling needs), its event
functions and where its runs start; its row in :data:`MODELS` says which capabilities it offers
(:data:`MODEL_CAPABILITIES`) and why it lacks the others, so a method that needs one it lacks is
refused with that reason (``engine.methods``), never run wrongly.

The model reaches the kernels inside the ``effects`` literal, above the effect bits:
``effects = effect bits | model id << MODEL_SHIFT`` (:func:`scene_key`). Each (model, effect
set) is its own compiled, disk-cached specialisation, and each function below picks the
model's own kernel at compile time: a model costs the others nothing. The cone is id 0, so a
cone scene's key is its effect bits.

The state y, the same for every model (its length :func:`state_size`): the meridian coordinate
(the cone's r) [m], theta [rad], u [m/s] along the meridian, v [m/s] along the parallel, w = a
omega_nu [m/s]; with ``ATTITUDE`` the unit quaternion (q0, q1, q2, q3) (body axes to the fixed
frame, identity at t = 0); with a dissipative effect last the work the effects took [J].
"""

from __future__ import annotations

import inspect
from typing import NamedTuple

import numpy as np
from numba.core import errors, types
from numba.extending import overload
from numba.np.unsafe.ndarray import to_fixed_tuple

from .._jit import kernel
from . import cone, cone_starts, surface, surface_starts
from .effects import EFFECT_BITS, REVOLUTIONS
from .layouts import (
    MODEL_BASE,
    P_G,
    P_INV_M1K,
    P_K,
    P_KK,
    P_M,
    P_R_VERTEX,
    P_RADIUS,
    P_RIM,
    P_THETA_MAX,
    P_V_REST,
    Y_R,
    Y_U,
    Y_V,
    Y_W,
)

# Effect bits (combine with |), from the effects table.
ROLLING_RESISTANCE = EFFECT_BITS["rolling_resistance"]
RIM = EFFECT_BITS["rim"]
SLIP_CHECK = EFFECT_BITS["slip_check"]

#: The model id's place in the ``effects`` literal (above the effect bits and run options).
MODEL_SHIFT = 20
assert REVOLUTIONS < 1 << MODEL_SHIFT, "run options must stay below the model id"

#: What a model may offer -> what that means. Each model declares every one, offered or
#: lacked with a reason.
MODEL_CAPABILITIES: dict[str, str] = {
    "exact maps": "orbits without integrating them: the cone's closed form (complete elliptic "
    "integrals), a surface's reduction to its meridian (Routh's integrals and quadrature)",
    "invariant grids": "maps over (alpha, E, h, L_z): an orbit identified by its invariants",
    "separable split": "a separable radial Hamiltonian (the symplectic integrator's split)",
    "sliding contact": "the sliding model: a slip becomes a transition (mu_k, c_spin), one "
    "launch's whole story",
    "sliding maps": "sliding scenes in maps and sampled trajectories: many stories at once on "
    "the SIMD lanes, a story's trajectory sampled",
}


class Model(NamedTuple):
    """A model's row: its name, its id in the ``effects`` literal, its kernel modules (the
    physics: ``SLOTS``, the equations, invariants and contact; the starts: where its runs
    start from a point of a map) and the capabilities it offers; ``lacks`` names each other
    one with the reason."""

    name: str
    id: int
    physics: object
    starts: object
    offers: tuple[str, ...]
    lacks: tuple[tuple[str, str], ...]


#: Every model, by id.
MODELS: tuple[Model, ...] = (
    Model("cone", 0, cone, cone_starts, tuple(MODEL_CAPABILITIES), ()),
    Model(
        "surface",
        1,
        surface,
        surface_starts,
        ("exact maps", "sliding contact"),
        (
            (
                "invariant grids",
                "an orbit off the cone is identified by its launch (rho0, v0, w0): its two "
                "linear integrals are constants of the whole surface's meridian",
            ),
            (
                "separable split",
                "the symplectic integrator splits the cone's radial Hamiltonian; a curved "
                "meridian has no such split",
            ),
            (
                "sliding maps",
                "on a surface one launch's story is followed (engine.story(surface=...)); the "
                "maps' launches and the sampled trajectory of a sliding scene are written for "
                "the cone's orbits (alpha, E, h, L_z)",
            ),
        ),
    ),
)
#: Model id -> row (what the functions below dispatch on).
MODEL_ROWS = {m.id: m for m in MODELS}
#: The models' ids.
CONE = 0
SURFACE = 1


def check_models(models: tuple[Model, ...]) -> None:
    """Refuse (ValueError) a registry whose ids are not the rows' positions, a row that does not
    declare every capability once (offered, or lacked with a reason), or a name used twice."""
    for position, m in enumerate(models):
        if m.id != position:
            raise ValueError(f"model {m.name!r}: id {m.id} must be its position {position}")
        declared = [*m.offers, *(c for c, _ in m.lacks)]
        if sorted(declared) != sorted(MODEL_CAPABILITIES):
            raise ValueError(
                f"model {m.name!r} must declare each of {sorted(MODEL_CAPABILITIES)} once, "
                f"offered or lacked with a reason; it declares {declared}"
            )
        if any(not why.strip() for _, why in m.lacks):
            raise ValueError(f"model {m.name!r}: a lacked capability needs its reason")
    if len({m.name for m in models}) != len(models):
        raise ValueError("model names must be unique")


check_models(MODELS)

#: Length of the parameter array: the shared and effect slots, then the largest model's own.
N_PARAMS = MODEL_BASE + max(len(m.physics.SLOTS) for m in MODELS)
#: The vertex region (the inner end of a surface), in units of the sphere's radius a.
VERTEX_FRACTION = 1e-2


def scene_key(model: int, effects: int) -> int:
    """The ``effects`` literal of a model and an effect set (module docstring)."""
    return int(effects) | (int(model) << MODEL_SHIFT)


def model_of_key(effects: int) -> int:
    """The model id of an ``effects`` literal."""
    return int(effects) >> MODEL_SHIFT


# ------------------------------------------------------------------------ the scene's params
@kernel
def make_params(M, g, k, a, slots, values):
    """The float64 parameter array (layout :mod:`.layouts`, length :data:`N_PARAMS`) of a
    sphere M, g, k, a: then ``values[i]`` into slot ``slots[i]`` (the effects' slots); no rim
    until the model sets one, and the model's own slots 0 until it sets them."""
    p = np.zeros(N_PARAMS)
    p[P_M] = M
    p[P_G] = g
    p[P_K] = k
    p[P_KK] = k / (1.0 + k)
    p[P_RADIUS] = a
    for i in range(slots.shape[0]):
        p[slots[i]] = values[i]
    p[P_INV_M1K] = 1.0 / (M * (1.0 + k))
    p[P_R_VERTEX] = VERTEX_FRACTION * a
    p[P_RIM] = np.inf
    p[P_V_REST] = 0.0
    p[P_THETA_MAX] = np.inf
    return p


@kernel
def param_tuple(p):
    """The parameter array as a tuple: the hot loops index it with constants and keep the values
    in registers (an array is re-read after every store that might alias it)."""
    return to_fixed_tuple(p, N_PARAMS)


# ------------------------------------------------------------------ the model's kernels
_JIT_ONLY = "runs inside numba kernels only"
_OPTS = {"error_model": "numpy", "fastmath": False, "nogil": True}


def literal_row(effects) -> Model:
    """The model row of a scene key typed as a numba literal (compile time)."""
    if not isinstance(effects, types.IntegerLiteral):
        raise errors.TypingError("a scene key must be a numba literal here (use numba.literally)")
    model = int(effects.literal_value) >> MODEL_SHIFT
    if model not in MODEL_ROWS:
        raise errors.TypingError(f"no model with id {model}")
    return MODEL_ROWS[model]


def interface(stub, part: str, takes_effects: bool = True, key: str = "effects"):
    """Make ``stub`` (a function of the interface) call the model's own kernel of the same name
    inside kernels, picked at compile time from its literal parameter ``key`` (a scene key,
    :func:`scene_key`: ``effects`` here, the contact key ``model`` in :mod:`.contact`): the
    model row's ``part`` module ("physics" or "starts"); without ``takes_effects`` the model's
    kernel does not take the key. A model module that lacks the kernel fails at import
    (:func:`check_interface`, ``contact.check_contact``)."""
    names = list(inspect.signature(stub).parameters)
    args = ", ".join(names)
    call = ", ".join(n for n in names if takes_effects or n != key)
    at = names.index(key)
    src = f"def typer({args}):\n    return pick(({args})[{at}])\n"
    body = f"def impl({args}):\n    return f({call})\n"

    def pick(effects):
        namespace = {"f": getattr(getattr(literal_row(effects), part), stub.__name__)}
        exec(compile(body, f"<conesurvey model {stub.__name__}>", "exec"), namespace)  # noqa: S102
        return namespace["impl"]

    namespace = {"pick": pick}
    exec(compile(src, f"<conesurvey model {stub.__name__} typer>", "exec"), namespace)  # noqa: S102
    overload(stub, jit_options=_OPTS)(namespace["typer"])
    return stub


def motion_rates(r, u, v, w, p, effects):
    """(rdot, thetadot, udot, vdot, wdot): the model's rolling equations with the effects'
    forces and couples. Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def dissipated_power(r, u, v, w, p, effects):
    """The power [W] the effects take from the rolling sphere. Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def omega_fixed(r, theta, u, v, w, p, effects):
    """The rolling sphere's angular velocity (wx, wy, wz) [rad/s] in the fixed frame.
    Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def invariants(y, p, effects):
    """(E [J], and the model's two conserved quantities: the cone's L_z and h) of the state y.
    Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def domain_floor(p, effects):
    """The meridian coordinate at or below which the model's state means nothing (the cone:
    r = 0; a surface: where the sphere stops fitting or touching): a step that ends there is
    rejected. Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def slip_margin(y, p, effects):
    """Event function of the slip check: |F| - mu N [N] (> 0: the sphere slips). Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def lift_margin(y, p, effects):
    """Event function of lift-off: -N [N] (>= 0: the normal force is gone, the sphere leaves
    the surface). Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def set_point(p, X, i, effects):
    """Point i's geometry (the columns of the points array X the model reads) into p. Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def period_start(effects, p, X, i, rtol):
    """Where point i's one-period run starts: (ok, y0 at a turning point, atol, the run's
    orbit constants); ok False: no bounded orbit. Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def fate_start(effects, p, X, i, rtol):
    """Where point i's fate run starts: (start, r, y0, t0, work0, atol, orbit constants),
    start :data:`.fate_codes.RUNS` or the fate it has at its start (the cone's:
    :func:`.cone_starts.fate_start`). Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def holds_at_rest(p, y, effects):
    """Whether rolling resistance holds a sphere at rest at the state y. Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


def starts_inner(effects, p, y0):
    """Whether a one-period run from the turning point y0 starts at the inner one (its first
    apsis is then the outer: the apocentre). Jit-only."""
    raise NotImplementedError(_JIT_ONLY)


interface(motion_rates, "physics")
interface(dissipated_power, "physics")
interface(omega_fixed, "physics", takes_effects=False)
interface(invariants, "physics", takes_effects=False)
interface(slip_margin, "physics")
interface(lift_margin, "physics", takes_effects=False)
interface(domain_floor, "physics", takes_effects=False)
interface(set_point, "starts", takes_effects=False)
interface(period_start, "starts")
interface(fate_start, "starts")
interface(holds_at_rest, "starts", takes_effects=False)
interface(starts_inner, "starts")

#: The kernels each model provides: (module part, name).
INTERFACE = tuple(
    (part, fn.__name__)
    for part, fns in (
        (
            "physics",
            (
                motion_rates,
                dissipated_power,
                omega_fixed,
                invariants,
                slip_margin,
                lift_margin,
                domain_floor,
            ),
        ),
        ("starts", (set_point, period_start, fate_start, holds_at_rest, starts_inner)),
    )
    for fn in fns
)


def check_interface(models: tuple[Model, ...]) -> None:
    """Refuse (ValueError) a model whose modules lack a kernel of the interface, or whose
    physics does not declare its parameter slots."""
    for m in models:
        missing = [f"{part}.{name}" for part, name in INTERFACE
                   if not hasattr(getattr(m, part), name)]  # fmt: skip
        for name in ("SLOTS", "DOMAIN_FLOOR_SLOT", "LEAVES"):
            if not hasattr(m.physics, name):
                missing.append(f"physics.{name}")
        if missing:
            raise ValueError(f"model {m.name!r} lacks {', '.join(missing)}")


check_interface(MODELS)


def leaves(effects) -> bool:
    """Whether the model of ``effects`` (an ``effects`` literal in a kernel, or an int) can
    lose its contact: its physics' ``LEAVES``; runs of such a model watch for lift-off.
    Folds to a constant in a kernel."""
    return bool(MODEL_ROWS[model_of_key(effects)].physics.LEAVES)


@overload(leaves, jit_options=_OPTS)
def _leaves(effects):
    value = bool(literal_row(effects).physics.LEAVES)
    return lambda effects: value


# ----------------------------------------------------------- what every model shares
@kernel
def rim_margin(y, p):
    """Event function of the rim: the meridian coordinate past the rim's (:data:`.layouts.P_RIM`,
    set by the model) [m] (>= 0: the sphere has left the surface)."""
    return y[Y_R] - p[P_RIM]


@kernel
def kinetic_energy(y, p):
    """Kinetic energy [J] of translation and rotation of the rolling sphere."""
    M = p[P_M]
    k = p[P_K]
    u = y[Y_U]
    v = y[Y_V]
    w = y[Y_W]
    return 0.5 * (1.0 + k) * M * (u * u + v * v) + 0.5 * k * M * w * w


@kernel
def energy(y, p, effects):
    """The total energy E [J] of the state y."""
    return invariants(y, p, effects)[0]

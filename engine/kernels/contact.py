"""The sliding contact's interface: what the hybrid model (:mod:`.sliding`, :mod:`.hybrid_rk`,
:mod:`.hybrid_step`, the story) asks of a model, in any mode.

The hybrid equations are written once for any surface of revolution in the meridian frame at
the centre (:func:`.sliding.frame_rates`); a model gives that frame and the height's energy:

- :func:`contact_frame` ``(model, r, u, v, p)``: (dtheta/dt [rad/s], N [N], g sin b [m s-2],
  cos(b)/rho, kappa, sin(b)/rho [1/m], dr/ds) at the centre's meridian coordinate r, moving at
  (u, v) [m/s] along (e1, e2): b the meridian's slope, rho the centre's distance from the axis,
  kappa the meridian's curvature, N the normal force (the same formula rolling or sliding:
  M (g cos b + kappa u^2 + sin(b)/rho v^2)), dr/ds the rate of the meridian coordinate along
  the arc (the cone's r is its arc: 1);
- :func:`height_energy` ``(model, r, p)``: M g z [J] of the centre at r.

``model`` is the contact key (:func:`contact_key`: the model id and the scene's applied
effects, :data:`APPLIED`, as a scene key), a numba literal in a kernel: each model's hybrid
kernels are their own compiled specialisations, the call resolved at compile time by
:func:`.model.interface`, the model interface's one dispatch (a model costs the others
nothing), and the sliding equations ask :func:`.forces.effect_terms` of the applied effects
alone. In plain Python (the ``.py_func`` of a hybrid kernel, as ``engine.simulate_hybrid`` and
the tests run them) the call goes to the model's kernel's ``.py_func`` by the key's value.

What a story asks of a model besides its frame (:mod:`.story_parts`, :mod:`.story_switches`):

- :func:`story_start` ``(model, effects, p, start, rtol, out, y0, atol)``: a launch's rolling
  start state y0, its tolerances and the rest threshold (in p) from the model's ``start``
  tuple (the cone's: radial energy, h, L_z, r_start, u0, slip_u, slip_v; a surface's: the
  centre's distance from the axis rho0 (the cylinder: its height), v0, w0, unused, u0,
  slip_u, slip_v); returns (the fate where it ends at its start or -1, the energy scale [J],
  the speed scale [m/s], the rolling orbit's constants (:func:`rolling_orbit`'s));
- :func:`resume_rolling` ``(model, effects, p, yr, rtol, ra)``: the tolerances of a rolling
  stretch that starts at yr (after a slip), and its orbit's constants;
- :func:`rolling_orbit` ``(model, r, u, v, w, p)``: the constants a story reports for a rolling
  state (the cone's (calE, h, L_z); a surface's (E, NaN, NaN): its two linear integrals need
  the surface's table, ``engine.routh``), and :func:`rolling_energy`, its energy E [J];
- :func:`rest_spin_rate` ``(model, c_spin, r, p)``: |dw/dt| of a sphere at rest at r spinning
  against spin friction, and :func:`holds_at_rest` ``(model, p, y)``: whether rolling
  resistance holds a sphere at rest at y;
- :func:`leaves_contact` ``(model)``: whether the model's normal force can fall to zero
  (then its stories watch for lift-off).
"""

from __future__ import annotations

from numba.extending import overload

from .effects import EFFECT_BITS, FORCE_EFFECTS
from .model import (
    MODEL_ROWS,
    MODEL_SHIFT,
    MODELS,
    Model,
    interface,
    literal_row,
    model_of_key,
    scene_key,
)

__all__ = ["APPLIED", "CONTACT", "check_contact", "contact_frame", "contact_key", "domain_floor",
           "height_energy", "holds_at_rest", "leaves_contact", "rest_spin_rate",
           "resume_rolling", "rolling_energy", "rolling_orbit", "story_start"]  # fmt: skip

_OPTS = {"error_model": "numpy", "fastmath": False, "nogil": True}

#: The effects the hybrid model asks of :func:`.forces.effect_terms` in both modes: every
#: effect acting through forces but rolling resistance, whose rules at zero tangential spin
#: the hybrid model writes itself (static while sliding, docs/physics.md "Rolling resistance
#: while sliding"). A recipe's new force effect is one of them.
APPLIED = FORCE_EFFECTS & ~EFFECT_BITS["rolling_resistance"]


def contact_key(model: int, effects: int) -> int:
    """The hybrid kernels' literal ``model``: the model id and the scene's :data:`APPLIED`
    effects, as a scene key (``model.scene_key``; the cone without them: 0). The hybrid
    kernels compile once per model and applied effect set, whatever the scene's other effects."""
    return scene_key(model, int(effects) & APPLIED)


def _row(model) -> Model:
    key = int(model)
    if key & ((1 << MODEL_SHIFT) - 1) & ~APPLIED:
        raise ValueError(f"{key} is not a contact key (a model id and applied effects)")
    row = MODEL_ROWS.get(model_of_key(key))
    if row is None:
        raise ValueError(f"no model with id {model_of_key(key)}")
    return row


def contact_frame(model, r, u, v, p):
    """The meridian frame at the centre (module docstring)."""
    return _row(model).physics.contact_frame.py_func(r, u, v, p)


def height_energy(model, r, p):
    """M g z [J] of the centre at the meridian coordinate r."""
    return _row(model).physics.height_energy.py_func(r, p)


def rolling_orbit(model, r, u, v, w, p):
    """The constants a story reports for the rolling state (r, u, v, w) (module docstring)."""
    return _row(model).physics.rolling_orbit.py_func(r, u, v, w, p)


def rolling_energy(model, r, u, v, w, p):
    """E [J] of the rolling state (r, u, v, w)."""
    return _row(model).physics.rolling_energy.py_func(r, u, v, w, p)


def rest_spin_rate(model, c_spin, r, p):
    """|dw/dt| [m s-2] of a sphere at rest at r spinning against spin friction."""
    return _row(model).physics.rest_spin_rate.py_func(c_spin, r, p)


def domain_floor(model, p):
    """The meridian coordinate at or below which the model's state means nothing (a step that
    ends there is rejected: :func:`.model.domain_floor`)."""
    return _row(model).physics.domain_floor.py_func(p)


def holds_at_rest(model, p, y):
    """Whether rolling resistance holds a sphere at rest at the state y."""
    return _row(model).starts.holds_at_rest.py_func(p, y)


def story_start(model, effects, p, start, rtol, out, y0, atol):
    """A launch's rolling start (module docstring)."""
    return _row(model).starts.story_start.py_func(effects, p, start, rtol, out, y0, atol)


def resume_rolling(model, effects, p, yr, rtol, ra):
    """A rolling stretch's tolerances into ra and its orbit's constants (module docstring)."""
    return _row(model).starts.resume_rolling.py_func(effects, p, yr, rtol, ra)


for _stub in (
    contact_frame,
    height_energy,
    rolling_orbit,
    rolling_energy,
    rest_spin_rate,
    domain_floor,
):
    interface(_stub, "physics", takes_effects=False, key="model")
for _stub in (holds_at_rest, story_start, resume_rolling):
    interface(_stub, "starts", takes_effects=False, key="model")

#: The kernels a model with sliding contact provides: (module part, name).
CONTACT = (("physics", "contact_frame"), ("physics", "height_energy"),
           ("physics", "rolling_orbit"), ("physics", "rolling_energy"),
           ("physics", "rest_spin_rate"), ("physics", "domain_floor"), ("physics", "LEAVES"),
           ("starts", "holds_at_rest"), ("starts", "story_start"),
           ("starts", "resume_rolling"))  # fmt: skip


def leaves_contact(model) -> bool:
    """Whether the model's normal force can fall to zero (its physics' ``LEAVES``). Folds to a
    constant in a kernel (``model`` literal)."""
    return bool(_row(model).physics.LEAVES)


@overload(leaves_contact, jit_options=_OPTS)
def _leaves_contact(model):
    value = bool(literal_row(model).physics.LEAVES)
    return lambda model: value


def check_contact(models: tuple[Model, ...]) -> None:
    """Refuse (ValueError) a model that offers sliding contact but lacks a kernel of
    :data:`CONTACT`."""
    for m in models:
        if "sliding contact" not in m.offers:
            continue
        missing = [f"{part}.{name}" for part, name in CONTACT
                   if not hasattr(getattr(m, part), name)]  # fmt: skip
        if missing:
            raise ValueError(f"model {m.name!r} offers sliding contact but lacks {missing}")


check_contact(MODELS)

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

``model`` is a model id (:data:`.model.MODELS`), a numba literal in a kernel: each model's hybrid
kernels are their own compiled specialisations, the call resolved at compile time (a model costs
the others nothing). In plain Python (the ``.py_func`` of a hybrid kernel, as
``engine.simulate_hybrid`` and the tests run them) the call goes to the model's kernel's
``.py_func`` by the model id's value.
"""

from __future__ import annotations

import inspect

from numba.core import errors, types
from numba.extending import overload

from .model import MODEL_ROWS, MODELS, Model

__all__ = ["CONTACT", "check_contact", "contact_frame", "height_energy"]

_OPTS = {"error_model": "numpy", "fastmath": False, "nogil": True}


def _row(model) -> Model:
    if model not in MODEL_ROWS:
        raise ValueError(f"no model with id {model}")
    return MODEL_ROWS[model]


def _interface(stub):
    """Make ``stub`` (first parameter ``model``) call the model's physics kernel of the same name
    with the other arguments: picked at compile time from the literal ``model`` in a kernel, by
    its value in plain Python."""
    names = list(inspect.signature(stub).parameters)
    args = ", ".join(names)
    rest = ", ".join(names[1:])
    body = f"def impl({args}):\n    return f({rest})\n"

    def typer(model, *rest):
        if not isinstance(model, types.IntegerLiteral):
            raise errors.TypingError("model must be a numba literal here (use numba.literally)")
        if model.literal_value not in MODEL_ROWS:
            raise errors.TypingError(f"no model with id {model.literal_value}")
        namespace = {"f": getattr(MODEL_ROWS[model.literal_value].physics, stub.__name__)}
        exec(compile(body, f"<conesurvey contact {stub.__name__}>", "exec"), namespace)  # noqa: S102
        return namespace["impl"]

    src = f"def typer_named({args}):\n    return typer({args})\n"
    namespace = {"typer": typer}
    exec(compile(src, f"<conesurvey contact {stub.__name__} typer>", "exec"), namespace)  # noqa: S102
    overload(stub, jit_options=_OPTS)(namespace["typer_named"])
    return stub


@_interface
def contact_frame(model, r, u, v, p):
    """The meridian frame at the centre (module docstring)."""
    return _row(model).physics.contact_frame.py_func(r, u, v, p)


@_interface
def height_energy(model, r, p):
    """M g z [J] of the centre at the meridian coordinate r."""
    return _row(model).physics.height_energy.py_func(r, p)


#: The kernels a model with sliding contact provides.
CONTACT = ("contact_frame", "height_energy")


def check_contact(models: tuple[Model, ...]) -> None:
    """Refuse (ValueError) a model that offers sliding contact but lacks a kernel of
    :data:`CONTACT`."""
    for m in models:
        if "sliding contact" not in m.offers:
            continue
        missing = [name for name in CONTACT if not hasattr(m.physics, name)]
        if missing:
            raise ValueError(f"model {m.name!r} offers sliding contact but lacks {missing}")


check_contact(MODELS)

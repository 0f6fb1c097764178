"""The effects table (engine/kernels/effects.py) and what derives from it: every method honours
or refuses every effect, with a reason; masks, Scene.effects, the map kind and the variables
follow the rows."""

from __future__ import annotations

import dataclasses

import pytest

from engine import Scene
from engine.kernels import effects as fx
from engine.kernels import symplectic
from engine.kernels.batch import BATCH_ROWS
from engine.kernels.protocol import EVENT_NAMES, kind_enabled
from engine.methods import METHODS, Method
from engine.schema import CLOSED_FORM, RESULTS, map_kind, period_variables, result_variables

#: One scene per effect, with only that effect on.
ONLY = {
    "rolling_resistance": Scene(c_rr=0.01),
    "rim": Scene(rim=3.0),
    "slip_check": Scene(mu=0.5),
    "attitude": Scene(attitude=True),
    "sliding": Scene(mu=0.5, mu_k=0.3),
    "spin_friction": Scene(mu=0.5, mu_k=0.3, c_spin=0.01),
}
#: The effects a scene must name for the effect to be possible (kinetic friction needs the static
#: coefficient; spin friction belongs to the sliding model).
PREREQUISITES = {"sliding": ("slip_check",), "spin_friction": ("slip_check", "sliding")}


def test_every_effect_has_a_scene_above():
    assert set(ONLY) == set(fx.BY_NAME)
    for name, scene in ONLY.items():
        assert scene.effects == (*PREREQUISITES.get(name, ()), name)
        assert scene.effects_mask == fx.mask_of(scene.effects)
        assert scene.effects_mask & fx.BY_NAME[name].bit


@pytest.mark.parametrize("method", list(METHODS.values()), ids=list(METHODS))
@pytest.mark.parametrize("effect", fx.EFFECTS, ids=[e.name for e in fx.EFFECTS])
def test_every_method_honours_or_refuses_every_effect_with_a_reason(method, effect):
    """A method either has every capability the effect needs, or refuses the effect with the
    reason it gave for lacking one; refusing goes through check_method's error."""
    refused = dict(method.refuses)
    lacked = [c for c in effect.needs if c not in method.supports]
    if not lacked:
        assert effect.name not in refused and method.honours(effect.name)
        return
    reason = refused[effect.name]
    assert reason.strip()
    for c in lacked:
        assert dict(method.lacks)[c] in reason
    assert method.refused_mask & effect.bit


def test_a_method_that_forgets_a_capability_is_an_error():
    """Support is opt-in: a method row that neither supports nor lacks a capability (as a new
    effect needing a new capability would leave every old row) does not construct."""
    some = next(iter(fx.CAPABILITIES))
    others = tuple(c for c in fx.CAPABILITIES if c != some)
    with pytest.raises(ValueError, match=f"missing \\['{some}'\\]"):
        Method("forgetful", 0, "runge-kutta", "t", others)
    with pytest.raises(ValueError, match="no reason"):
        Method("terse", 0, "runge-kutta", "t", others, ((some, " "),))
    with pytest.raises(ValueError, match="twice"):
        Method("both", 0, "runge-kutta", "t", tuple(fx.CAPABILITIES), ((some, "why"),))


def test_symplectic_kernel_refuses_what_the_registry_refuses():
    """The kernel's own guard (status UNSUPPORTED) and the registry agree, from one declaration."""
    assert symplectic.UNSUPPORTED_EFFECTS == METHODS["symplectic"].refused_mask
    assert METHODS["symplectic"].supports == symplectic.SUPPORTS


def test_masks_follow_the_rows():
    assert fx.ALL_EFFECTS == sum(e.bit for e in fx.EFFECTS)
    assert fx.DISSIPATIVE == fx.mask_of(("rolling_resistance", "sliding", "spin_friction"))
    assert fx.ROLLING_EFFECTS == fx.mask_of(("rolling_resistance", "rim", "slip_check", "attitude"))
    assert fx.names_of(fx.ALL_EFFECTS) == tuple(fx.BY_NAME)
    assert not fx.REVOLUTIONS & fx.ALL_EFFECTS


@pytest.mark.parametrize("effect", fx.EFFECTS, ids=[e.name for e in fx.EFFECTS])
def test_terminal_events_follow_the_rows(effect):
    for kind in range(EVENT_NAMES.index("spill"), EVENT_NAMES.index("horizon")):
        assert kind_enabled.py_func(effect.bit, kind) == (EVENT_NAMES[kind] in effect.events)


@pytest.mark.parametrize("effect", fx.EFFECTS, ids=[e.name for e in fx.EFFECTS])
def test_map_kind_and_variables_follow_the_rows(effect):
    scene = ONLY[effect.name]
    fate = effect.dissipative or bool(effect.events)
    kind = "fate" if fate else "one period"
    if "sliding contact" in effect.needs:  # a slip is a transition: the hybrid kernels
        kind = "sliding fate"
    assert map_kind("rk45", scene) == kind
    added = dict(effect.variables)
    assert set(added.get("fate", ())) <= set(result_variables("rk45", scene))
    if METHODS["exact"].honours(effect.name):
        closed = list(result_variables("exact", scene))
        assert closed[8:] == list(added.get("closed form", ()))
    assert set(added.get("period", ())) <= set(period_variables(scene))
    if effect.bit & fx.ROLLING_EFFECTS:  # the others have no one-period map (engine.story)
        assert ("energy_loss" in period_variables(scene)) == effect.dissipative


def test_scene_fields_are_checked_by_their_switch():
    """Each effect's Scene field is checked as its switch says (a coefficient >= 0, a limit > 0
    or None, a flag a bool), naming the field."""
    bad = {"coefficient": -1.0, "limit": 0.0, "flag": 1}
    for effect in fx.EFFECTS:
        with pytest.raises(ValueError, match=f"Scene.{effect.scene_field} "):
            Scene(**{effect.scene_field: bad[effect.switch]})
    names = {f.name for f in dataclasses.fields(Scene)}
    assert {e.scene_field for e in fx.EFFECTS} <= names


def test_table_variables_exist():
    for effect in fx.EFFECTS:
        for out, names in effect.variables:
            if out != "trajectory":
                assert set(names) <= set(RESULTS)


def test_closed_form_variables_are_the_batch_rows_by_name():
    """The closed form's variables and the batch kernel's rows are named, not counted."""
    assert CLOSED_FORM[0] == "orbit_class"
    assert CLOSED_FORM[1:] == BATCH_ROWS[: len(CLOSED_FORM) - 1]
    assert set(CLOSED_FORM) <= set(RESULTS)

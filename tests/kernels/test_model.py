"""The model interface (engine.kernels.model) and the layouts it rests on (engine.kernels.layouts):
the registry's checks, the parameter array's derived size and slots, the model id inside the
``effects`` literal, and the dispatch to the model's own kernels."""

import math

import numba
import numpy as np
import pytest
from numba.core import errors

from engine.kernels import cone, cone_starts, layouts, model
from engine.kernels.effects import EFFECTS
from engine.scene import Scene


def test_parameter_array_size_is_derived_from_the_declared_slots():
    """N_PARAMS is the shared and effect slots plus the largest model's own: nothing to keep by
    hand (a forgotten N_PARAMS once let make_params write past the array)."""
    effect_slots = [s for e in EFFECTS for s in e.params]
    assert layouts.MODEL_BASE == len(layouts.SHARED_SLOTS) + len(effect_slots)
    assert model.N_PARAMS == layouts.MODEL_BASE + max(len(m.physics.SLOTS) for m in model.MODELS)
    scene = Scene(rim=2.0, mu=0.3, c_rr=0.01)
    p = scene.params(0.7)
    assert p.shape == (model.N_PARAMS,)
    for e in EFFECTS:  # each effect's slot holds its Scene field's value
        for slot in e.params:
            assert p[layouts.SLOTS[slot]] == getattr(scene, e.scene_field)


def test_slots_are_unique_and_model_slots_follow_the_shared_ones():
    assert len(set(layouts.SLOTS.values())) == len(layouts.SLOTS)
    assert cone.P_ALPHA == layouts.MODEL_BASE
    with pytest.raises(ValueError, match="twice"):
        layouts.model_slots(("a", "b", "a"))


def test_a_model_row_that_breaks_the_rules_fails_at_import():
    """The registry's check (run at import) refuses a wrong id, an undeclared capability and a
    lack without its reason."""
    caps = tuple(model.MODEL_CAPABILITIES)
    bad_rows = [
        (model.Model("cone", 1, cone, cone_starts, caps, ()), "id 1 must be its position 0"),
        (model.Model("cone", 0, cone, cone_starts, caps[1:], ()), "must declare each"),
        (model.Model("cone", 0, cone, cone_starts, caps[1:], ((caps[0], " "),)), "reason"),
    ]
    for row, message in bad_rows:
        with pytest.raises(ValueError, match=message):
            model.check_models((row,))
    with pytest.raises(ValueError, match="unique"):
        model.check_models((model.MODELS[0], model.MODELS[0]._replace(id=1)))
    model.check_models(model.MODELS)


def test_scene_key_carries_the_model_above_the_effects():
    key = model.scene_key(3, Scene(c_rr=0.1, rim=1.0).effects_mask)
    assert model.model_of_key(key) == 3
    assert key & ((1 << model.MODEL_SHIFT) - 1) == Scene(c_rr=0.1, rim=1.0).effects_mask
    assert model.scene_key(model.CONE, 5) == 5  # a cone scene's key is its effect bits


@numba.njit
def _motion(effects, y, p):
    return model.motion_rates(y[0], y[2], y[3], y[4], p, numba.literally(effects))


def test_the_interface_calls_the_models_own_kernel():
    """Through the interface, the cone's rates are the cone's own, bit for bit."""
    p = Scene(c_rr=0.05).params(0.8)
    y = np.array([1.3, 0.2, 0.4, -0.7, 1.1])
    for effects in (0, model.ROLLING_RESISTANCE):
        got = _motion(effects, y, p)
        want = cone.motion_rates(y[0], y[2], y[3], y[4], p, effects)
        assert got == want


def test_an_unknown_model_id_is_a_compile_error():
    p = Scene().params(0.8)
    y = np.array([1.3, 0.2, 0.4, -0.7, 1.1])
    with pytest.raises(errors.TypingError, match="no model with id 7"):
        _motion(model.scene_key(7, 0), y, p)


def test_make_params_fills_the_shared_slots():
    p = model.make_params(2.0, 3.0, 0.5, 0.05, np.array([layouts.P_MU]), np.array([0.2]))
    assert p[layouts.P_M] == 2.0 and p[layouts.P_G] == 3.0 and p[layouts.P_K] == 0.5
    assert p[layouts.P_KK] == 0.5 / 1.5 and p[layouts.P_INV_M1K] == 1.0 / (2.0 * 1.5)
    assert p[layouts.P_R_VERTEX] == model.VERTEX_FRACTION * 0.05
    assert p[layouts.P_MU] == 0.2 and p[layouts.P_RIM] == math.inf
    assert p[layouts.P_THETA_MAX] == math.inf and p[layouts.P_V_REST] == 0.0

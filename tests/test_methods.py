"""The method registry (engine.methods): kernel ids checked at import, and what a method needs of
a model (engine.kernels.model), refused with the model's reasons."""

import pytest

from engine.kernels import orbit
from engine.kernels.model import MODELS
from engine.kernels.tableaux import RK_TABLEAUX
from engine.methods import METHODS, MODEL_BY_NAME, Method, check_kernel_ids, check_model
from engine.scene import Scene


def test_kernel_ids_are_checked():
    """A duplicate id, an id no run kernel has, and a non-Runge-Kutta id among the pairs'
    positions each fail loudly (today's registry passes)."""
    check_kernel_ids(METHODS)
    orbit.check_kernel_ids(orbit.RUN_KERNELS, len(RK_TABLEAUX))
    rk = METHODS["rk45"]
    with pytest.raises(ValueError, match="share kernel id"):
        check_kernel_ids({**METHODS, "twin": Method("twin", rk.kernel_id, "runge-kutta", "t",
                                                    rk.supports)})  # fmt: skip
    with pytest.raises(ValueError, match="names no run kernel"):
        check_kernel_ids({"stray": Method("stray", 57, "splitting", "s", rk.supports)})
    with pytest.raises(ValueError, match="names no run kernel"):  # a pair's id, not a pair
        check_kernel_ids({"low": Method("low", 0, "splitting", "l", rk.supports)})
    with pytest.raises(ValueError, match=">= 100"):
        orbit.check_kernel_ids({3: None}, len(RK_TABLEAUX))
    with pytest.raises(ValueError, match="reach the other kernels"):
        orbit.check_kernel_ids({}, 101)


def test_methods_refuse_a_model_that_lacks_what_they_need():
    """On a surface the closed form serves (Routh's reduction), the symplectic method does not
    (no separable split), the Runge-Kutta pairs do; a sliding scene is served in one launch's
    story (the sliding model), not in maps or sampled trajectories (they need "sliding
    maps")."""
    surface = MODEL_BY_NAME["surface"]
    for name in ("exact", "rk45", "dop853"):
        check_model(METHODS[name], surface)
    with pytest.raises(ValueError, match="separable split") as err:
        check_model(METHODS["symplectic"], surface)
    assert "methods that can: exact, rk45, dop853" in str(err.value)
    sliding = Scene(mu=0.5, mu_k=0.4)
    with pytest.raises(ValueError, match="sliding maps: on a surface one launch's story"):
        check_model(METHODS["rk45"], surface, sliding)
    check_model(METHODS["rk45"], surface, sliding, story=True)
    with pytest.raises(ValueError, match="separable split"):
        check_model(METHODS["symplectic"], surface, sliding, story=True)
    for method in METHODS.values():  # the cone offers everything
        check_model(method, MODELS[0], sliding)

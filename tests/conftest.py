import os
import sys

sys.path.insert(0, os.path.dirname(__file__))

from hypothesis import settings  # noqa: E402

# The suite draws the same examples on every run (a red CI run is reproducible as it stands);
# HYPOTHESIS_PROFILE=explore draws fresh ones each run to hunt for new failures.
settings.register_profile("repeatable", max_examples=60, deadline=None, derandomize=True)
settings.register_profile("explore", max_examples=60, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))

#: Tests left out of the inner loop (``pytest -m "not slow"``, CONTRIBUTING.md): they compile
#: kernels for effect sets no other test uses, run copies of the package or of the scripts in
#: fresh interpreters, start dask clusters or a browser, or fill a disk. Files, or file::test.
SLOW = {
    "test_recipes.py",
    "test_scripts.py",
    "test_jit_cache.py",
    "test_architecture.py::test_recipe_new_runge_kutta_pair",
    "test_dask.py",
    "test_attacks.py",
    "test_enospc.py",
    "test_package_writes.py",
    "test_report_browser.py",
}


def pytest_collection_modifyitems(config, items):
    import pytest

    for item in items:
        name = item.path.name
        if name in SLOW or f"{name}::{item.originalname}" in SLOW:
            item.add_marker(pytest.mark.slow)

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
    "test_surface_oracle.py::test_reduction_on_the_cone_meets_every_shared_case",
    "test_surface_oracle.py::test_stored_reference_every_case",
}


#: Files whose tests take longest (``--durations=0``, summed per file), longest first. With
#: ``-n 2 --dist loadfile`` each file runs whole on one worker, and the workers take files in
#: the collection's order (``--no-loadscope-reorder`` in pyproject.toml; xdist's own order, by
#: number of tests, put these few-test files last, so the suite ended with one of them running
#: alone). They start first; the other files follow, most tests first, and fill the gaps.
#: test_scripts.py runs each script in a fresh interpreter, which loads from the compile cache
#: the kernels the files before it compiled (on an empty cache, minutes of compiling): it comes
#: after the files that compile the kernels its scripts' smoke runs use (the fate and hybrid
#: maps of test_fates, test_lanes_fate, test_lanes_hybrid and test_hybrid, the period maps of
#: test_lanes and test_integrated).
LONGEST_FIRST = (
    "test_hybrid.py",
    "test_dask.py",
    "test_fates.py",
    "test_lanes_fate.py",
    "test_lanes_hybrid.py",
    "test_simulate.py",
    "test_lanes.py",
    "test_recipes.py",
    "test_architecture.py",
    "test_integrated.py",
    "test_attacks.py",
    "test_interrupt_after_complete.py",
    "test_runner.py",
    "test_scripts.py",
    "test_report.py",
    "test_message_edges.py",
)


def pytest_collection_modifyitems(config, items):
    import pytest

    for item in items:
        name = item.path.name
        if name in SLOW or f"{name}::{item.originalname}" in SLOW:
            item.add_marker(pytest.mark.slow)
    per_file: dict = {}
    for item in items:
        per_file.setdefault(item.path, []).append(item)

    def rank(path):
        if path.name in LONGEST_FIRST:
            return (0, LONGEST_FIRST.index(path.name))
        return (1, -len(per_file[path]))

    items[:] = [item for path in sorted(per_file, key=rank) for item in per_file[path]]

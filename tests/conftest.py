import os
import sys

sys.path.insert(0, os.path.dirname(__file__))

from hypothesis import settings  # noqa: E402

# The suite draws the same examples on every run (a red CI run is reproducible as it stands);
# HYPOTHESIS_PROFILE=explore draws fresh ones each run to hunt for new failures.
settings.register_profile("repeatable", max_examples=60, deadline=None, derandomize=True)
settings.register_profile("explore", max_examples=60, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))

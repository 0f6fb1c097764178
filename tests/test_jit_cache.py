"""The compile cache (engine/_jit.py) is keyed per entry point on what it compiles: two installs
of the same source at different paths share it; a docstring, a moved line or a change in a
kernel the entry point does not call keeps it; a change in a kernel it calls does not."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "engine"

#: Compile (or load) cone.coefficients, which calls cone.coefficients_sc; print (hits, misses).
PROBE = """
from engine.kernels import cone
A, B, C = cone.coefficients(0.5, 1.0, 1.0, 1.0, 9.81, 0.4)
st = cone.coefficients.stats
print(sum(st.cache_hits.values()), sum(st.cache_misses.values()), repr(C))
"""


def _copy(dest: Path) -> Path:
    shutil.copytree(PKG, dest / "engine", ignore=shutil.ignore_patterns("__pycache__"))
    return dest / "engine" / "kernels" / "cone.py"


def _probe(where: Path, cache: Path) -> tuple[int, int, str]:
    env = dict(os.environ, PYTHONPATH=str(where), CONESURVEY_CACHE_DIR=str(cache))
    env.pop("CONESURVEY_NO_CACHE", None)
    res = subprocess.run(
        [sys.executable, "-c", PROBE], env=env, cwd=where, capture_output=True, text=True
    )
    assert res.returncode == 0, res.stderr[-3000:]
    hits, misses, c = res.stdout.split()
    return int(hits), int(misses), c


def _edit(path: Path, old: str, new: str) -> None:
    src = path.read_text()
    assert src.count(old) == 1, old
    path.write_text(src.replace(old, new))


def test_cache_is_shared_by_content_and_keyed_on_what_an_entry_point_compiles(tmp_path):
    cache = tmp_path / "cache"
    a, b = tmp_path / "a", tmp_path / "site-packages"
    _copy(a)
    model_b = _copy(b)
    assert _probe(a, cache)[:2] == (0, 1)  # compiled
    assert _probe(b, cache)[:2] == (1, 0)  # the same source installed elsewhere: loaded
    # A docstring of the callee, a line moved (every line below shifts) and an unrelated kernel.
    _edit(model_b, "(arithmetic only).", "(arithmetic only; edited).")
    _edit(model_b, "\nimport math\n", "\n# a comment\n\nimport math\n")
    _edit(model_b, "return A / (r * r) + B / r + C * r", "return A / (r * r) + B / r + r * C")
    hits, misses, old = _probe(b, cache)
    assert (hits, misses) == (1, 0)
    # The callee's code: the caller is compiled again, and computes the new formula.
    _edit(model_b, "    C = M * g * c / (1.0 + k)", "    C = 2.0 * M * g * c / (1.0 + k)")
    hits, misses, new = _probe(b, cache)
    assert (hits, misses) == (0, 1)
    assert float(new) == 2.0 * float(old)


def test_a_literal_is_named_by_a_parameter_the_kernel_has():
    """call_specialized reads the literal arguments' places from the kernel's signature: a name
    the kernel lacks is an error before anything is called."""
    from engine._jit import call_specialized
    from engine.kernels.trajectory import solve_restarting

    with pytest.raises(TypeError, match="solve_restarting has no parameter 'methd'"):
        call_specialized(solve_restarting, (), ("methd", "effects"))


#: Write an index for cone.coefficients that names a class the package has not (as an index
#: written by another version of the package can), then compile (or load) it; print (hits,
#: misses, C) and whether the index is readable afterwards.
STALE = """
import pickle
from engine.kernels import cone
index = cone.coefficients._cache._cache_file
with open(index._index_path, "wb") as f:
    pickle.dump(index._version, f)
    f.write(b"(S'stamp'\\ncengine.kernels.geometry\\nFamily\\ntp0\\n.")
A, B, C = cone.coefficients(0.5, 1.0, 1.0, 1.0, 9.81, 0.4)
st = cone.coefficients.stats
with open(index._index_path, "rb") as f:
    pickle.load(f)
    pickle.loads(f.read())
print(sum(st.cache_hits.values()), sum(st.cache_misses.values()), repr(C))
"""


def test_an_index_this_version_cannot_read_is_a_cache_miss(tmp_path):
    """An index naming a class this version has not (``engine.kernels.geometry.Family``, a
    named tuple an earlier version pickled into its indexes) is not an error: the kernel is
    compiled again, gives the value the probe gives, and its index is written anew, readable."""
    env = dict(os.environ, CONESURVEY_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("CONESURVEY_NO_CACHE", None)
    res = subprocess.run(
        [sys.executable, "-c", STALE], env=env, cwd=ROOT, capture_output=True, text=True
    )
    assert res.returncode == 0, res.stderr[-3000:]
    hits, misses, c = res.stdout.split()
    assert (int(hits), int(misses)) == (0, 1)
    assert c == _probe(ROOT, tmp_path / "cache")[2]

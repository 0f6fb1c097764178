"""The shape of the package (docs/architecture.md): layers, no import circles, no hidden
function-level imports, modules of a readable size; and the recipe "a new Runge-Kutta pair is one
Tableau in kernels/tableaux.py", done once on a copy of the package."""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from cases import CASES
from runs import copy_cache

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "engine"
#: Function-level imports of package modules that are allowed, with the reason.
LAZY_ALLOWED: dict[str, str] = {}
#: Longest module, in lines, for a new module (the house's "~400").
MAX_LINES = 400
#: The ratchet: modules longer than MAX_LINES when the hard cap became this ratchet, with their
#: length then. They may shrink (then lower the number here), never grow.
LONGER: dict[str, int] = {
    "engine/kernels/tableaux.py": 407,
}


def _modules() -> dict[str, Path]:
    out = {}
    for path in PKG.rglob("*.py"):
        rel = path.relative_to(ROOT).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _resolve(module: str, node: ast.ImportFrom | ast.Import, is_pkg: bool) -> list[str]:
    """Absolute names of the engine modules an import statement refers to."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name.split(".")[0] == "engine"]
    base = module.split(".")
    if node.level:
        base = base if is_pkg else base[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    if target.split(".")[0] != "engine":
        return []
    return [target] + [f"{target}.{a.name}" for a in node.names]


def _imports() -> tuple[dict[str, set[str]], list[tuple[str, int, str]]]:
    """Module-level import graph between engine modules, and the function-level imports."""
    mods = _modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    lazy = []
    for name, path in mods.items():
        tree = ast.parse(path.read_text())
        is_pkg = path.name == "__init__.py"
        top = set(tree.body)
        for node in ast.walk(tree):
            if not isinstance(node, ast.Import | ast.ImportFrom):
                continue
            targets = [t for t in _resolve(name, node, is_pkg) if t in mods and t != name]
            in_type_checking = any(
                isinstance(p, ast.If) and "TYPE_CHECKING" in ast.unparse(p.test)
                for p in tree.body
                if node in ast.walk(p) and p is not node
            )
            if in_type_checking:
                continue
            if node in top:
                graph[name].update(targets)
            elif targets:
                lazy.append((name, node.lineno, targets[0]))
    return graph, lazy


def test_no_import_circles():
    graph, _ = _imports()
    state: dict[str, int] = {}

    def visit(m: str, stack: list[str]) -> None:
        state[m] = 1
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                cycle = stack[stack.index(n) :] + [n] if n in stack else [m, n]
                pytest.fail("import circle: " + " -> ".join(cycle))
            if n not in state:
                visit(n, stack + [n])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])


def test_kernels_import_nothing_above_them():
    graph, _ = _imports()
    for m, deps in graph.items():
        if m.startswith("engine.kernels"):
            above = {d for d in deps if not d.startswith("engine.kernels") and d != "engine._jit"}
            assert not above, f"{m} imports {sorted(above)}"


def test_no_function_level_imports_of_package_modules():
    _, lazy = _imports()
    unexplained = [x for x in lazy if f"{x[0]}:{x[2]}" not in LAZY_ALLOWED]
    assert not unexplained, unexplained


def test_modules_stay_readable():
    """No module grows past MAX_LINES, or past its recorded length if it was longer (a ratchet:
    a module that shrank records its new length)."""
    lengths = {
        str(p.relative_to(ROOT)): len(p.read_text().splitlines()) for p in _modules().values()
    }
    grown = {m: n for m, n in lengths.items() if n > LONGER.get(m, MAX_LINES)}
    assert not grown, f"modules past their length (split them, or shorten): {grown}"
    shrunk = {m: (cap, lengths.get(m)) for m, cap in LONGER.items() if lengths.get(m) != cap}
    assert not shrunk, f"lower (or drop) the ratchet's entries: {shrunk}"


def _private_imports() -> list[str]:
    """``from engine.x import _name`` anywhere in the package (a module's private name used by
    another module)."""
    found = []
    mods = _modules()
    for name, path in mods.items():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom) or not _resolve(name, node, False):
                continue
            for alias in node.names:
                target = _resolve(name, node, path.name == "__init__.py")[0]
                is_module = f"{target}.{alias.name}" in mods
                dunder = alias.name.startswith("__") and alias.name.endswith("__")
                if alias.name.startswith("_") and not (is_module or dunder):
                    found.append(f"{name}:{node.lineno} imports {target}.{alias.name}")
    return found


def test_no_module_imports_another_modules_private_names():
    assert not _private_imports()


# --- the recipe: a new Runge-Kutta pair ----------------------------------------------------------
#: Bogacki-Shampine 3(2) with its cubic Hermite dense output, as a Tableau (the recipe's input).
BS32 = """
_BS_A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0],
        [0.5, 0.0, 0.0, 0.0],
        [0.0, 0.75, 0.0, 0.0],
        [2 / 9, 1 / 3, 4 / 9, 0.0],
    ]
)
RK_TABLEAUX = RK_TABLEAUX + (
    Tableau(
        name="bs32",
        title="Bogacki-Shampine 3(2)",
        A=_BS_A,
        C=np.array([0.0, 0.5, 0.75, 1.0]),
        E=np.array([2 / 9 - 7 / 24, 1 / 3 - 1 / 4, 4 / 9 - 1 / 3, -1 / 8]),
        E3=np.zeros(4),
        P=np.array(
            [
                [1.0, -4 / 3, 5 / 9],
                [0.0, 1.0, -2 / 3],
                [0.0, 4 / 3, -8 / 9],
                [0.0, -1.0, 1.0],
            ]
        ),
        n_stages=3,
        order=3,
        error_order=2,
        beta=0.0,
        beta_weight=0.0,
        unroll=True,
    ),
)
"""

CHECK = """
import sys, engine
from engine.surveyfile import parse_survey
assert "bs32" in engine.METHODS, list(engine.METHODS)
m = engine.METHODS["bs32"]
assert m.family == "runge-kutta" and m.integrates
alpha, energy, h, Lz, period, tol = map(float, sys.argv[1:])
tr = engine.simulate(alpha, energy, h, Lz, method="bs32", rtol=1e-9, periods=1)
assert int(tr.event_kind[-1]) == 0, tr.event_kind.values  # back at the pericentre
rel = abs(float(tr.event_time[-1]) / period - 1)
assert rel < tol, rel
s = parse_survey('method = "bs32"\\n[axes.alpha]\\nvalues=[0.5]\\n[axes.energy]\\nvalues=[20.0]\\n'
                 '[axes.h]\\nvalues=[1.0]\\n[axes.Lz]\\nvalues=[0.8]\\n')
assert s.method == "bs32"
print("ok", rel, tr.time.size)
"""


def test_recipe_new_runge_kutta_pair(tmp_path):
    """Append one Tableau to a copy of kernels/tableaux.py: the method exists in the registry,
    the survey file takes it, and it integrates a period to its tolerance."""
    copy = tmp_path / "engine"
    shutil.copytree(PKG, copy, ignore=shutil.ignore_patterns("__pycache__"))
    tableaux = copy / "kernels" / "tableaux.py"
    tableaux.write_text(tableaux.read_text() + textwrap.dedent(BS32))
    cache = copy_cache(tmp_path, "new-runge-kutta-pair")
    env = dict(os.environ, PYTHONPATH=str(tmp_path), CONESURVEY_CACHE_DIR=str(cache))
    env["NUMBA_NUM_THREADS"] = "1"
    # A reference orbit (40-digit period, the reference data) integrated for one period: the
    # integrators' promise is 100 rtol kappa (tests/cases.py), kappa = max(1, A/r1^2/calE).
    case = next(c for c in CASES if c["id"] == "P001")
    i, aux = case["inputs"], case["aux"]
    kappa = max(1.0, aux["A"] / case["outputs"]["r1"] ** 2 / i["calE"])
    args = [i["alpha"], i["calE"], i["h"], i["Lz"], case["outputs"]["T_r"], 100 * 1e-9 * kappa]
    res = subprocess.run(
        [sys.executable, "-c", CHECK, *map(repr, args)],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    assert res.stdout.startswith("ok")


def test_architecture_doc_lists_every_module():
    """docs/architecture.md (which the README's layout points to) names every module."""
    doc = (ROOT / "docs" / "architecture.md").read_text()
    missing = []
    for name, path in _modules().items():
        rel = path.relative_to(ROOT / "engine")
        if rel.name == "__init__.py":
            continue
        shown = str(rel)
        if f"`{shown}`" not in doc and f"engine/{shown}" not in doc:
            missing.append(name)
    assert not missing, missing

"""The shape of the package (docs/architecture.md): layers, no import circles, no hidden
function-level imports, modules of a readable size, each behaviour of the scalar and the lanes
drivers in one function both call; and the recipe "a new Runge-Kutta pair is one
Tableau in kernels/tableaux.py", done once on a copy of the package."""

from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import NamedTuple

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


class Edge(NamedTuple):
    """One import of an engine module by another: ``kind`` is "module" (at module level),
    "annotation" (under ``if TYPE_CHECKING:``, for annotations only), "function" (inside a
    function) or "string" (a module named by a string: ``importlib.import_module(".x", ...)``,
    ``_lazy(".x", name)``)."""

    source: str
    target: str
    kind: str
    line: int


#: Calls that import the module their first argument names (a string literal).
STRING_IMPORTS = ("import_module", "_lazy")


def _under_type_checking(tree: ast.Module) -> set[ast.AST]:
    """The import statements under an ``if TYPE_CHECKING:`` of the module's top level."""
    out: set[ast.AST] = set()
    for node in tree.body:
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            out.update(n for n in ast.walk(node) if isinstance(n, ast.Import | ast.ImportFrom))
    return out


def _string_import(name: str, node: ast.Call, is_pkg: bool) -> list[str]:
    func = node.func
    called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
    if called not in STRING_IMPORTS or not node.args:
        return []
    arg = node.args[0]
    if not isinstance(arg, ast.Constant) or not isinstance(arg.value, str):
        return []
    text = arg.value
    level = len(text) - len(text.lstrip("."))
    fake = ast.ImportFrom(module=text[level:] or None, names=[], level=level)
    return _resolve(name, fake, is_pkg)


def _edges() -> list[Edge]:
    """Every import between engine modules, of every kind."""
    mods = _modules()
    edges = []
    for name, path in mods.items():
        tree = ast.parse(path.read_text())
        is_pkg = path.name == "__init__.py"
        top = set(tree.body)
        typing_only = _under_type_checking(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                for t in _string_import(name, node, is_pkg):
                    if t in mods and t != name:
                        edges.append(Edge(name, t, "string", node.lineno))
                continue
            if not isinstance(node, ast.Import | ast.ImportFrom):
                continue
            kind = "annotation" if node in typing_only else "module" if node in top else "function"
            for t in _resolve(name, node, is_pkg):
                if t in mods and t != name:
                    edges.append(Edge(name, t, kind, node.lineno))
    return edges


def _imports() -> tuple[dict[str, set[str]], list[tuple[str, int, str]]]:
    """The import graph between engine modules (at module level, annotation-only and inside
    functions: every import a reader of the code follows), and the function-level imports."""
    graph: dict[str, set[str]] = {m: set() for m in _modules()}
    lazy = []
    for e in _edges():
        if e.kind == "string":  # deferred by name (a registry's rows): layers, not circles
            continue
        graph[e.source].add(e.target)
        if e.kind == "function":
            lazy.append((e.source, e.line, e.target))
    return graph, lazy


def _circle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph``, or None."""
    state: dict[str, int] = {}

    def visit(m: str, stack: list[str]) -> list[str] | None:
        state[m] = 1
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                return stack[stack.index(n) :] + [n]
            if n not in state and (found := visit(n, stack + [n])):
                return found
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (found := visit(m, [m])):
            return found
    return None


def test_no_import_circles():
    """No circle among the imports, annotation-only ones (``if TYPE_CHECKING:``) counted."""
    circle = _circle(_imports()[0])
    assert circle is None, "import circle: " + " -> ".join(circle or [])


def test_the_circle_check_sees_annotation_imports():
    """The check itself: an import under ``if TYPE_CHECKING:`` is one, and closes a circle."""
    src = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .a import X\n"
    tree = ast.parse(src)
    (node,) = _under_type_checking(tree)
    assert _resolve("engine.b", node, False)[0] == "engine.a"
    assert _circle({"engine.a": {"engine.b"}, "engine.b": set()}) is None
    circle = _circle({"engine.a": {"engine.b"}, "engine.b": {"engine.a"}})
    assert circle == ["engine.a", "engine.b", "engine.a"]


def _annotation_names(tree: ast.Module) -> list[tuple[str, int]]:
    """The names an annotation of the module starts with (``np`` of ``np.ndarray``), string
    annotations and those that ``from __future__ import annotations`` leaves unevaluated
    included."""
    found = []

    def names(expr: ast.expr | None) -> None:
        if expr is None:
            return
        for n in ast.walk(expr):
            if isinstance(n, ast.Constant) and isinstance(n.value, str):
                try:
                    names(ast.parse(n.value, mode="eval").body)
                except SyntaxError:  # a Literal["..."] member, not an annotation
                    pass
            elif isinstance(n, ast.Name):
                found.append((n.id, expr.lineno))

    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            a = node.args
            for arg in (*a.posonlyargs, *a.args, *a.kwonlyargs, a.vararg, a.kwarg):
                if arg is not None:
                    names(arg.annotation)
            names(node.returns)
        elif isinstance(node, ast.AnnAssign):
            names(node.annotation)
    return found


def _bound_names(tree: ast.Module) -> set[str]:
    """Names a module binds anywhere (imports, also under TYPE_CHECKING; definitions;
    assignments), and the builtins."""
    bound = set(dir(__builtins__) if isinstance(__builtins__, dict) is False else __builtins__)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            bound.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            bound.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            bound.add(node.id)
    return bound


def test_every_annotation_names_an_import():
    """An annotation may name only what its module imports or defines: a name that
    ``from __future__ import annotations`` leaves unevaluated is a dependency too, and the
    layer and circle checks see it only as an import."""
    unbound = []
    for name, path in _modules().items():
        tree = ast.parse(path.read_text())
        bound = _bound_names(tree)
        unbound += [f"{name}:{line} {n}" for n, line in _annotation_names(tree) if n not in bound]
    assert not unbound, unbound


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


# --- the layers, read from the diagram of docs/architecture.md ---------------------------------
DOC = ROOT / "docs" / "architecture.md"
#: A path the diagram names: a module (``engine/x.py``) or a package (``engine/io/``).
LISTED = re.compile(r"engine/(?:[\w]+/)*(?:[\w]+\.py)?")


def _diagram(text: str) -> list[tuple[str, list[str]]]:
    """The layers of the doc's diagram (its first fenced block), top layer first: (label, the
    paths listed in it). A line indented by two spaces opens a layer; deeper lines go on."""
    block = re.search(r"^```\n(.*?)^```", text, flags=re.S | re.M)
    assert block, "docs/architecture.md has no layer diagram"
    layers: list[tuple[str, list[str]]] = []
    for line in block.group(1).splitlines():
        if not line.strip():
            continue
        if line.startswith("  ") and not line.startswith("   "):
            label, _, rest = line.strip().partition(" ")
            layers.append((label, []))
        else:
            rest = line
        layers[-1][1].extend(LISTED.findall(rest.split("(")[0]))
    return layers


def _layer_of(layers: list[tuple[str, list[str]]]) -> dict[str, tuple[int, str]]:
    """Each module of engine/ -> (its height, 0 = bottom; the layer's label), from the listing:
    a module named in the diagram, else the innermost package named that holds it."""
    height = {label: len(layers) - 1 - i for i, (label, _) in enumerate(layers)}
    files, packages = {}, {}
    for label, paths in layers:
        for p in paths:
            where = packages if p.endswith("/") else files
            assert p not in where, f"{p} is listed twice in the diagram"
            where[p] = label
    out = {}
    for name, path in _modules().items():
        rel = str(path.relative_to(ROOT))
        if rel in files:
            label = files[rel]
        else:
            holders = [p for p in packages if rel.startswith(p)]
            if not holders:
                continue
            inner = max(holders, key=len)
            label = packages[inner]
            outer = [packages[p] for p in holders if p != inner]
            assert all(o == label for o in outer), f"{rel}: its packages are in {outer + [label]}"
        out[name] = (height[label], label)
    return out


def test_the_diagram_lists_every_module_in_one_layer():
    layers = _diagram(DOC.read_text())
    assert [label for label, _ in layers] == ["edge", "API", "io", "vocabulary", "kernels"]
    named = [p for _, paths in layers for p in paths]
    assert len(named) == len(set(named)), "a path listed twice"
    missing_paths = [p for p in named if not (ROOT / p).exists()]
    assert not missing_paths, f"the diagram lists what is not there: {missing_paths}"
    layer = _layer_of(layers)
    unlisted = sorted(set(_modules()) - set(layer))
    assert not unlisted, f"modules in no layer of the diagram: {unlisted}"


def test_every_import_stays_in_its_layer_or_goes_down():
    """Annotation-only, function-level and by-name imports included."""
    layer = _layer_of(_diagram(DOC.read_text()))
    upward = [
        f"{e.source} ({layer[e.source][1]}) imports {e.target} ({layer[e.target][1]}), "
        f"line {e.line}, {e.kind}"
        for e in _edges()
        if layer[e.target][0] > layer[e.source][0]
    ]
    assert not upward, "\n".join(upward)


def test_the_layer_check_reads_the_diagram():
    """The reading of the diagram: labels, continuation lines, comments and packages."""
    text = (
        "x\n```\n  top         engine/a.py  engine/pkg/\n              engine/b.py\n"
        "  bottom      engine/pkg/c.py   (a comment naming engine/a.py)\n```\n"
    )
    assert _diagram(text) == [
        ("top", ["engine/a.py", "engine/pkg/", "engine/b.py"]),
        ("bottom", ["engine/pkg/c.py"]),
    ]


def test_each_module_is_described_in_its_layers_section():
    """A module's row in docs/architecture.md is in the section of its layer (a heading that
    names the layer: "## The kernels ...", "## The API layer", ...)."""
    text = DOC.read_text()
    labels = [label for label, _ in _diagram(text)]
    layer = _layer_of(_diagram(text))
    sections = re.split(r"^## ", text, flags=re.M)[1:]
    section_of = {}
    for section in sections:
        heading = section.splitlines()[0]
        names = [lab for lab in labels if re.search(rf"\b{re.escape(lab)}\b", heading)]
        if len(names) != 1:
            continue
        for row in re.findall(r"^\|(.*?)\|", section, flags=re.M):
            for rel in re.findall(r"`([\w/]+\.py)`", row):
                section_of.setdefault(rel, names[0])
    wrong = {}
    for name, path in _modules().items():
        rel = str(path.relative_to(PKG))
        if rel.endswith("__init__.py") and rel != "__init__.py":
            continue
        if section_of.get(rel) != layer[name][1]:
            wrong[rel] = (section_of.get(rel), layer[name][1])
    assert not wrong, f"module: (section of its row, its layer): {wrong}"


# --- the storage layer reads the plan through its protocol --------------------------------------
def _plan_reads() -> dict[str, set[str]]:
    """What engine/io/ reads of a plan: the attributes of a name ``plan`` (and of
    ``plan.output``), per protocol."""
    reads: dict[str, set[str]] = {"RunPlan": set(), "OutputPlan": set()}
    for path in (PKG / "io").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.Attribute):
                continue
            if isinstance(node.value, ast.Name) and node.value.id == "plan":
                reads["RunPlan"].add(node.attr)
            elif (
                isinstance(node.value, ast.Attribute)
                and node.value.attr == "output"
                and isinstance(node.value.value, ast.Name)
                and node.value.value.id == "plan"
            ):
                reads["OutputPlan"].add(node.attr)
    return reads


def _members(protocol: type) -> set[str]:
    return {n for n in vars(protocol) if not n.startswith("_")}


def test_io_reads_of_the_plan_are_its_protocols():
    from engine.io import planshape
    from engine.plan import survey_plan
    from engine.schema import DIMS

    reads = _plan_reads()
    assert {"dims", "axis", "variables", "output"} <= reads["RunPlan"]  # the scan finds them
    for name, read in reads.items():
        undeclared = read - _members(getattr(planshape, name))
        assert not undeclared, f"io/ reads {sorted(undeclared)} of a plan; declare them in {name}"
    plan = survey_plan(DIMS, dict(alpha=[0.5], energy=[20.0], h=[1.0], Lz=[0.8]))
    assert isinstance(plan, planshape.RunPlan)
    assert isinstance(plan.output, planshape.OutputPlan)
    for protocol, value in ((planshape.RunPlan, plan), (planshape.OutputPlan, plan.output)):
        for member in _members(protocol):
            declared = vars(protocol)[member]
            got = getattr(value, member)
            assert callable(got) == (not isinstance(declared, property)), member


def test_an_unfinished_runs_plan_is_read_by_the_reader_handed_down(tmp_path):
    """io/results.py imports no survey reader; the package hands it one, and with none it
    says so rather than failing some other way."""
    import engine  # noqa: F401  (the package's import hands the reader down)
    from engine.io import results

    assert results._readers, "engine/__init__.py did not hand io/results.py its reader"
    text = "[axes.alpha]\nvalues = [0.5]\n[axes.energy]\nvalues = [20.0]\n"
    text += "[axes.h]\nvalues = [1.0]\n[axes.Lz]\nvalues = [0.8]\n"
    plan = results._readers[0](text, "t.toml")
    assert plan.dims == ("alpha", "energy", "h", "Lz") and plan.shape == (1, 1, 1, 1)


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


#: The most parameters a kernel function takes: longer lists travel as tuples with named places
#: (kernels/story_parts.L_*, lanes_fate.R_* and OUT_*, lanes_hybrid.ST_* and SC_*).
MAX_PARAMS = 20


def test_no_kernel_function_takes_a_long_positional_list():
    long = []
    for path in sorted((PKG / "kernels").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and len(node.args.args) > MAX_PARAMS:
                long.append(f"{path.name}:{node.name} ({len(node.args.args)} parameters)")
    assert not long, long


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


# --- the scalar and the lanes drivers: each behaviour once --------------------------------------
def _drivers_table() -> list[list[str]]:
    """The rows of docs/architecture.md's table under "The scalar and the lanes drivers"."""
    doc = (ROOT / "docs" / "architecture.md").read_text()
    part = doc.split("**The scalar and the lanes drivers.**", 1)[1]
    rows = []
    for line in part.splitlines():
        if line.startswith("| behaviour") or line.startswith("|---"):
            continue
        if not line.startswith("|"):
            if rows:
                break
            continue
        rows.append([cell.strip() for cell in line.strip("|").split("|")])
    return rows


def _called(ref: str) -> set[str]:
    """The names a kernel function calls (``module.function``: from its AST) or, for a module
    (``module``), every word of its source (its generators write calls into strings)."""
    module, _, function = ref.partition(".")
    source = (PKG / "kernels" / f"{module}.py").read_text()
    if not function:
        return set(re.findall(r"\w+", source))
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef) and node.name == function:
            return {
                call.func.id if isinstance(call.func, ast.Name) else call.func.attr
                for call in ast.walk(node)
                if isinstance(call, ast.Call) and isinstance(call.func, (ast.Name, ast.Attribute))
            }
    raise AssertionError(f"docs/architecture.md names {ref}, which engine/kernels has not")


def test_the_scalar_and_the_lanes_drivers_call_one_description_of_each_behaviour():
    """Each row of the drivers' table: its functions exist, and the scalar callers (together)
    and the lanes' callers (together) call every one of them."""
    rows = _drivers_table()
    assert len(rows) >= 8, rows
    for behaviour, described, scalar, lanes in rows:
        names = re.findall(r"`(\w+)\.(\w+)`", described)
        assert names, behaviour
        for module, function in names:
            source = (PKG / "kernels" / f"{module}.py").read_text()
            assert re.search(rf"^def {function}\(", source, re.M), f"{module}.{function}"
        for side in (scalar, lanes):
            refs = re.findall(r"`([\w.]+)`", side)
            assert refs, (behaviour, side)
            called = set().union(*(_called(ref) for ref in refs))
            missing = [f for _, f in names if f not in called]
            assert not missing, f"{behaviour!r}: {side} does not call {missing}"

"""The documentation's examples and commands work as a new user pastes them.

- Every ```python block of README.md and docs/*.md runs in a fresh interpreter (nothing is
  shared between blocks but the files they write: the blocks of one page run in order, in one
  temporary directory, as a reader following the page would run them). A block immediately
  followed by a ```output block must print exactly that.
- The README's two set-up commands: the first installs the package with the plot extra and
  runs the survey, and every later command of the README reaches the installed
  ``conesurvey`` and reads the file the first one writes; the second is the command CI runs
  (``.ci/run``), character for character.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```\n", flags=re.S | re.M)


def examples(text: str) -> list[tuple[str, str | None]]:
    """The page's ```python blocks, each with the ```output block right after it (or None)."""
    fences = [(m.group(1), m.group(2), m.start(), m.end()) for m in FENCE.finditer(text)]
    found = []
    for i, (lang, body, _, end) in enumerate(fences):
        if lang != "python":
            continue
        expected = None
        if i + 1 < len(fences):
            nlang, nbody, nstart, _ = fences[i + 1]
            if nlang == "output" and not text[end:nstart].strip():
                expected = nbody
        found.append((body, expected))
    return found


def test_examples_are_found_with_their_outputs():
    text = "```python\nprint(1)\n```\n\n```output\n1\n```\ntext\n```python\nx = 2\n```\n"
    assert examples(text) == [("print(1)\n", "1\n"), ("x = 2\n", None)]
    assert examples("```python\nprint(1)\n```\nsome words\n```output\n1\n```\n") == [
        ("print(1)\n", None)
    ]


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_examples_run_standalone(page, tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(ROOT)  # the checkout under test, whatever is installed
    env["MPLBACKEND"] = "Agg"
    for n, (code, expected) in enumerate(examples(page.read_text()), start=1):
        done = subprocess.run(
            [sys.executable, "-c", code],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=900,
        )
        where = f"{page.name}, python block {n}"
        assert done.returncode == 0, f"{where} failed:\n{done.stderr[-3000:]}"
        if expected is not None:
            assert done.stdout == expected, f"{where} printed:\n{done.stdout}"


def _bash_blocks(text: str) -> list[str]:
    return [m.group(2) for m in FENCE.finditer(text) if m.group(1) == "bash"]


def _setup_commands() -> tuple[str, str, list[str]]:
    """The README's main command (its first block), its test command (the block that runs
    pytest) and the other blocks."""
    blocks = _bash_blocks((ROOT / "README.md").read_text())
    tests = [b for b in blocks if "pytest" in b]
    assert len(tests) == 1, "one test command"
    main, test = blocks[0].strip(), tests[0].strip()
    assert "\n" not in main and "\n" not in test, "each set-up command is one line"
    return main, test, [b for b in blocks[1:] if b is not tests[0]]


def test_ci_runs_the_readme_test_command():
    _, tests, _ = _setup_commands()
    ci = [line for line in (ROOT / ".ci" / "run").read_text().splitlines() if line.strip()]
    assert tests in ci, ".ci/run must run the README's test command as written"
    assert "-e '.[test]'" in tests


def test_readme_pastes_top_to_bottom():
    """After command 1 (no venv activated), every later command of the README reaches the
    installed conesurvey, with the extras it needs, and reads the file command 1 wrote."""
    main, _, later = _setup_commands()
    assert ".venv/bin/pip install -q '.[plot]'" in main
    written = re.search(r"conesurvey run (\S+\.toml) -o (\S+\.nc)", main)
    assert written, main
    survey, output = written.groups()
    assert (ROOT / survey).is_file()
    assert later, "the README shows what to do next"
    for block in later:
        for line in block.splitlines():
            line = line.split("#")[0].strip()
            if not line:
                continue
            assert line.startswith(".venv/bin/conesurvey "), line
            for name in re.findall(r"(?<![-\w])[\w.-]+\.nc\b", line):
                assert name == output, f"{line!r} reads {name}; command 1 writes {output}"


def _cells(row: str) -> int:
    """Cells of a Markdown table row: ``|`` separates them unless escaped as ``\\|``."""
    return len(re.split(r"(?<!\\)\|", row.strip().strip("|")))


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_tables_have_as_many_cells_in_each_row_as_in_their_header(page):
    text = FENCE.sub("", page.read_text())  # code blocks hold no tables
    for table in re.findall(r"(?:^\|.*\|\n)+", text, flags=re.M):
        rows = table.splitlines()
        width = _cells(rows[0])
        for row in rows[1:]:
            assert _cells(row) == width, f"{page.name}: an unescaped | in {row!r}"


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_pictures_and_local_links_exist(page):
    for target in re.findall(r"\]\(([^)#]+)\)", page.read_text()):
        if "://" not in target:
            assert (page.parent / target).exists(), f"{page.name} links {target}"

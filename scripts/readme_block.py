"""The README's generated blocks: a benchmark writes its table between two HTML comments
(``<!-- NAME: start -->`` ... ``<!-- NAME: end -->``), so the figures are printed, not typed."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def update_readme(name: str, text: str, readme: Path = README) -> None:
    """Replace the README's block ``name`` by ``text`` (SystemExit if the block is missing)."""
    start, end = f"<!-- {name}: start -->", f"<!-- {name}: end -->"
    src = readme.read_text()
    pat = re.compile(re.escape(start) + ".*?" + re.escape(end), re.S)
    if not pat.search(src):
        raise SystemExit(f"README.md has no {start} ... {end} block")
    readme.write_text(pat.sub(lambda _: f"{start}\n{text}\n{end}", src))

"""The README's Python examples run as written (in order, in one namespace, in a temporary
directory), so the documentation cannot drift from the API."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_readme_python_examples_run(tmp_path, monkeypatch, capsys):
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) >= 2
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, "README.md", "exec"), namespace)  # noqa: S102
    assert (tmp_path / "map.nc").exists()
    assert namespace["fate"].attrs["map_kind"] == "fate"
    assert namespace["launch"].orbit_class.dims == ("alpha", "r0", "v0", "w0")
    assert namespace["traj"].attrs["status"] in (0, 1, 2, 9, 10)  # an end, not a failure

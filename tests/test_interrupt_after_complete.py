"""A Ctrl-C that arrives after the output is complete (issue 19, item 12).

Once the run has renamed its output into place there is nothing to resume: a SIGINT while
the run tidies up or prints its summary must not say "interrupted ... resume". Each case runs
``conesurvey run`` in a subprocess that sends itself a real SIGINT at that moment.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import xarray as xr
from runs import as_in_a_terminal, env, free_fall_survey, here

SCRIPT = textwrap.dedent(
    """
    import os, signal, sys
    import engine.commands.run as run_command
    from engine.io.blocks import BlockStore
    from engine.io.zarrstore import RunStore
    from engine import cli

    def interrupt():
        os.kill(os.getpid(), signal.SIGINT)

    def hooked(original):
        def wrapper(*args, **kwargs):
            interrupt()
            return original(*args, **kwargs)
        return wrapper

    if sys.argv[1] == "tidying":  # the output is renamed into place; the parts are removed next
        BlockStore.remove = hooked(BlockStore.remove)
        RunStore.remove = hooked(RunStore.remove)
    else:
        run_command.print_summary = hooked(run_command.print_summary)
    sys.exit(cli.main(sys.argv[2:]))
    """
)


@pytest.mark.parametrize("moment", ["tidying", "summary"])
@pytest.mark.parametrize("name", ["out.nc", "out.zarr"])
def test_sigint_after_the_output_is_complete_says_so(
    tmp_path: Path, moment: str, name: str, capsys
):
    if name.endswith(".zarr"):
        pytest.importorskip("zarr")
    (tmp_path / "s.toml").write_text(free_fall_survey("after the end"))
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, moment, "run", "s.toml", "-o", name],
        cwd=tmp_path, env=env(), capture_output=True, text=True, timeout=600,
        preexec_fn=as_in_a_terminal,
    )  # fmt: skip
    assert proc.returncode in (0, 130), proc.stderr
    assert "resume" not in proc.stderr.replace("nothing to resume", ""), proc.stderr
    assert f"{name} is complete" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    with xr.open_dataset(tmp_path / name, engine="zarr" if name.endswith(".zarr") else None) as ds:
        assert ds.orbit_class.size == 56
    again = here(tmp_path, capsys, "run", "s.toml", "-o", name)  # in this process: no signal
    assert again.returncode == 0, again.stderr
    assert "already holds this survey, complete" in again.stdout


def test_sigint_before_the_output_is_complete_still_says_resume(tmp_path: Path):
    """The other side: interrupted while blocks are computed, the run is resumable."""
    script = SCRIPT.replace(
        'if sys.argv[1] == "tidying":',
        'if sys.argv[1] == "early":\n'
        "    run_command.run_survey = hooked(run_command.run_survey)\n"
        'elif sys.argv[1] == "tidying":',
    )
    (tmp_path / "s.toml").write_text(free_fall_survey("before the end"))
    proc = subprocess.run(
        [sys.executable, "-c", script, "early", "run", "s.toml", "-o", "out.nc"],
        cwd=tmp_path, env=env(), capture_output=True, text=True, timeout=600,
        preexec_fn=as_in_a_terminal,
    )  # fmt: skip
    assert proc.returncode == 130, proc.stderr
    assert "resume" in proc.stderr, proc.stderr
    assert not (tmp_path / "out.nc").exists()

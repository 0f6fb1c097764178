"""A Ctrl-C while Python imports the package, or while numba loads or compiles a kernel, ends as
any interrupted command: ``conesurvey: error: interrupted ...`` and exit status 130, no
traceback, no output file (engine/commands/interrupts.py, conesurvey_cli.py).

The moments are made exact: each subprocess sends itself a real SIGINT from inside the import of
numba, or from inside llvmlite's object-cache callback while numba compiles (``notify``) or loads
(``getbuffer``) a small cached kernel at the start of the run. Without the fix the first printed
a KeyboardInterrupt traceback (exit -2), the second ended in ``RuntimeError: no compiled object
yet`` (exit 1) and the third lost the Ctrl-C (the run went on to exit 0).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from runs import ROOT, as_in_a_terminal, env, free_fall_survey
from runs import cli as runs_cli

from engine._startup import as_module_command

#: A sitecustomize that sends SIGINT to its own process when the module named by
#: INTERRUPT_AT (numba: inside ``import engine``; engine.commands.run: inside engine/cli.py's
#: own imports, where ``python -m engine.cli`` runs) is first imported.
ON_IMPORT = textwrap.dedent(
    """
    import os, signal, sys

    class Interrupt:
        def find_spec(self, name, path=None, target=None):
            if name == os.environ.get("INTERRUPT_AT"):
                sys.meta_path.remove(self)
                os.kill(os.getpid(), signal.SIGINT)
            return None

    sys.meta_path.insert(0, Interrupt())
    """
)

#: Runs ``conesurvey ARGS`` in process after arming a SIGINT inside llvmlite's object-cache
#: callback ``argv[1]`` while numba compiles or loads ``tiny`` (a cached kernel in ``argv[2]``).
IN_HOOK = textwrap.dedent(
    """
    import os, signal, sys
    from numba.core import codegen

    which, where = sys.argv[1], sys.argv[2]
    name = {"notify": "_object_compiled_hook", "getbuffer": "_object_getbuffer_hook"}[which]
    original = getattr(codegen.JITCodeLibrary, name).__func__
    armed = []

    def hook(cls, *args):
        if armed:
            armed.clear()
            os.kill(os.getpid(), signal.SIGINT)
        return original(cls, *args)

    setattr(codegen.JITCodeLibrary, name, classmethod(hook))
    sys.path.insert(0, where)
    import engine.commands.run as run_command
    from engine import cli

    run_survey = run_command.run_survey

    def compile_then_run(*args, **kwargs):
        import tiny

        armed.append(True)
        tiny.tiny(1.0)
        return run_survey(*args, **kwargs)

    run_command.run_survey = compile_then_run
    sys.exit(cli.main(sys.argv[3:]))
    """
)

TINY = "import numba\n\n@numba.njit(cache=True)\ndef tiny(x):\n    return x + 1.0\n"


def _console_script() -> list[str]:
    script = Path(sys.executable).parent / "conesurvey"
    return [str(script)] if script.exists() else [sys.executable, "-m", "conesurvey_cli"]


def test_console_script_is_the_launcher():
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert 'conesurvey = "conesurvey_cli:main"' in text
    assert 'py-modules = ["conesurvey_cli"]' in text


@pytest.mark.parametrize(
    "launcher, at",
    [
        ("console script", "numba"),
        ("-m engine.cli", "numba"),
        ("-m engine.cli", "engine.commands.run"),
    ],
)
def test_ctrl_c_while_the_package_imports(tmp_path: Path, launcher: str, at: str):
    """The console script and ``python -m engine.cli`` alike (the second printed a
    KeyboardInterrupt traceback and died of the SIGINT)."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(ON_IMPORT)
    (tmp_path / "s.toml").write_text(free_fall_survey("interrupted import"))
    command = _console_script() if launcher == "console script" else runs_cli()
    proc = subprocess.run(
        [*command, "run", "s.toml", "-o", "out.nc"],
        cwd=tmp_path,
        env=env(PYTHONPATH=os.pathsep.join((str(site), str(ROOT))), INTERRUPT_AT=at),
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=as_in_a_terminal,
    )
    assert proc.returncode == 130, proc.stderr[-3000:]
    assert proc.stderr == "conesurvey: error: interrupted; nothing written\n", proc.stderr[-3000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml", "site"]


def test_only_python_m_engine_cli_installs_the_start_up_handler():
    assert as_module_command(["python", "-m", "engine.cli", "run", "s.toml"])
    assert as_module_command(["python", "-X", "importtime", "-W", "ignore", "-mengine.cli"])
    for argv in (
        ["conesurvey", "run", "s.toml"],  # the console script handles its own start
        ["python", "-m", "engine.clix"],
        ["python", "-m", "pytest", "-m", "engine.cli"],
        ["python", "script.py", "-m", "engine.cli"],
        ["python", "-c", "import engine", "-m", "engine.cli"],
        ["python"],
    ):
        assert not as_module_command(argv), argv


@pytest.mark.parametrize("hook", ["notify", "getbuffer"])
def test_ctrl_c_while_numba_compiles_or_loads_a_kernel(tmp_path: Path, hook: str):
    where = tmp_path / "tiny"
    where.mkdir()
    (where / "tiny.py").write_text(TINY)
    run_env = env(NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    if hook == "getbuffer":  # cache it first: the interrupted run loads it
        prime = subprocess.run(
            [sys.executable, "-c", "import tiny; tiny.tiny(1.0)"],
            cwd=where,
            env=run_env,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert prime.returncode == 0, prime.stderr[-3000:]
    (tmp_path / "s.toml").write_text(free_fall_survey("interrupted compile"))
    proc = subprocess.run(
        [sys.executable, "-c", IN_HOOK, hook, str(where), "run", "s.toml", "-o", "out.nc"],
        cwd=tmp_path,
        env=run_env,
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=as_in_a_terminal,
    )
    assert proc.returncode == 130, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr, proc.stderr
    assert proc.stderr.rstrip().endswith(
        "conesurvey: error: interrupted; finished blocks are kept: run the same command again "
        "to resume"
    ), proc.stderr[-3000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["numba-cache", "s.toml", "tiny"]
    leftovers = [p.name for p in (tmp_path / "numba-cache").rglob("*") if ".tmp." in p.name]
    assert leftovers == []


#: Sends itself a SIGINT from code whose exceptions Python swallows (argv[1]: a destructor run by
#: the garbage collector, or a weakref callback), inside interrupts_outside_compile_hooks, then
#: works on for up to 5 s: the Ctrl-C must still end the work.
IN_SWALLOWING_CODE = textwrap.dedent(
    """
    import gc, os, signal, sys, time, weakref
    from engine.commands.interrupts import interrupts_outside_compile_hooks

    class Doomed:
        def __del__(self):
            if sys.argv[1] == "destructor":
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(1000):  # lines for the handler to run at, all in __del__
                    pass

    def callback(ref):
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(1000):
            pass

    try:
        with interrupts_outside_compile_hooks():
            doomed = Doomed()
            doomed.self = doomed  # a cycle: only the garbage collector frees it
            ref = weakref.ref(doomed, callback) if sys.argv[1] == "weakref" else None
            del doomed
            gc.collect()
            end = time.monotonic() + 5.0
            while time.monotonic() < end:
                pass
    except KeyboardInterrupt:
        print("interrupted")
    else:
        print("the Ctrl-C was lost")
    """
)


@pytest.mark.parametrize("where", ["destructor", "weakref"])
def test_ctrl_c_inside_code_that_swallows_exceptions_still_interrupts(where: str):
    """CI saw the compile test above end 0: the SIGINT came while the garbage collector ran
    llvmlite's ``ObjectRef.__del__``, and Python printed the KeyboardInterrupt as "Exception
    ignored" and went on."""
    proc = subprocess.run(
        [sys.executable, "-c", IN_SWALLOWING_CODE, where],
        cwd=ROOT,
        env=env(),
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=as_in_a_terminal,  # SIGINT as a terminal leaves it (an xdist worker ignores it)
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout == "interrupted\n", proc.stderr[-3000:]
    assert "Exception ignored" not in proc.stderr, proc.stderr

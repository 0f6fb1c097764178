"""Input edges of the command line (issue 11): files that are not regular, outputs that are the
survey, texts the output cannot hold, and definitions ``validate`` must refuse like ``run``.

Each case runs the command (in a subprocess where a bug could hang: FIFOs and devices) and
checks the exit status, the one-line message and that nothing was written."""

from __future__ import annotations

import math
import os
import subprocess

import numpy as np
import pytest
import runs

import engine
from engine.checks import PlanError
from engine.story import launch_fates, story

SURVEY = runs.free_fall_survey("edges")


@pytest.fixture
def workdir(tmp_path):
    (tmp_path / "s.toml").write_text(SURVEY)
    return tmp_path


def refused(cwd, *args, timeout=60, capsys=None):
    """Run the command (here if ``capsys``); it must exit 2 with one error line and no
    traceback."""
    proc = (
        runs.run(cwd, *args, timeout=timeout) if capsys is None else runs.here(cwd, capsys, *args)
    )
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    assert proc.stderr.startswith("conesurvey: error: ") and "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1, proc.stderr
    return proc.stderr


@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_device_is_not_read(workdir, command):
    """/dev/zero would be read until memory runs out: refused at once, nothing written."""
    err = refused(workdir, command, "/dev/zero", timeout=30)
    assert "/dev/zero is a device" in err
    assert runs.listing(workdir) == ["s.toml"]


@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_fifo_does_not_hang(workdir, command):
    os.mkfifo(workdir / "pipe.toml")
    err = refused(workdir, command, "pipe.toml", "-q" if command == "run" else "--", timeout=30)
    assert "pipe.toml is a FIFO" in err
    assert runs.listing(workdir) == ["pipe.toml", "s.toml"]


def test_an_oversized_file_is_refused_after_reading_its_cap(workdir, capsys):
    (workdir / "big.toml").write_text(SURVEY + "#" * (5 << 20) + "\n")
    err = refused(workdir, "validate", "big.toml", capsys=capsys)
    assert "big.toml: larger than 4 MiB" in err


@pytest.mark.parametrize("spelling", ["s.nc", "./sub/../s.nc", "link.nc", "hard.nc"])
def test_the_output_may_not_be_the_survey_file(workdir, spelling, capsys):
    """Also with --overwrite, under another spelling, through a link or a hard link (the survey
    file named as an output is: an output's suffix names its format, a .toml is none)."""
    (workdir / "s.toml").rename(workdir / "s.nc")
    (workdir / "sub").mkdir()
    (workdir / "link.nc").symlink_to("s.nc")
    os.link(workdir / "s.nc", workdir / "hard.nc")
    before = runs.listing(workdir)
    err = refused(workdir, "run", "s.nc", "-o", spelling, "--overwrite", "-q", capsys=capsys)
    assert "is the survey file itself" in err
    assert (workdir / "s.nc").read_text() == SURVEY
    assert runs.listing(workdir) == before


def test_a_title_with_nul_is_refused_naming_the_key(workdir, capsys):
    (workdir / "nul.toml").write_text(SURVEY.replace('title = "edges"', 'title = "a\\u0000b"'))
    for command in ("validate", "run"):
        err = refused(workdir, command, "nul.toml", capsys=capsys)
        assert "nul.toml: title: must not contain NUL" in err
    assert runs.listing(workdir) == ["nul.toml", "s.toml"]


def test_validate_refuses_what_run_refuses_and_a_refused_run_leaves_no_debris(workdir, capsys):
    """The issue's case: rk45 with rtol = 0.01 passed validate, run refused it but left
    OUT.parts, and then refused the corrected survey as "another survey"."""
    bad = SURVEY.replace('title = "edges"', 'title = "edges"\nmethod = "rk45"\nrtol = 0.01')
    (workdir / "rk.toml").write_text(bad)
    for command in ("validate", "run"):
        extra = ["-q"] if command == "run" else []
        err = refused(workdir, command, "rk.toml", *extra, capsys=capsys)
        assert "rk.toml: rtol: must lie in [1e-14, 0.001] for the integrator rk45, got 0.01" in err
    assert runs.listing(workdir) == ["rk.toml", "s.toml"]
    (workdir / "rk.toml").write_text(bad.replace("rtol = 0.01", "rtol = 1e-6"))
    ok = runs.here(workdir, capsys, "run", "rk.toml", "-q")
    assert ok.returncode == 0, ok.stderr
    assert runs.listing(workdir) == ["rk.nc", "rk.toml", "s.toml"]


def test_a_method_that_cannot_honour_the_scene_is_refused_by_validate(workdir, capsys):
    text = SURVEY.replace("g = 0.0", "g = 0.0\nc_rr = 1e-3").replace(
        'title = "edges"', 'title = "edges"\nmethod = "symplectic"'
    )
    (workdir / "sy.toml").write_text(text)
    err = refused(workdir, "validate", "sy.toml", capsys=capsys)
    assert "sy.toml: method: method 'symplectic' cannot honour" in err
    assert "the scene's rolling_resistance" in err


@pytest.mark.parametrize(
    "scene, problem",
    [
        ("M = 1e308", "must be at most 1e150"),
        ("M = 5e-324", "must be at least 1e-150: the run divides by it"),
        ("a = 1e308", "must be at most 1e150"),
        ("k = 1e300", "must be at most 1e150"),
    ],
    ids=lambda s: s.split()[0],
)
def test_extreme_scene_values_are_refused_naming_the_key(workdir, scene, problem, capsys):
    """A scene whose numbers a run's arithmetic cannot hold (docs/api.md, "Input bounds"):
    refused by ``run`` and ``validate`` naming the key, nothing written."""
    (workdir / "x.toml").write_text(SURVEY.replace("g = 0.0", f"g = 9.81\n{scene}"))
    key = "scene." + scene.split()[0]
    for command in ("validate", "run"):
        err = refused(workdir, command, "x.toml", capsys=capsys)
        assert f"x.toml: {key}: {problem}" in err, err
    assert runs.listing(workdir) == ["s.toml", "x.toml"]


def test_info_of_a_fifo_or_device_does_not_hang(workdir):
    os.mkfifo(workdir / "out.nc")
    proc = subprocess.run(
        runs.cli("info", "out.nc"),
        cwd=workdir,
        env=runs.env(),
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr


def test_an_output_path_that_is_a_fifo_is_never_replaced(workdir):
    """(A device such as /dev/null is refused the same way: it is not a regular file.)"""
    os.mkfifo(workdir / "out.nc")
    err = refused(workdir, "run", "s.toml", "-o", "out.nc", "--overwrite", "-q", timeout=30)
    assert "out.nc is a FIFO (named pipe); give a file name" in err
    assert runs.listing(workdir) == ["out.nc", "s.toml"]
    assert not (workdir / "out.nc").is_file()


# --- issue 33 item 7: one input check, bounds from the physics (docs/api.md "Input bounds") ---
SLIDING = engine.Scene(mu=0.5, mu_k=0.3)


@pytest.mark.parametrize(
    "call, field",
    [
        (lambda: story(0.5, 1.0, 1.0, 0.0, u0=math.nan, scene=SLIDING, horizon_time=1.0), "u0"),
        (lambda: story(0.5, 1.0, 1.0, 0.0, slip_u=math.inf, scene=SLIDING, horizon_time=1.0),
         "slip_u"),
        (lambda: story(0.5, 1.0, 1.0, 0.0, slip_v=-math.inf, scene=SLIDING, horizon_time=1.0),
         "slip_v"),
        (lambda: engine.simulate(0.5, 20.0, 1.0, 0.8, SLIDING, t_end=1.0, u0=1e300), "u0"),
        (lambda: launch_fates(0.5, 1.0, 1e200, 0.0, scene=SLIDING, horizon_time=1.0), "v0"),
        (lambda: engine.launch_survey([0.5], [1e-200], [1.0], [0.0], method="rk45",
                                      scene=engine.Scene(c_rr=0.01), horizon_time=1.0), "r0"),
        (lambda: engine.launch_survey([1e-160], [1.0], [1.0], [0.0]), "alpha"),
    ],
    ids=["story_nan_u0", "story_inf_slip_u", "story_inf_slip_v", "simulate_u0_1e300",
         "launch_fates_v0_1e200", "launch_survey_r0_1e-200", "launch_survey_alpha_1e-160"],
)  # fmt: skip
def test_a_launch_the_run_cannot_hold_is_refused_naming_the_field(call, field):
    """Before: story ran NaN to ``failed``, simulate(u0=1e300) spent its step budget in 0 s,
    the overflowing launches ended ``no_orbit``. Now each is refused before any kernel runs."""
    with pytest.raises(PlanError) as info:
        call()
    assert info.value.field == field, str(info.value)
    assert str(info.value).startswith(f"{field} "), str(info.value)


def test_a_heavy_scene_is_refused_at_its_bound():
    assert engine.Scene(M=1e150, g=1.0).M == 1e150
    with pytest.raises(ValueError, match=r"^Scene\.M must be at most 1e150 .*got 1\.0000001e\+150"):
        engine.Scene(M=1.0000001e150)
    with pytest.raises(ValueError, match=r"^Scene\.g makes the weight M g = 1\.6e\+150 N"):
        engine.Scene(M=1e75, g=1.6e75)


def test_a_scene_at_the_mass_bound_runs_as_the_unit_scene_bit_for_bit():
    """The bound leaves room: M = 2^494 kg (5e148; its weight 5e149 N), energy and L_z scaled by
    2^494, is the unit-mass orbit exactly (the motion does not depend on M, and a power of two
    scales every product exactly): the same states, steps and times, the energies scaled."""
    big = 2.0**494
    alpha, h, Lz = 0.6, 1.0, 0.5
    energy = 1.5 * float(engine.minimum_energy(alpha, h, Lz))
    one = engine.simulate(alpha, energy, h, Lz, periods=1)
    heavy = engine.simulate(alpha, energy * big, h, Lz * big, engine.Scene(M=big), periods=1)
    assert one.attrs["status"] == heavy.attrs["status"] == 0
    for name in ("time", "r", "theta", "u", "v", "w", "event_time", "event_r"):
        np.testing.assert_array_equal(one[name].values, heavy[name].values, err_msg=name)
    np.testing.assert_array_equal(one.E_drift.values * big, heavy.E_drift.values)
    assert one.attrs["E0"] * big == heavy.attrs["E0"]


def test_a_launch_at_the_speed_bound_is_the_slow_launch_in_fast_time():
    """v0 = 2^249 m/s under g = 2^498 m s-2 (its squared speed 8e149 m2 s-2, at the bound) is the
    launch at 1 m/s under g = 1 m s-2 with time run 2^249 times faster: the same radii and
    angles; period, rate, energy, h, L_z scaled by powers of two, bit for bit (powers of two
    scale every product exactly, as long as nothing over- or underflows). A launch a little
    faster is refused."""
    n = 249
    one = engine.launch_survey([1.0], [1.0], [1.0], [0.0], scene=engine.Scene(g=1.0))
    fast = engine.launch_survey([1.0], [1.0], [2.0**n], [0.0], scene=engine.Scene(g=2.0 ** (2 * n)))
    scale = {"period": 2.0**-n, "precession_rate": 2.0**n, "energy": 2.0 ** (2 * n),
             "h": 2.0**n, "Lz": 2.0**n}  # fmt: skip
    assert one.orbit_class.item() == fast.orbit_class.item() == 1  # bounded
    for name in ("r_min", "r_max", "r_circ", "period", "apsidal_angle", "precession_rate",
                 "mu_required", "energy", "h", "Lz"):  # fmt: skip
        want = one[name].item() * scale.get(name, 1.0)
        assert fast[name].item() == want, name
    with pytest.raises(PlanError, match=r"^v0 makes the launch's squared speed v0\^2 = 1\.1e\+150"):
        engine.launch_survey([1.0], [1.0], [math.sqrt(1.1e150)], [0.0],
                             scene=engine.Scene(g=2.0 ** (2 * n)))  # fmt: skip

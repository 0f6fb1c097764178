"""``conesurvey info``: never a traceback, whatever it is given; ``--verify``; a closed pipe."""

from __future__ import annotations

import json
import subprocess

import netCDF4
import numpy as np
import pytest
import runs

from engine import cli
from engine.runner import run_survey
from engine.surveyfile import parse_survey

SURVEY = runs.free_fall_survey("info test")


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("info") / "r.nc"
    run_survey(parse_survey(SURVEY), out)
    return out


def info(capsys, *args):
    status = cli.main(["info", *map(str, args)])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return status, out, err


def test_a_result_is_complete_and_verifies(result, capsys):
    status, out, _ = info(capsys, result)
    assert status == 0
    assert "  state       complete (not verified: --verify reads every value)" in out
    assert "  survey_fingerprint " in out and "  content_checksum sha256-v1:" in out
    status, out, _ = info(capsys, result, "--verify")
    assert status == 0 and "complete, verified: every value and attribute matches" in out


def _foreign(path, codes, dtype="i1", attrs=None):
    with netCDF4.Dataset(path, "w") as nc:
        nc.setncatts(attrs or {})
        nc.createDimension("x", len(codes))
        v = nc.createVariable("orbit_class", dtype, ("x",))
        v[:] = np.asarray(codes)


@pytest.mark.parametrize(
    ("codes", "dtype", "shown"),
    [
        ([0, 1, 1, -3, 9, 5], "i1", ["other                    2"]),
        ([0, 1, 2], "i8", ["bounded                  1"]),
        ([0.5, np.nan], "f8", ["orbit_class is not an integer array (float64)"]),
    ],
    ids=["odd codes", "int64", "floats"],
)
def test_a_file_of_another_tool_is_described(tmp_path, capsys, codes, dtype, shown):
    _foreign(tmp_path / "f.nc", codes, dtype)
    status, out, _ = info(capsys, tmp_path / "f.nc")
    assert status == 0
    assert "not a finished conesurvey result (no survey fingerprint)" in out
    for text in shown:
        assert text in out, out
    status, out, _ = info(capsys, tmp_path / "f.nc", "--verify")
    assert status == 1


def test_odd_attributes_are_shown_not_crashed_on(tmp_path, capsys):
    _foreign(
        tmp_path / "f.nc",
        [1],
        attrs={"title": np.arange(3), "survey_fingerprint": 7, "history": ""},
    )
    status, out, _ = info(capsys, tmp_path / "f.nc")
    assert status == 0 and "  title       [0 1 2]" in out
    status, out, _ = info(capsys, tmp_path / "f.nc", "--verify")
    assert status == 1 and "DAMAGED: no content checksum recorded" in out


@pytest.mark.parametrize(
    ("content", "shown"),
    [
        (None, "manifest.json is unreadable (missing); the next run removes it and starts over"),
        ("{not json", "unreadable (Expecting property name"),
        ("[]", "unreadable (not a JSON object); run with --overwrite to discard it"),
        (json.dumps({"format": "conesurvey-blocks/2"}), "its checksum does not match"),
    ],
    ids=["bare", "not JSON", "not an object", "no fields"],
)
def test_an_unfinished_run_that_cannot_be_resumed_is_described(tmp_path, capsys, content, shown):
    parts = tmp_path / "o.nc.parts"
    parts.mkdir(mode=0o700)
    if content is not None:
        (parts / "manifest.json").write_text(content)
    status, out, _ = info(capsys, tmp_path / "o.nc")
    assert status == 0
    assert "  state       unfinished, cannot be resumed: " in out and shown in out, out


@pytest.mark.parametrize("text", [b"", b"not netCDF at all", b"\x89HDF\r\n\x1a\n" + b"\0" * 100])
def test_a_file_that_is_not_netcdf_is_exit_2(tmp_path, capsys, text):
    (tmp_path / "x.nc").write_bytes(text)
    status, _, err = info(capsys, tmp_path / "x.nc")
    assert status == 2 and err.startswith("conesurvey: error: ") and "not a readable netCDF" in err


def test_a_flipped_bit_in_a_data_chunk_is_damage(tmp_path, capsys):
    """The file is uncompressed here so that the bytes of r_min can be found and one bit of
    them flipped (compressed chunks that fail to inflate: tests/io/test_contents.py)."""
    path = tmp_path / "r.nc"
    run_survey(parse_survey(SURVEY), path, complevel=0)
    with netCDF4.Dataset(path) as nc:
        values = np.ascontiguousarray(nc.variables["r_min"][...].filled(np.nan), "<f8")
    data = bytearray(path.read_bytes())
    at = data.find(values.tobytes()[:64])
    assert at > 0 and data.find(values.tobytes()[:64], at + 1) == -1
    data[at + 13] ^= 0x01
    path.write_bytes(bytes(data))
    status, out, _ = info(capsys, path)
    assert status == 0 and "state       complete (not verified" in out
    status, out, _ = info(capsys, path, "--verify")
    assert status == 1
    assert "  state       DAMAGED: the contents do not match the recorded checksum" in out


def test_info_into_a_closed_pipe(tmp_path):
    """``conesurvey info OUT.nc | head -1``: the reader goes away; no BrokenPipeError
    traceback, exit status 141 (as a process killed by SIGPIPE)."""
    text = SURVEY + "".join(f"# a long comment, line {i}\n" for i in range(5000))  # > 64 kB
    (tmp_path / "s.toml").write_text(text)
    assert runs.run(tmp_path, "run", "s.toml", "-o", "o.nc", "-q").returncode == 0
    proc = subprocess.Popen(
        runs.cli("info", "o.nc"),
        cwd=tmp_path,
        env=runs.env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert proc.stdout.readline().strip() == b"o.nc"
    proc.stdout.close()  # as head -1 does
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141, err
    assert err == ""

"""engine.io.manifest: the manifest validated as data, and the survey fingerprint."""

from __future__ import annotations

import json
import time

import pytest
import runs

from engine.grid import Tiling
from engine.io import OutputError, manifest
from engine.io.manifest import (
    FORMAT,
    MANIFEST,
    Manifest,
    fingerprint,
    read_manifest,
    write_manifest,
)
from engine.plan import plan_from_survey
from engine.surveyfile import parse_survey

SURVEY = runs.gravity_survey("manifest test", alpha=(0.3, 0.6), energy=5, h=2, lz=3)


@pytest.fixture
def survey():
    return _plan(SURVEY)


def _plan(text):
    return plan_from_survey(parse_survey(text))


@pytest.fixture
def written(tmp_path, survey):
    m = Manifest.new(survey, Tiling(survey.shape, (1, 1, 2, 3), (1, 1, 2, 3)))
    write_manifest(tmp_path, m)
    return m


def test_fingerprint_is_stable_and_sees_every_input(survey, monkeypatch):
    fp = fingerprint(survey)
    assert len(fp) == 64 and fp == fingerprint(_plan(SURVEY))
    variants = [
        SURVEY.replace("manifest test", "other"),
        SURVEY.replace("num = 5", "num = 6"),
        SURVEY.replace("stop = 10.0", "stop = 10.000000000000002"),  # one ulp
        SURVEY.replace("values = [0.3, 0.6]", "values = [0.6, 0.3]"),  # order
        SURVEY.replace('relative_to = "V_min"\n', ""),
        SURVEY + "\n[scene]\ng = 1.62\n",
        'method = "rk45"\n' + SURVEY,
        "rtol = 1e-8\n" + SURVEY,
    ]
    fps = {fingerprint(_plan(text)) for text in variants}
    assert len(fps) == len(variants) and fp not in fps
    monkeypatch.setattr(manifest, "__version__", "9.9.9")
    assert fingerprint(survey) != fp


def test_fingerprint_of_a_ten_million_point_axis_is_cheap():
    """The axes are hashed as bytes: a 1e7-point axis (80 MB) takes well under a second and no
    copy of it (the issue measured 10 s and 1.2 GB for the former list of hex strings)."""
    import tracemalloc

    text = SURVEY.replace("num = 5", "num = 10000000").replace('scale = "log"\n', "")
    big = _plan(text)
    tracemalloc.start()
    t = time.perf_counter()
    fp = fingerprint(big)
    seconds = time.perf_counter() - t
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert len(fp) == 64 and seconds < 1.0, seconds
    assert peak < 1 << 20, peak  # < 1 MB allocated: the 80 MB axis is not copied


def test_manifest_round_trip_and_format(tmp_path, survey, written):
    assert read_manifest(tmp_path) == written
    doc = json.loads((tmp_path / MANIFEST).read_text())
    assert doc["format"] == FORMAT and len(doc["check"]) == 64
    assert doc["shape"] == list(survey.shape) and doc["block"] == [1, 1, 2, 3]
    # the blocks hold the variables on every axis; r_circ and V_min (on (alpha, h, Lz)) are
    # written whole by the writers
    assert doc["variables"] == {
        "orbit_class": "int8",
        **{n: "float64" for n in ("r_min", "r_max", "period", "apsidal_angle")},
        **{n: "float64" for n in ("precession_rate", "mu_required")},
    }
    assert doc["survey_definition"] == SURVEY
    assert written.mismatch(survey) is None
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST]


def _edited(tmp_path, change, *, recheck: bool):
    doc = json.loads((tmp_path / MANIFEST).read_text())
    change(doc)
    if recheck:  # a consistent forgery: only the validation of the data can refuse it
        doc["check"] = manifest._self_check(doc)
    (tmp_path / MANIFEST).write_text(json.dumps(doc))


@pytest.mark.parametrize(
    ("change", "why"),
    [
        (lambda d: d.update(block=[0, 0, 0, 0]), "block must be 4 positive integers"),
        (lambda d: d.update(block=[1, 1, 2]), "block must be 4 positive integers"),
        (lambda d: d.update(shape=[2, 5, 2, True]), "shape must be 4 positive integers"),
        (lambda d: d.update(chunk="1,1,2,3"), "chunk must be 4 positive integers"),
        (lambda d: d.update(block=[1, 1, 2, 4]), "exceeds the grid"),
        (lambda d: d.update(block=[1, 3, 2, 3], chunk=[1, 2, 2, 3]), "not a whole number"),
        (lambda d: d["variables"].update(r_min="float32"), "not a result variable"),
        (lambda d: d["variables"].update(evil="float64"), "not a result variable"),
        (lambda d: d.update(variables={}), "non-empty"),
        (lambda d: d.update(fingerprint="zz"), "not a SHA-256"),
        (lambda d: d.update(engine=None), "must be strings"),
        (lambda d: d.update(format="conesurvey-blocks/1"), "format"),
    ],
)
def test_invalid_manifest_data_is_refused(tmp_path, written, change, why):
    _edited(tmp_path, change, recheck=True)
    with pytest.raises(OutputError, match="manifest.json is unreadable") as info:
        read_manifest(tmp_path)
    assert why in str(info.value)


def test_a_hand_edit_fails_the_self_check(tmp_path, written):
    _edited(tmp_path, lambda d: d.update(shape=[2, 5, 2, 4]), recheck=False)
    with pytest.raises(OutputError, match="checksum does not match"):
        read_manifest(tmp_path)


def test_a_consistent_manifest_of_another_grid_is_a_mismatch(tmp_path, survey, written):
    _edited(tmp_path, lambda d: d.update(shape=[2, 5, 2, 4]), recheck=True)
    m = read_manifest(tmp_path)
    assert "grid [2, 5, 2, 4] is not the survey's [2, 5, 2, 3]" in m.mismatch(survey)


@pytest.mark.parametrize(
    "text", [None, "{not json", '{"fingerprint": "x"}', '{"shape": 3}', "[]", "\xff", "[" * 10**5]
)
def test_unreadable_manifest_is_an_output_error(tmp_path, text):
    if text is not None:
        (tmp_path / MANIFEST).write_bytes(text.encode("utf-8", "surrogateescape"))
    with pytest.raises(OutputError, match="manifest.json is unreadable"):
        read_manifest(tmp_path)


def test_a_manifest_that_is_a_link_is_not_followed(tmp_path, survey, written):
    real = tmp_path / "real.json"
    (tmp_path / MANIFEST).rename(real)
    (tmp_path / MANIFEST).symlink_to(real)
    with pytest.raises(OutputError, match="symbolic link"):
        read_manifest(tmp_path)


def test_writing_the_manifest_never_follows_a_planted_link(tmp_path, survey):
    """Links planted at the old temporary name and at the manifest's own name: the targets
    keep their contents; the manifest replaces the link."""
    target = tmp_path / "victim"
    target.write_bytes(b"precious")
    (tmp_path / (MANIFEST + ".tmp")).symlink_to(target)
    (tmp_path / MANIFEST).symlink_to(target)
    m = Manifest.new(survey, Tiling.for_grid(survey.shape))
    write_manifest(tmp_path, m)
    assert target.read_bytes() == b"precious"
    assert not (tmp_path / MANIFEST).is_symlink() and read_manifest(tmp_path) == m

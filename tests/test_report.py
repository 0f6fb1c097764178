"""``conesurvey report``: the page's content, its escaping, and its numbers against xarray."""

from __future__ import annotations

import base64
import html
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from look_cases import (
    GRAVITY,
    INTEGRATOR,
    check_numbers,
    computed_mask,
    run_file,
    unfinished_run,
)

from engine import cli
from engine.io.results import open_result
from engine.report import build_report


@pytest.fixture(scope="module")
def rk(tmp_path_factory) -> tuple[Path, str]:
    out = run_file(INTEGRATOR, tmp_path_factory.mktemp("report") / "rk.nc")
    with open_result(out) as r:
        return out, build_report(r)


class Page(HTMLParser):
    """Tags with their attributes, the text of every element with a class, and all text."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str]]] = []
        self.rows: list[dict[str, str]] = []  # data-* of <tr> + the text of its classed cells
        self._cell: str | None = None
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = {k: v or "" for k, v in attrs}
        self.tags.append((tag, a))
        if tag == "tr" and any(k.startswith("data-") for k in a):
            self.rows.append(dict(a))
        if tag == "td" and self.rows and "class" in a:
            self._cell = a["class"].split()[-1]
            self.rows[-1][self._cell] = ""

    def handle_endtag(self, tag):
        if tag == "td":
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self.rows[-1][self._cell] += data


def test_numbers_equal_xarray(rk):
    nc, text = rk
    rows = Page(text).rows
    ds = xr.open_dataset(nc)
    flags = len(ds.orbit_class.attrs["flag_meanings"].split())
    flags += len(ds.status.attrs["flag_meanings"].split())
    ranges = len(ds.data_vars) - 2
    assert check_numbers(rows, nc) == flags + ranges


def test_a_map_of_every_variable_and_the_integrator_diagnostics(rk):
    nc, text = rk
    ds = xr.open_dataset(nc)
    imgs = [a for tag, a in Page(text).tags if tag == "img"]
    maps = [a for a in imgs if "data-variable" in a]  # the others: sample orbits
    assert sorted(a["data-variable"] for a in maps) == sorted(ds.data_vars)
    assert len(imgs) > len(maps)
    for a in imgs:
        assert a["src"].startswith("data:image/png;base64,")
        png = base64.b64decode(a["src"].split(",", 1)[1])
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        assert (int(a["width"]), int(a["height"])) == tuple(
            int.from_bytes(png[i : i + 4], "big") for i in (16, 20)
        )
    diag = text[text.index('id="diagnostics"') : text.index('id="maps"')]
    assert 'data-variable="status"' in diag and 'data-variable="energy_drift"' in diag
    assert "fixed at alpha = 0.8 radian (middle value), h = 1 m s-1 (middle value)" in text
    assert "<b>Lz</b> (x) against <b>energy</b> (y)" in text


def test_definition_and_provenance(rk):
    nc, text = rk
    ds = xr.open_dataset(nc)
    shown = re.search(r'<pre id="survey-definition">(.*?)</pre>', text, re.S).group(1)
    assert html.unescape(shown) == INTEGRATOR == ds.attrs["survey_definition"]
    attrs = {a["data-attr"] for tag, a in Page(text).tags if "data-attr" in a}
    for key in ("source", "method", "rtol", "circular_tol", "survey_fingerprint", "scene_g"):
        assert key in attrs
    assert ds.attrs["survey_fingerprint"] in text
    assert html.escape(ds.attrs["history"].splitlines()[0]) in text
    assert "method <code>rk45</code>" in text and '<span class="state-complete">' in text


def test_every_text_is_escaped_and_nothing_is_fetched(rk):
    _, text = rk
    assert "<script" not in text.lower()
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt; &amp; &quot;co&quot;" in text
    for tag, a in Page(text).tags:
        for key in ("src", "href"):
            if key in a:
                assert a[key].startswith(("data:", "#")), (tag, a)
        assert tag not in ("script", "link", "iframe", "object")


def test_unfinished_run_counts_only_computed_points(tmp_path):
    keep = [1, 2, 6, 11]
    out = tmp_path / "part.nc"
    _, full, tiling = unfinished_run(GRAVITY, out, (1, 4, 1, 5), (1, 4, 3, 10), keep)
    mask = computed_mask(tiling, keep)
    with open_result(out) as r:
        text = build_report(r)
    page = Page(text)
    counts = {r["data-flag"]: int(r["data-count"]) for r in page.rows if "data-flag" in r}
    names = full.orbit_class.attrs["flag_meanings"].split()
    want = np.bincount(full.orbit_class.values[mask], minlength=len(names))
    assert counts == dict(zip(names, want.tolist(), strict=True))
    assert f'data-points="{mask.sum()}"' in text
    period = next(r for r in page.rows if r.get("data-variable") == "period")
    v = full.period.values[mask]
    assert float(period["data-min"]) == np.nanmin(v)
    assert int(period["data-nan"]) == np.isnan(v).sum()
    assert f"unfinished run: {len(keep)} of 18 blocks computed" in text
    assert "hatched: not computed yet" in text


def test_command_default_name_and_no_overwrite(rk, tmp_path, monkeypatch, capsys):
    nc, _ = rk
    monkeypatch.chdir(tmp_path)
    assert cli.main(["report", str(nc)]) == 0
    page = tmp_path / "rk_report.html"
    assert page.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    assert f"wrote {page}" in capsys.readouterr().out
    before = page.read_bytes()
    assert cli.main(["report", str(nc), "-o", str(page)]) == 2
    assert "output file exists" in capsys.readouterr().err
    assert page.read_bytes() == before
    assert cli.main(["report", str(nc), "-o", "r.txt"]) == 2
    assert "a report is HTML" in capsys.readouterr().err
    assert cli.main(["report", "missing.nc"]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rk_report.html"]


def test_variables_that_do_not_depend_on_the_energy_are_not_drawn_over_it(rk, monkeypatch):
    """r_circ and V_min are properties of an (alpha, h, Lz) family: their maps are over h and
    Lz (the energy map drew the same value up every column), with the values of the file."""
    import engine.report as report

    nc, _ = rk
    drawn = {}

    def keep(fig, alt, caption, variable):
        drawn[variable] = (fig, caption)
        return ""

    monkeypatch.setattr(report, "_figure", keep)
    with open_result(nc) as r:
        build_report(r)
    ds = xr.open_dataset(nc)
    for name in ("r_circ", "V_min"):
        fig, caption = drawn[name]
        ax = fig.axes[0]
        assert "energy" not in ax.get_xlabel() + ax.get_ylabel(), name
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("Lz [kg m2 s-1]", "h [m s-1]")
        assert "it does not depend on energy" in caption
        want = ds[name].isel(alpha=ds.sizes["alpha"] // 2).transpose("h", "Lz").values
        got = ax.collections[0].get_array().filled(np.nan).reshape(want.shape)
        np.testing.assert_array_equal(got, want)
    fig, _ = drawn["r_min"]  # the others stay over the two longest axes
    assert fig.axes[0].get_ylabel().startswith("energy")


def test_a_sample_orbit_of_each_class_found(rk):
    """One picture per orbit class present (those with an orbit), each of a grid point that
    has that class in the file; the classes without one named as not drawn."""
    nc, text = rk
    ds = xr.open_dataset(nc)
    section = text[text.index('<section id="orbits">') :]
    section = section[: section.index("</section>")]
    names = ds.orbit_class.attrs["flag_meanings"].split()
    present = {names[c] for c in np.unique(ds.orbit_class.values)}
    drawn = re.findall(r'<figure class="orbit" data-flag="(\w+)">', section)
    no_orbit = {"forbidden", "out_of_range", "off_cone"}
    assert set(drawn) == present - no_orbit and drawn
    for flag in present & no_orbit:
        assert f"<li><b>{flag}</b>: no orbit to draw</li>" in section
    for flag, at in re.findall(r'data-flag="(\w+)">.*?--at ([^<]+)</code>', section):
        point = {k: float(v) for k, v in (x.split("=") for x in html.unescape(at).split(","))}
        code = int(ds.orbit_class.sel(point, method="nearest"))
        assert names[code] == flag, (flag, point)

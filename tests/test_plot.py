"""``conesurvey plot`` and engine.plot / engine.mapspec: maps of any variable over any two
axes, flag legends read from the attributes, log axes detected from the coordinates, NaN and
inf, unfinished runs, errors (exit 2, nothing written), no overwrite."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import matplotlib.colors as mcolors
import numpy as np
import pytest
import xarray as xr
from look_cases import FREE_FALL, GRAVITY, computed_mask, run_file, unfinished_run

from engine import cli
from engine.io.results import open_result
from engine.mapspec import LookError, is_log_spaced, parse_at, plan
from engine.plot import (
    OVER_COLOR,
    UNDEFINED_COLOR,
    map_figure,
    save_figure,
)

PNG = b"\x89PNG\r\n\x1a\n"
ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def nc(tmp_path_factory) -> Path:
    return run_file(GRAVITY, tmp_path_factory.mktemp("plot") / "grav.nc")


@pytest.fixture(scope="module")
def free_fall(tmp_path_factory) -> Path:
    return run_file(FREE_FALL, tmp_path_factory.mktemp("plot") / "ff.nc")


#: Blocks kept of the unfinished run: tiling (3, 3, 1, 2) blocks of (1, 4, 3, 10) points.
KEEP = [0, 3, 4, 8, 10, 15]


@pytest.fixture(scope="module")
def partial(tmp_path_factory):
    out = tmp_path_factory.mktemp("plot") / "part.nc"
    survey, full, tiling = unfinished_run(GRAVITY, out, (1, 4, 1, 5), (1, 4, 3, 10), KEEP)
    assert tiling.nblocks == 18
    return out, full, tiling


def _main(args, capsys) -> tuple[int, str, str]:
    rc = cli.main([str(a) for a in args])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def _labels(fig) -> list[str]:
    return [t.get_text() for leg in fig.legends for t in leg.get_texts()]


def _mesh(ax):
    return ax.collections[0]


def _cell_colours(ax) -> list[str]:
    """The colour of each cell of the map, as drawn (colormap of the normalised values)."""
    mesh = _mesh(ax)
    return [mcolors.to_hex(c, keep_alpha=True) for c in mesh.to_rgba(mesh.get_array().ravel())]


# --- the request ------------------------------------------------------------------------------


def test_defaults_are_the_longest_axes_with_energy_up_and_middle_values(nc):
    with open_result(nc) as r:
        spec = plan(r.ds)
    assert (spec.variable, spec.x, spec.y, spec.facet) == ("orbit_class", "Lz", "energy", None)
    assert spec.fixed == {"alpha": (1, "middle value"), "h": (1, "middle value")}
    with open_result(nc) as r:  # one axis given: the other is the longest left
        assert (plan(r.ds, x="h").y, plan(r.ds, y="alpha").x) == ("Lz", "Lz")
        spec = plan(r.ds, facet="Lz")
    assert (spec.x, spec.y, list(spec.fixed)) == ("h", "energy", ["alpha"])


def test_parse_at_and_nearest_value(nc):
    assert parse_at(["alpha=0.35,h=1", " Lz = 2 "]) == {"alpha": 0.35, "h": 1.0, "Lz": 2.0}
    with open_result(nc) as r:
        spec = plan(r.ds, "period", at={"alpha": 0.35, "h": 0.7})
    assert spec.fixed == {"alpha": (0, "nearest to 0.35"), "h": (2, "nearest to 0.7")}


def test_log_spacing_is_detected_from_the_values():
    assert is_log_spaced(np.geomspace(1e-4, 10, 12))
    assert is_log_spaced(np.geomspace(10, 1e-4, 5))  # descending
    assert not is_log_spaced(np.linspace(1, 10, 12))
    assert not is_log_spaced([1.0, 10.0])  # two points: linear and log alike
    assert not is_log_spaced(-np.geomspace(1, 100, 5))
    assert not is_log_spaced([1.0, 10.0, 100.0, 1001.0])
    assert not is_log_spaced([0.0, 1.0, 2.0])


# --- what is drawn ----------------------------------------------------------------------------


def test_default_map_from_the_command_line(nc, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc, out, err = _main(["plot", nc], capsys)
    assert rc == 0, err
    png = tmp_path / "grav_orbit_class.png"
    assert png.read_bytes()[:8] == PNG
    assert "orbit_class over Lz (x) and energy (y)" in out
    assert "alpha = 0.6 radian (middle value), h = 0 m s-1 (middle value)" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grav_orbit_class.png"]


def test_class_map_legend_axes_and_title(nc):
    with open_result(nc) as r:
        fig = map_figure(r.ds, plan(r.ds))
    ds = xr.open_dataset(nc)
    sl = ds.orbit_class.isel(alpha=1, h=1)
    names = ds.orbit_class.attrs["flag_meanings"].split()
    present = [names[c] for c in np.unique(sl.values)]
    assert len(present) >= 2
    assert _labels(fig) == present  # from flag_meanings, in flag order, only those present
    ax = fig.axes[0]
    assert (ax.get_xscale(), ax.get_yscale()) == ("linear", "log")
    assert ax.get_xlabel() == "Lz [kg m2 s-1]"
    assert ax.get_ylabel() == "energy offset (calE - V_min)/|V_min|"
    title = fig._suptitle.get_text()
    assert "Gravity look" in title and "orbit class (orbit_class)" in title
    assert "alpha = 0.6 radian (middle value), h = 0 m s-1 (middle value)" in title
    # The cells carry the codes of the file, laid out (energy, Lz).
    np.testing.assert_array_equal(_mesh(ax).get_array().reshape(12, 20), sl.values)


def test_values_drawn_are_the_selected_slice(nc, tmp_path, capsys):
    out = tmp_path / "p.png"
    rc, text, err = _main(["plot", nc, "period", "--at", "alpha=0.35", "-o", out], capsys)
    assert rc == 0, err
    assert "alpha = 0.3 radian (nearest to 0.35)" in text
    with open_result(nc) as r:
        spec = plan(r.ds, "period", at={"alpha": 0.35})
        fig = map_figure(r.ds, spec)
    ax = fig.axes[0]
    want = xr.open_dataset(nc).period.isel(alpha=0, h=1).transpose("energy", "Lz").values
    got = _mesh(ax).get_array().filled(np.nan).reshape(want.shape)
    np.testing.assert_array_equal(got, want)
    assert "period [s]" in fig.axes[1].get_ylabel()  # the colour bar: name and units
    assert "radial period" in fig._suptitle.get_text()  # the long name


def test_other_axes_and_linear_scales(nc):
    with open_result(nc) as r:
        fig = map_figure(r.ds, plan(r.ds, "r_min", x="h", y="alpha"))
    ax = fig.axes[0]
    assert (ax.get_xscale(), ax.get_yscale()) == ("linear", "linear")
    assert ax.get_xlabel() == "h [m s-1]" and ax.get_ylabel() == "alpha [radian]"
    assert "energy = " in fig._suptitle.get_text() and "Lz = " in fig._suptitle.get_text()


def test_facet_grid_shares_one_colour_scale(nc):
    ds = xr.open_dataset(nc)
    with open_result(nc) as r:
        fig = map_figure(r.ds, plan(r.ds, "r_max", facet="alpha"))
    panels = [ax for ax in fig.axes if ax.get_visible() and ax.get_title()]
    assert [ax.get_title() for ax in panels] == [
        "alpha = 0.3 radian",
        "alpha = 0.6 radian",
        "alpha = 0.9 radian",
    ]
    v = ds.r_max.isel(h=1).values
    fin = v[np.isfinite(v)]
    for ax in panels:
        norm = _mesh(ax).norm
        assert (norm.vmin, norm.vmax) == (fin.min(), fin.max())


def test_facet_over_up_to_25_values_draws_them_all(nc):
    with open_result(nc) as r:
        fig = map_figure(r.ds, plan(r.ds, "period", x="h", y="energy", facet="Lz"))
    panels = [ax for ax in fig.axes if ax.get_visible() and ax.get_title()]
    assert len(panels) == 20  # every value of Lz
    assert "values of Lz" not in fig._suptitle.get_text()
    assert panels[0].get_title() == "Lz = 0 kg m2 s-1"
    assert panels[-1].get_title() == "Lz = 2 kg m2 s-1"


def test_facet_over_many_values_keeps_zero_and_names_the_ones_left_out():
    """41 values of h (-2 .. 2 by 0.1): 25 panels, h = 0 among them (evenly spaced indices
    skip it), and every value not drawn is named in the title."""
    h = np.round(np.linspace(-2.0, 2.0, 41), 12)
    period = np.arange(41 * 3 * 2, dtype=float).reshape(41, 3, 2) + 1.0
    ds = xr.Dataset(
        {"period": (("h", "energy", "Lz"), period, {"units": "s"})},
        coords={"h": ("h", h, {"units": "m s-1"}), "energy": [1.0, 2.0, 3.0], "Lz": [0.5, 1.0]},
    )
    fig = map_figure(ds, plan(ds, "period", x="Lz", y="energy", facet="h"))
    titles = [ax.get_title() for ax in fig.axes if ax.get_visible() and ax.get_title()]
    assert len(titles) == 25
    drawn = {float(t.split("=")[1].split()[0]) for t in titles}
    assert 0.0 in drawn and -2.0 in drawn and 2.0 in drawn
    text = " ".join(fig._suptitle.get_text().split())
    assert "25 of 41 values of h; left out:" in text
    named = text.split("left out:")[1]
    shown = [float(x) for x in named.replace(" and", ",").split(",")[:12]]
    missing = sorted(set(h.tolist()) - drawn)
    assert len(missing) == 16 and shown == missing[:12] and "and 4 more" in named


def test_flag_legend_and_colours_come_from_the_attributes():
    """A flag variable the engine does not know (codes 0, 2, 5) is drawn with its own names,
    and every cell has the colour of its flag's legend entry."""
    codes = np.array([[0, 2, 5], [5, 5, 0]], np.int8)
    ds = xr.Dataset(
        {"fate": (("energy", "Lz"), codes, {"long_name": "fate", "flag_values": [0, 2, 5],
                                             "flag_meanings": "stays leaves falls_off"})},
        coords={"energy": [1.0, 2.0], "Lz": [0.1, 0.2, 0.3]},
    )  # fmt: skip
    fig = map_figure(ds, plan(ds, "fate"))
    handles = fig.legends[0].legend_handles
    colour = {h.get_label(): mcolors.to_hex(h.get_facecolor(), keep_alpha=True) for h in handles}
    assert list(colour) == ["stays", "leaves", "falls_off"]
    assert len(set(colour.values())) == 3
    cells = _cell_colours(fig.axes[0])
    names = {0: "stays", 2: "leaves", 5: "falls_off"}
    assert cells == [colour[names[c]] for c in codes.ravel()]


def test_nan_is_undefined_and_inf_is_in_the_extension(free_fall):
    ds = xr.open_dataset(free_fall)
    with open_result(free_fall) as r:
        fig = map_figure(r.ds, plan(r.ds, "r_max", x="h", y="energy"))
    ax = fig.axes[0]
    sl = ds.r_max.isel(alpha=0, Lz=1).transpose("energy", "h").values
    assert np.isinf(sl).any() and np.isnan(sl).any()
    assert set(_labels(fig)) == {"+inf", "undefined (NaN)"}
    assert mcolors.to_hex(ax.get_facecolor()) == UNDEFINED_COLOR  # NaN cells are not painted
    mesh = _mesh(ax)
    assert mesh.get_array().mask.reshape(sl.shape).tolist() == np.isnan(sl).tolist()
    painted = np.array(_cell_colours(ax)).reshape(sl.shape)
    assert set(painted[np.isinf(sl)]) == {OVER_COLOR + "ff"}
    assert OVER_COLOR + "ff" not in set(painted[np.isfinite(sl)])
    assert fig.axes[1].get_ylabel().startswith("r_max [m]")


def test_colour_scales_follow_the_values():
    """Both signs: diverging and symmetric about 0; positive over 1000x: log; else linear."""
    coords = {"energy": [1.0, 2.0], "Lz": [0.1, 0.2]}
    cases = {
        "signed": ([[-1.0, 3.0], [0.5, np.nan]], "RdBu_r", (-3.0, 3.0), "Normalize"),
        "wide": ([[1e-12, 1e-9], [1e-6, 1e-8]], "viridis", (1e-12, 1e-6), "LogNorm"),
        "narrow": ([[2.0, 3.0], [5.0, 4.0]], "viridis", (2.0, 5.0), "Normalize"),
    }
    for name, (values, cmap, limits, norm) in cases.items():
        ds = xr.Dataset({name: (("energy", "Lz"), np.array(values), {"units": "1"})}, coords)
        mesh = _mesh(map_figure(ds, plan(ds, name)).axes[0])
        assert mesh.cmap.name.startswith(cmap), name
        assert (mesh.norm.vmin, mesh.norm.vmax) == limits, name
        assert type(mesh.norm).__name__ == norm, name


# --- unfinished runs --------------------------------------------------------------------------


def test_unfinished_run_draws_what_is_done(partial, tmp_path, capsys):
    out, full, tiling = partial
    png = tmp_path / "part.png"
    rc, text, err = _main(["plot", out, "period", "-o", png], capsys)
    assert rc == 0, err
    assert png.read_bytes()[:8] == PNG
    mask = computed_mask(tiling, KEEP)
    with open_result(out) as r:
        assert not out.exists() and not r.complete and r.blocks_done == len(KEEP)
        np.testing.assert_array_equal(r.computed().values, mask)
        got = r.ds.period.values
        np.testing.assert_array_equal(got[mask], full.period.values[mask])
        assert np.isnan(got[~mask]).all()
        codes = r.ds.orbit_class.values
        np.testing.assert_array_equal(codes[mask], full.orbit_class.values[mask])
        fig = map_figure(r.ds, plan(r.ds, "orbit_class"), r.computed(), r.note)
    title = fig._suptitle.get_text()
    assert f"unfinished run: {len(KEEP)} of 18 blocks computed" in title
    assert "not computed yet" in _labels(fig)
    hatched = fig.axes[0].collections[1]
    assert hatched.get_hatch() == "////"
    missing = ~mask[1, :, 1, :]  # the drawn slice (alpha, h middle), laid out (energy, Lz)
    assert np.count_nonzero(~hatched.get_array().mask) == missing.sum() > 0


def test_unfinished_run_lazy_selections_and_parts_path(partial):
    out, full, tiling = partial
    mask = computed_mask(tiling, KEEP)
    sel = {"alpha": [2, 0], "energy": slice(None, None, -3), "h": 1, "Lz": slice(3, 17)}
    with open_result(Path(str(out) + ".parts")) as r:  # the .parts directory itself
        assert r.path == out
        got = r.ds.r_min.isel(sel).values
        done = r.computed().isel(sel).values
    want = full.r_min.isel(sel).values
    np.testing.assert_array_equal(done, xr.DataArray(mask, dims=full.r_min.dims).isel(sel))
    np.testing.assert_array_equal(got[done], want[done])
    assert np.isnan(got[~done]).all()


def test_reading_an_unfinished_run_never_changes_it(tmp_path, capsys):
    out = tmp_path / "run.nc"
    unfinished_run(GRAVITY, out, (1, 4, 1, 5), (1, 4, 3, 10), [0, 1, 2])
    root = Path(str(out) + ".parts")
    (root / "b00000001.npz").write_bytes(b"truncated")  # a corrupt block: left alone
    before = {p.name: p.read_bytes() for p in root.iterdir()}
    rc, _, err = _main(["plot", out, "r_max", "-o", tmp_path / "m.png"], capsys)
    assert rc == 0, err
    assert {p.name: p.read_bytes() for p in root.iterdir()} == before


# --- fate maps, derived variables, contours ---------------------------------------------------

#: A small fate map (rolling resistance, a rim, a friction limit: the effects of
#: surveys/fate_rolling_resistance.toml): 2 x 4 x 5 x 1 launches.
FATE = """\
title = "fate look"
method = "rk45"

[scene]
c_rr = 0.01
rim = 3.0
mu = 0.5

[horizon]
time = 5.0

[axes.alpha]
values = [0.6, 1.2]

[axes.r0]
start = 0.5
stop = 2.0
num = 4

[axes.v0]
start = 0.2
stop = 2.0
num = 5

[axes.w0]
values = [0.0]
"""


@pytest.fixture(scope="module")
def fate_nc(tmp_path_factory) -> Path:
    return run_file(FATE, tmp_path_factory.mktemp("plot") / "fate.nc")


def test_a_fate_map_is_drawn_by_fate_by_default(fate_nc, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc, out, err = _main(["plot", fate_nc], capsys)
    assert rc == 0, err
    assert out.startswith(f"wrote {tmp_path / 'fate_fate.png'}: fate over ")
    with open_result(fate_nc) as r:
        spec = plan(r.ds)
        fig = map_figure(r.ds, spec)
    assert spec.variable == "fate"
    ds = xr.open_dataset(fate_nc)
    want = ds.fate.isel(spec.selection()).transpose(spec.y, spec.x).values
    np.testing.assert_array_equal(_mesh(fig.axes[0]).get_array().reshape(want.shape), want)
    names = ds.fate.attrs["flag_meanings"].split()
    assert _labels(fig) == [names[c] for c in np.unique(want)]


def test_precession_per_revolution_is_plotted_from_the_command_line(nc, tmp_path, capsys):
    """A derived variable: 2 psi - 2 pi in degrees on bounded, circular and spilling orbits,
    computed here from the file's apsidal_angle and orbit_class."""
    out = tmp_path / "ppr.png"
    rc, text, err = _main(["plot", nc, "precession_per_revolution", "-o", out], capsys)
    assert rc == 0, err
    assert out.read_bytes()[:8] == PNG and "precession_per_revolution over Lz (x)" in text
    from engine.accessor import with_derived

    with open_result(nc) as r:
        ds = with_derived(r.ds, "precession_per_revolution")
        fig = map_figure(ds, plan(ds, "precession_per_revolution"))
    f = xr.open_dataset(nc).isel(alpha=1, h=1).transpose("energy", "Lz")
    names = f.orbit_class.attrs["flag_meanings"].split()
    codes = [names.index(c) for c in ("bounded", "circular", "spills") if c in names]
    want = np.where(np.isin(f.orbit_class.values, codes),
                    np.degrees(2.0 * f.apsidal_angle.values - 2.0 * np.pi), np.nan)  # fmt: skip
    got = _mesh(fig.axes[0]).get_array().filled(np.nan).reshape(want.shape)
    assert np.isfinite(want).sum() > 100
    np.testing.assert_allclose(got, want, rtol=1e-12, equal_nan=True)


def test_a_zero_contour_runs_where_the_variable_changes_sign(nc, tmp_path, capsys):
    """--contour 0 on precession_rate (both signs at alpha = 0.3, h = -1): each crossing of
    zero between two neighbouring cells along Lz, interpolated linearly here, is a vertex of
    the drawn line, and every vertex lies on the grid lines where the values interpolate to 0."""
    args = ["precession_rate", "--at", "alpha=0.3,h=-1", "--contour", "0"]
    rc, _, err = _main(["plot", nc, *args, "-o", tmp_path / "c.png"], capsys)
    assert rc == 0, err
    with open_result(nc) as r:
        spec = plan(r.ds, "precession_rate", at={"alpha": 0.3, "h": -1.0}, contours=[0.0])
        fig = map_figure(r.ds, spec)
    ax = fig.axes[0]
    f = xr.open_dataset(nc).precession_rate.isel(alpha=0, h=0).transpose("energy", "Lz")
    z, lz, en = f.values, f.Lz.values, f.energy.values
    verts = np.concatenate([p.vertices for c in ax.collections[1:] for p in c.get_paths()
                            if len(p.vertices)])  # fmt: skip
    crossings = []  # along Lz (x) and along energy (y), linear in the data coordinates
    for j in range(en.size):
        for i in range(lz.size - 1):
            a, b = z[j, i], z[j, i + 1]
            if np.isfinite(a) and np.isfinite(b) and a * b < 0:
                crossings.append((lz[i] + a / (a - b) * (lz[i + 1] - lz[i]), en[j]))
    for i in range(lz.size):
        for j in range(en.size - 1):
            a, b = z[j, i], z[j + 1, i]
            if np.isfinite(a) and np.isfinite(b) and a * b < 0:
                crossings.append((lz[i], en[j] + a / (a - b) * (en[j + 1] - en[j])))
    assert len(crossings) >= 3
    for x, y in crossings:
        d = np.hypot(verts[:, 0] - x, (verts[:, 1] - y) / y)
        assert d.min() < 1e-9, (x, y)
    assert len(verts) >= len(crossings)
    for x, y in verts:  # on a grid line, where the neighbours' values interpolate to 0
        i = np.flatnonzero(np.isclose(lz, x, rtol=0, atol=1e-12))
        j = np.flatnonzero(np.isclose(en, y, rtol=1e-12, atol=0))
        assert i.size or j.size, (x, y)
        if i.size:
            v = np.interp(y, en, z[:, i[0]])
        else:
            v = np.interp(x, lz, z[j[0], :])
        assert abs(v) < 1e-9 * np.nanmax(np.abs(z)), (x, y, v)
    assert "precession_rate = 0" in _labels(fig)


# --- errors and overwriting -------------------------------------------------------------------

ERRORS = [
    (["nosuchvar"], "no variable 'nosuchvar'; variables: orbit_class, r_min"),
    (["--x", "theta"], "--x: no axis 'theta'; axes: alpha, energy, h, Lz"),
    (["--y", "E"], "--y: no axis 'E'; axes: alpha, energy, h, Lz"),
    (["--facet", "time"], "--facet: no axis 'time'"),
    (["--at", "beta=1"], "--at: no axis 'beta'"),
    (["--at", "alpha"], "--at 'alpha': expected AXIS=VALUE"),
    (["--at", "alpha=big"], "--at alpha='big': not a number"),
    (["--at", "alpha=nan"], "must be finite"),
    (["--x", "h", "--y", "h"], "must be different axes"),
    (["--x", "h", "--at", "h=0"], "--at h: h is drawn"),
    (["-o", "map.jpg"], "unknown format '.jpg'"),
    (["-o", "missing/map.png"], "output directory does not exist"),
    (["--dpi", "0"], "--dpi must be in 10..1200; got 0"),
    (["--dpi", "100000"], "--dpi must be in 10..1200; got 100000"),
    (["--dpi", "1200", "--facet", "alpha"], "pixels, more than 50,000,000; at most --dpi"),
    (["precesion_rate"], "no variable 'precesion_rate'; did you mean 'precession_rate'?"),
    (["--x", "lz"], "--x: no axis 'lz'; did you mean 'Lz'?"),
    (["orbit_class", "--contour", "0"], "orbit_class is a flag variable; contours need numbers"),
    (["--x", "h", "--at", "alpha=1,energy=1,Lz=1"], "no axis left to draw"),
]


@pytest.mark.parametrize(("extra", "message"), ERRORS)
def test_bad_requests_exit_2_and_write_nothing(nc, tmp_path, monkeypatch, capsys, extra, message):
    monkeypatch.chdir(tmp_path)
    rc, out, err = _main(["plot", nc, *extra], capsys)
    assert rc == 2
    assert message in err and err.startswith("conesurvey: error: ")
    assert list(tmp_path.iterdir()) == []


def test_missing_result_exits_2(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc, _, err = _main(["plot", "nothere.nc"], capsys)
    assert rc == 2 and "no such file: nothere.nc" in err
    (tmp_path / "junk.nc").write_text("not netCDF")
    rc, _, err = _main(["plot", "junk.nc"], capsys)
    assert rc == 2 and "junk.nc is not a readable netCDF file" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["junk.nc"]


def test_never_overwrites_without_overwrite(nc, tmp_path, capsys):
    out = tmp_path / "map.png"
    out.write_bytes(b"mine")
    rc, _, err = _main(["plot", nc, "-o", out], capsys)
    assert rc == 2 and "output file exists" in err and "--overwrite" in err
    assert out.read_bytes() == b"mine"
    rc, _, err = _main(["plot", nc, "-o", out, "--overwrite"], capsys)
    assert rc == 0, err
    assert out.read_bytes()[:8] == PNG
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.png"]


@pytest.mark.parametrize(("suffix", "magic"), [(".svg", b"<?xml"), (".pdf", b"%PDF")])
def test_vector_formats(nc, tmp_path, capsys, suffix, magic):
    out = tmp_path / f"map{suffix}"
    assert _main(["plot", nc, "mu_required", "-o", out], capsys)[0] == 0
    assert out.read_bytes()[: len(magic)] == magic


def test_failed_write_leaves_nothing(nc, tmp_path):
    with open_result(nc) as r:
        fig = map_figure(r.ds, plan(r.ds))

    def broken(path, **kw):
        Path(path).write_bytes(b"half")
        raise OSError(28, "No space left on device")

    fig.savefig = broken
    with pytest.raises(OSError, match="No space"):
        save_figure(fig, tmp_path / "m.png")
    assert list(tmp_path.iterdir()) == []


def test_plan_errors_name_what_exists():
    ds = xr.Dataset({"v": (("a",), [1.0, 2.0])}, coords={"a": [0.0, 1.0]})
    with pytest.raises(LookError, match="v has 1 dimension"):
        plan(ds, "v")


def test_a_map_larger_than_a_figure_draws_is_refused_before_anything_is_read():
    """3000 x 2000 cells (6 million, over MAX_CELLS): refused by the plan, from the sizes
    alone (the values are a dask array that is never computed), for plot and report."""
    from types import SimpleNamespace

    import dask.array as da

    from engine.mapspec import MAX_CELLS
    from engine.report import check_report

    big = xr.Dataset(
        {"orbit_class": (("energy", "Lz"), da.zeros((3000, 2000), dtype="i1", chunks=500),
                         {"flag_values": [0, 1], "flag_meanings": "a b"})},
        coords={"energy": np.arange(3000.0), "Lz": np.arange(2000.0)},
    )  # fmt: skip
    assert 3000 * 2000 > MAX_CELLS
    with pytest.raises(LookError, match=r"is 6,000,000 cells; a figure draws at most 4,000,000"):
        plan(big)
    with pytest.raises(LookError, match="a figure draws at most"):
        check_report(SimpleNamespace(ds=big))
    small = big.isel(energy=slice(0, 1000))  # 2 million: drawn
    assert plan(small).x == "Lz"
    faceted = xr.Dataset(
        {"orbit_class": (("h", "energy", "Lz"), da.zeros((3, 750, 2000), dtype="i1"),
                         big.orbit_class.attrs)},
        coords={"h": [-1.0, 0.0, 1.0], "energy": np.arange(750.0), "Lz": np.arange(2000.0)},
    )  # fmt: skip
    assert plan(faceted).facet is None  # one panel of 1.5 million cells
    with pytest.raises(LookError, match="x 3 panels"):  # 3 panels of 1.5 million
        plan(faceted, facet="h")


def test_dpi_bounds_are_checked_before_the_result_is_opened(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc, _, err = _main(["plot", "missing.nc", "--dpi", "100000"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "--dpi must be in 10..1200" in err


# --- matplotlib stays optional ----------------------------------------------------------------


def _python(code: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT
    )


def test_engine_and_its_cli_do_not_import_matplotlib():
    res = _python(
        "import sys, engine, engine.cli\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib')\n"
        "print(bad)\n"
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]"


@pytest.mark.parametrize("command", ["plot", "report"])
def test_without_matplotlib_the_commands_say_how_to_install_it(nc, tmp_path, command):
    out = tmp_path / ("m.png" if command == "plot" else "r.html")
    res = _python(
        "import sys\n"
        "sys.modules['matplotlib'] = None  # as if it were not installed\n"
        "from engine.cli import main\n"
        f"raise SystemExit(main([{command!r}, {str(nc)!r}, '-o', {str(out)!r}]))\n"
    )
    assert res.returncode == 2, res.stderr
    assert "-m pip install '.[plot]'" in res.stderr  # from the checkout, as the README does
    assert list(tmp_path.iterdir()) == []

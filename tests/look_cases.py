"""Small survey results for the tests of ``conesurvey plot`` and ``report``: a finished netCDF
file (run by :func:`engine.runner.run_survey`), an integrator run, and an unfinished run whose
block store holds only some blocks (written as the runner writes them); and the check of a
report's numbers against xarray (shared by the HTML and the browser tests)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from engine.grid import Tiling
from engine.io.blocks import BlockStore
from engine.io.manifest import Manifest, parts_dir
from engine.plan import plan_from_survey
from engine.runner import run_survey
from engine.surveyfile import Survey, parse_survey

#: Gravity, energy relative to V_min on a log axis, Lz linear from 0 (forbidden at Lz = 0),
#: 3 x 12 x 3 x 20 = 2,160 points.
GRAVITY = """\
title = "Gravity look"

[scene]
g = 9.81

[axes.alpha]
values = [0.3, 0.6, 0.9]

[axes.energy]
start = 1e-4
stop = 10.0
num = 12
scale = "log"
relative_to = "V_min"

[axes.h]
values = [-1.0, 0.0, 1.0]

[axes.Lz]
start = 0.0
stop = 2.0
num = 20
"""

#: An rk45 run (integrator diagnostics: status, n_steps, energy_drift), with a title full of
#: characters HTML must escape: 2 x 6 x 2 x 5 = 120 points.
INTEGRATOR = """\
title = "rk45 <script>alert('x')</script> & \\"co\\""
method = "rk45"
rtol = 1e-8

[scene]
g = 9.81

[axes.alpha]
values = [0.4, 0.8]

[axes.energy]
start = 1e-3
stop = 10.0
num = 6
scale = "log"
relative_to = "V_min"

[axes.h]
values = [-1.0, 1.0]

[axes.Lz]
start = 0.0
stop = 2.0
num = 5
"""

#: Free fall over (energy, h): forbidden, bounded and hyperbolic orbits (r_max = +inf, NaN
#: periods), 1 x 9 x 7 x 2 points.
FREE_FALL = """\
title = "Free fall"

[scene]
g = 0.0

[axes.alpha]
values = [0.5]

[axes.energy]
start = -1.0
stop = 1.0
num = 9

[axes.h]
start = -6.0
stop = 6.0
num = 7

[axes.Lz]
values = [0.5, 1.0]
"""


def run_file(text: str, out: Path) -> Path:
    """Run the survey ``text`` into the netCDF file ``out`` (quietly)."""
    run_survey(parse_survey(text), out, warn=lambda msg: None)
    return out


def unfinished_run(
    text: str, out: Path, chunk: tuple[int, ...], block: tuple[int, ...], keep: list[int]
) -> tuple[Survey, xr.Dataset, Tiling]:
    """The block store of an unfinished run of ``text`` behind ``out`` (no ``out`` itself)
    holding the blocks ``keep`` of a ``chunk``/``block`` tiling, with the values the full
    survey has there. Returns the survey, its full in-memory result and the tiling."""
    survey = parse_survey(text)
    full = survey.run()
    tiling = Tiling(survey.shape, chunk, block)
    store = BlockStore.create(parts_dir(out), Manifest.new(plan_from_survey(survey), tiling))
    for i in keep:
        sl = tiling.slices(i)
        store.commit(i, {n: full[n].values[sl] for n in store.names})
    return survey, full, tiling


def computed_mask(tiling: Tiling, keep: list[int]) -> np.ndarray:
    """Boolean grid: True on the points of the blocks ``keep``."""
    mask = np.zeros(tiling.shape, bool)
    for i in keep:
        mask[tiling.slices(i)] = True
    assert 0 < mask.sum() < math.prod(tiling.shape)
    return mask


def _shown(text: str) -> float:
    """A number as the page shows it (``1,080``, ``0.9000``, ``3.20715e-09``, ``-``)."""
    return np.nan if text.strip() == "-" else float(text.replace(",", ""))


def check_numbers(rows: list[dict[str, str]], nc: Path) -> int:
    """Every count, fraction and range on the page equals what xarray computes from the file
    (exactly in the data-* attributes, to the shown digits in the text); returns the number
    of rows checked. Shared with the browser test, which reads the rows from the DOM."""
    ds = xr.open_dataset(nc)
    n = 0
    for row in rows:
        if "data-flag" in row:
            var = ds[row["data-flag-variable"]]
            names = var.attrs["flag_meanings"].split()
            code = int(var.attrs["flag_values"][names.index(row["data-flag"])])
            count = int((var == code).sum())
            assert int(row["data-count"]) == count == _shown(row["count"]), row
            assert float(row["data-fraction"]) == count / var.size, row
            assert _shown(row["fraction"]) == pytest.approx(count / var.size, abs=5e-5)
        elif "data-min" in row:
            var = ds[row["data-variable"]].astype(float)
            finite = var.where(np.isfinite(var))
            lo, hi = float(finite.min()), float(finite.max())
            assert float(row["data-min"]) == lo and float(row["data-max"]) == hi, row
            assert _shown(row["min"]) == pytest.approx(lo, rel=5e-6), row
            assert _shown(row["max"]) == pytest.approx(hi, rel=5e-6), row
            assert int(row["data-finite"]) == int(np.isfinite(var).sum()) == _shown(row["finite"])
            assert int(row["data-nan"]) == int(var.isnull().sum()) == _shown(row["nan"])
            assert int(row["data-posinf"]) == int((var == np.inf).sum())
        else:
            continue
        n += 1
    return n

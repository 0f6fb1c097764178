"""dask.distributed backend: bit-identical to the local backend, survives a killed worker."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
import xarray as xr

from engine.runner import run_survey
from engine.surveyfile import parse_survey

distributed = pytest.importorskip("distributed")

SURVEY = """\
title = "dask test"

[axes.alpha]
values = [0.3, 0.6, 0.9, 1.2]

[axes.energy]
start = 1e-6
stop = 10.0
num = 40
scale = "log"
relative_to = "V_min"

[axes.h]
start = -2.0
stop = 2.0
num = 33

[axes.Lz]
start = 0.05
stop = 1.0
num = 100
"""
CHUNK = 1 << 16


def _values(path):
    with xr.open_dataset(path) as ds:
        return {k: v.values.copy() for k, v in ds.variables.items()}


@pytest.fixture(autouse=True)
def _keep_environment():
    """A LocalCluster's nannies write NUMBA_NUM_THREADS=1 etc. into os.environ (distributed
    Nanny.start); numba in this process must not see that after the test."""
    saved = dict(os.environ)
    yield
    os.environ.clear()
    os.environ.update(saved)


@pytest.fixture(scope="module")
def local_result(tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "local.nc"
    stats = run_survey(parse_survey(SURVEY), out, block_points=CHUNK)
    assert stats.blocks_total >= 6
    return _values(out)


def test_existing_cluster_with_a_worker_killed_mid_run(tmp_path, local_result):
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        pids = list(client.run(os.getpid).values())
        killed = []

        def kill_one(index: int) -> None:
            if not killed:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])

        out = tmp_path / "dask.nc"
        stats = run_survey(
            parse_survey(SURVEY),
            out,
            block_points=CHUNK,
            scheduler=cluster.scheduler_address,
            on_block=kill_one,
        )
    assert killed and stats.blocks_total >= 6
    got = _values(out)
    assert got.keys() == local_result.keys()
    for name, arr in local_result.items():
        np.testing.assert_array_equal(got[name], arr, err_msg=name)  # bit-identical, NaN too


def test_local_cluster_started_by_workers_flag(tmp_path, local_result):
    out = tmp_path / "workers.nc"
    before = dict(os.environ)
    run_survey(parse_survey(SURVEY), out, block_points=CHUNK, workers=2)
    assert dict(os.environ) == before  # the runner restores what the nannies changed
    got = _values(out)
    for name, arr in local_result.items():
        np.testing.assert_array_equal(got[name], arr, err_msg=name)


def test_unreachable_scheduler_is_a_clear_error(tmp_path):
    from engine.runner import RunError

    with pytest.raises(RunError, match="cannot reach the dask scheduler"):
        run_survey(parse_survey(SURVEY), tmp_path / "x.nc", scheduler="tcp://127.0.0.1:9")

"""dask.distributed backend: bit-identical to the local backend, survives a killed worker."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import runs
import xarray as xr
from dask.config import set as dask_config

from engine.runner import RunError, RunFailed, run_survey
from engine.surveyfile import parse_survey

distributed = pytest.importorskip("distributed")

SURVEY = runs.gravity_survey("dask test", energy=20)  # 8 blocks of 34,000 points
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


def _worker_processes() -> list[int]:
    """Pids of this process's children that are dask worker processes (multiprocessing's
    spawned children, not its resource tracker)."""
    pids = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = open(f"/proc/{entry}/stat").read()
            cmd = open(f"/proc/{entry}/cmdline", "rb").read().replace(b"\0", b" ")
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        if ppid == os.getpid() and b"spawn_main" in cmd and b"resource_tracker" not in cmd:
            pids.append(int(entry))
    return pids


def test_the_only_worker_of_a_local_cluster_killed_mid_run(tmp_path, local_result):
    """--workers 1: the issue saw a FutureCancelledError traceback (the survey description was
    scattered data, lost with the worker). The nanny restarts the worker, the description is
    a task that can be recomputed, and the run finishes, bit-identical."""
    killed = []

    def kill_worker(index: int) -> None:
        if not killed:
            (pid,) = _worker_processes()
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    out = tmp_path / "one.nc"
    run_survey(parse_survey(SURVEY), out, block_points=CHUNK, workers=1, on_block=kill_worker)
    assert killed
    got = _values(out)
    for name, arr in local_result.items():
        np.testing.assert_array_equal(got[name], arr, err_msg=name)


def test_unreachable_scheduler_is_a_clear_error_and_nothing_is_written(tmp_path):
    """Checked before any work, within CONNECT_TIMEOUT (5 s), and not blamed on the survey."""
    t = time.monotonic()
    with pytest.raises(RunFailed, match="cannot reach the dask scheduler") as info:
        run_survey(parse_survey(SURVEY), tmp_path / "x.nc", scheduler=f"tcp://127.0.0.1:{_port()}")
    assert time.monotonic() - t < 15
    assert "within 5 s" in str(info.value) and "nothing was written" in str(info.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("address", ["tcp://", "127.0.0.1", "tcp://host:99999", "ftp://h:1"])
def test_a_malformed_scheduler_address_is_bad_input(tmp_path, address):
    with pytest.raises(RunError, match="--scheduler"):
        run_survey(parse_survey(SURVEY), tmp_path / "x.nc", scheduler=address)
    assert list(tmp_path.iterdir()) == []


# --- an external cluster, the command in a subprocess -----------------------------------------


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Cluster:
    """A ``dask scheduler`` and ``dask worker`` processes (no nannies: a killed worker stays
    dead), on localhost."""

    def __init__(self, workers: int) -> None:
        self.address = f"tcp://127.0.0.1:{_port()}"
        self.dask = str(Path(sys.executable).parent / "dask")
        host, port = self.address[6:].split(":")
        self.scheduler = self._start("scheduler", "--host", host, "--port", port, "--no-dashboard")
        self.workers = [self.add_worker() for _ in range(workers)]
        self.wait_for(workers)

    def _start(self, *args: str) -> subprocess.Popen:
        env = dict(runs.env(), NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
        return subprocess.Popen(
            [self.dask, *args], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )

    def add_worker(self) -> subprocess.Popen:
        return self._start(
            "worker", self.address, "--nthreads", "1", "--no-nanny", "--no-dashboard"
        )

    def wait_for(self, n: int) -> None:
        from distributed import Client

        with Client(self.address, timeout=60, set_as_default=False) as client:
            client.wait_for_workers(n, timeout=120)

    def kill(self, procs: list[subprocess.Popen]) -> None:
        for p in procs:
            p.kill()
            p.wait()

    def close(self) -> None:
        self.kill([self.scheduler, *self.workers])


@pytest.fixture
def cluster_factory():
    made: list[Cluster] = []

    def make(workers: int) -> Cluster:
        made.append(Cluster(workers))
        return made[-1]

    yield make
    for c in made:
        c.close()


def _cli_run(work: Path, *extra: str, **env: str) -> subprocess.Popen:
    args = runs.cli("run", "s.toml", "-o", "out.nc", "-q", "--block-points", str(CHUNK), *extra)
    return subprocess.Popen(
        args,
        cwd=work,
        env=runs.env(**env),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _cli_here(work: Path, capsys, *extra: str) -> subprocess.CompletedProcess:
    """The same command, run to its end in this process (no interpreter start)."""
    args = ("run", "s.toml", "-o", "out.nc", "-q", "--block-points", str(CHUNK), *extra)
    return runs.here(work, capsys, *args)


def _stopped_resumably(proc: subprocess.Popen, what: str) -> None:
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 1, (out, err)
    assert err.startswith("conesurvey: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err and what in err, err
    assert err.rstrip().endswith("the run is resumable: run the same command again"), err


def _when_blocks(work: Path, n: int, proc: subprocess.Popen) -> None:
    deadline = time.monotonic() + 300
    while runs.blocks_in(work / "out.nc.parts") < n:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.01)


@pytest.fixture
def work(tmp_path):
    (tmp_path / "s.toml").write_text(SURVEY)
    return tmp_path


def _same_as_local(work: Path, local_result) -> None:
    assert runs.listing(work) == ["out.nc", "s.toml"]
    got = _values(work / "out.nc")
    assert got.keys() == local_result.keys()
    for name, arr in local_result.items():
        np.testing.assert_array_equal(got[name], arr, err_msg=name)


def test_every_worker_killed_is_a_resumable_error(work, local_result, cluster_factory, capsys):
    """Both workers of an external cluster (no nannies) killed: after
    conesurvey.no-workers-timeout (here 1 s) the run stops with one line; with a new worker the
    same command finishes it, identical. (One worker killed of a local cluster, whose nanny
    restarts it, finishes: test_the_only_worker_of_a_local_cluster_killed_mid_run.)"""
    cluster = cluster_factory(2)
    proc = _cli_run(work, "--scheduler", cluster.address, DASK_CONESURVEY__NO_WORKERS_TIMEOUT="1")
    _when_blocks(work, 2, proc)
    cluster.kill(cluster.workers)
    _stopped_resumably(proc, "the dask cluster has had no workers for 1 s")
    cluster.workers = [cluster.add_worker()]
    cluster.wait_for(1)
    again = _cli_here(work, capsys, "--scheduler", cluster.address)
    assert again.returncode == 0, again.stderr
    _same_as_local(work, local_result)


def test_a_killed_scheduler_is_a_resumable_error(work, local_result, cluster_factory, capsys):
    cluster = cluster_factory(1)
    proc = _cli_run(work, "--scheduler", cluster.address)
    _when_blocks(work, 2, proc)
    cluster.kill([cluster.scheduler])
    _stopped_resumably(proc, "lost the dask cluster")
    again = _cli_here(work, capsys)  # resumed without dask: the blocks are the same
    assert again.returncode == 0, again.stderr
    _same_as_local(work, local_result)


def test_an_unreachable_scheduler_on_the_command_line(work, capsys):
    """The command's one line, in this process (no interpreter start to measure beside it);
    conesurvey.connect-timeout, here 1 s, bounds the wait (the API's test above: the default)."""
    t = time.monotonic()
    with dask_config({"conesurvey.connect-timeout": 1}):
        proc = runs.here(work, capsys, "run", "s.toml", "-o", "out.nc", "-q",
                         "--scheduler", f"tcp://127.0.0.1:{_port()}")  # fmt: skip
    assert proc.returncode == 1 and time.monotonic() - t < 10, proc.stderr
    err = proc.stderr
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "cannot reach the dask scheduler at tcp://127.0.0.1:" in err and "within 1 s" in err
    assert "s.toml" not in err  # not blamed on the survey file
    assert runs.listing(work) == ["s.toml"]

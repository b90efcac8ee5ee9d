"""``aes-swarm sweep`` on a real Dask cluster on this machine: a scheduler and two workers
started the standard way (``dask scheduler``, ``dask worker``) inside the test.

- the sweep on the cluster gives exactly the numbers of the same sweep run locally;
- a worker killed (SIGKILL) mid-sweep costs nothing: the sweep completes, identical.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers.ros_env import wait_for

BIN = Path(sys.executable).parent
#: 400 robots, 20 s, 4 runs a point, one point a task: a few tenths of a second each,
#: so that a worker can be killed while the sweep is under way.
SWEEP = [
    "--setup", "linear", "--robots", "400", "--duration", "20", "--runs", "4",
    "--param", "alpha=0.02:0.2:4", "--param", "d_theta=0:0.2:6", "--points-per-task", "1",
    "--no-progress",
]  # fmt: skip


@pytest.fixture
def cluster(tmp_path: Path):
    """A scheduler and two single-threaded workers; yields (address, worker processes)."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    file = tmp_path / "scheduler.json"
    logs = tmp_path / "dask-logs"
    logs.mkdir()
    procs: list[subprocess.Popen] = []

    def start(*args: str, name: str) -> subprocess.Popen:
        log = open(logs / f"{name}.log", "w")
        proc = subprocess.Popen(
            [str(BIN / "dask"), *args], env=env, stdout=log, stderr=subprocess.STDOUT,
            start_new_session=True,
        )  # fmt: skip
        procs.append(proc)
        return proc

    try:
        start("scheduler", "--scheduler-file", str(file), "--host", "127.0.0.1", "--port", "0",
              "--no-dashboard", name="scheduler")  # fmt: skip
        assert wait_for(file.exists, 60), (logs / "scheduler.log").read_text()
        address = json.loads(file.read_text())["address"]
        workers = [
            start(
                "worker",
                "--scheduler-file",
                str(file),
                "--nthreads",
                "1",
                "--nworkers",
                "1",
                "--no-dashboard",
                "--no-nanny",
                name=f"worker_{k}",
            )
            for k in range(2)
        ]
        yield address, workers
    finally:
        for proc in procs:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
        for proc in procs:
            try:
                proc.wait(15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(5)


def sweep(out: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [str(BIN / "aes-swarm"), "sweep", *SWEEP, "--out", str(out), *extra],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip


def finished(proc: subprocess.Popen, timeout: float = 300) -> str:
    out, _ = proc.communicate(timeout=timeout)
    assert proc.returncode == 0, out[-3000:]
    return out


def test_cluster_equals_local_and_survives_a_lost_worker(cluster, tmp_path):
    address, workers = cluster
    finished(sweep(tmp_path / "local"))
    local = {n: (tmp_path / "local" / n).read_text() for n in ("runs.csv", "points.csv")}
    assert local["runs.csv"].count("\n") == 1 + 24 * 4

    out = finished(sweep(tmp_path / "cluster", "--scheduler", address))
    assert f"on {address}" in out
    for name, text in local.items():
        assert (tmp_path / "cluster" / name).read_text() == text, name

    # a worker killed once the first points are in: its tasks run again on the other
    proc = sweep(tmp_path / "killed", "--scheduler", address)
    runs = tmp_path / "killed" / "runs.csv"
    assert wait_for(lambda: runs.exists() and runs.read_text().count("\n") > 1 + 4, 120)
    os.kill(workers[0].pid, signal.SIGKILL)
    killed_at = runs.read_text().count("\n") - 1
    time.sleep(0.1)
    finished(proc)
    assert killed_at < 24 * 4, "the sweep was over before the kill: nothing was shown"
    assert workers[0].wait(10) == -signal.SIGKILL
    for name, text in local.items():
        assert (tmp_path / "killed" / name).read_text() == text, name

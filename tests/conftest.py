"""Shared fixtures: an isolated ROS 2 environment per test and process cleanup.

``ros_env`` gives each test its own ``ROS_DOMAIN_ID`` (held with a file lock so
that parallel pytest runs on one machine never share one) and keeps discovery
on this host. ``spawn`` starts real processes in their own process groups and
guarantees they are stopped (SIGINT, then SIGKILL) and Fast DDS shared-memory
leftovers are cleaned when the test ends, pass or fail.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

LOCK_DIR = Path("/tmp/aes_swarm_ros_domains")
#: Domain ids handed to tests (0 is left to users; Linux allows up to 101).
DOMAIN_IDS = range(1, 101)


@contextlib.contextmanager
def reserved_domain_id() -> Iterator[int]:
    """Hold an unused ROS_DOMAIN_ID for the duration of the block."""
    LOCK_DIR.mkdir(exist_ok=True)
    start = os.getpid() % len(DOMAIN_IDS)
    for offset in range(len(DOMAIN_IDS)):
        domain = DOMAIN_IDS[(start + offset) % len(DOMAIN_IDS)]
        fh = open(LOCK_DIR / f"{domain}.lock", "w")  # held until the block ends
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.close()
            continue
        try:
            yield domain
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)
            fh.close()
        return
    raise RuntimeError("no free ROS_DOMAIN_ID")


@pytest.fixture
def ros_env(monkeypatch: pytest.MonkeyPatch) -> Iterator[dict[str, str]]:
    """Environment for this test's ROS processes (also applied to the test process)."""
    with reserved_domain_id() as domain:
        env = {
            "ROS_DOMAIN_ID": str(domain),
            "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "PYTHONUNBUFFERED": "1",
        }
        for key, value in env.items():
            monkeypatch.setenv(key, value)
        yield {**os.environ, **env}


class Processes:
    """Processes started by one test; all stopped by :meth:`stop_all`."""

    def __init__(self, env: dict[str, str], log_dir: Path) -> None:
        self.env, self.log_dir = env, log_dir
        self.procs: list[tuple[subprocess.Popen, Path]] = []

    def start(self, *cmd: str, name: str | None = None) -> subprocess.Popen:
        """Start ``cmd`` (a console script or ``python -m``) with the test's ROS env.

        Output goes to ``<tmp>/<name>.log``, shown when the test fails.
        """
        log = self.log_dir / f"{name or Path(cmd[0]).name}-{len(self.procs)}.log"
        exe = cmd[0]
        if not os.path.isabs(exe):
            local = Path(sys.executable).parent / exe
            exe = str(local) if local.exists() else exe
        proc = subprocess.Popen(
            [exe, *cmd[1:]],
            env=self.env,
            stdout=log.open("w"),
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        self.procs.append((proc, log))
        return proc

    def stop(self, proc: subprocess.Popen, timeout: float = 10.0) -> int:
        """SIGINT the process group, SIGKILL it if it has not exited in ``timeout`` s."""
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        return proc.returncode

    def stop_all(self) -> None:
        for proc, _ in reversed(self.procs):
            self.stop(proc)
        # Fast DDS leaves /dev/shm segments behind for processes that died hard.
        fastdds = Path(sys.executable).parent / "fastdds"
        if fastdds.exists():
            subprocess.run([str(fastdds), "shm", "clean"], capture_output=True, timeout=30)

    def logs(self) -> str:
        return "\n".join(f"--- {log.name}\n{log.read_text()[-3000:]}" for _, log in self.procs)


@pytest.fixture
def spawn(ros_env: dict[str, str], tmp_path: Path, request: pytest.FixtureRequest):
    """Start processes for a test; they are stopped when the test ends.

    Usage: ``spawn.start("aes-sim-bridge", "--ros-args", "-p", "lockstep:=true")``.
    """
    procs = Processes(ros_env, tmp_path)
    try:
        yield procs
    finally:
        procs.stop_all()
        report = getattr(request.node, "rep_call", None)
        if report is not None and report.failed:
            print(procs.logs())


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    rep = yield
    setattr(item, f"rep_{rep.when}", rep)
    return rep


def wait_for(predicate, timeout: float, interval: float = 0.05) -> bool:
    """Poll ``predicate`` until it is true or ``timeout`` s pass."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())

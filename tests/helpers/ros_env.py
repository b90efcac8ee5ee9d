"""A ROS 2 environment of the test's own and the processes it starts.

:func:`reserved_domain_id` hands out a ``ROS_DOMAIN_ID`` held with a file lock, so
that parallel pytest runs on one machine never share one. :class:`Processes` starts
console scripts (or ``python -m …``) with the test's environment through the
launcher's own :class:`~aes_ros.ros.launch.processes.ProcessSet` (process groups,
SIGINT then SIGKILL, the shared-memory clean), and knows each process's log.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shlex
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from aes_ros.ros.discovery import set_environ
from aes_ros.ros.launch.processes import Child, ProcessSet, domain_processes
from aes_ros.ros.launch.shared_memory import SHM_DIR, domain_port_files, mapped

#: Default wait [s] for a reply, a match or a service: generous, since other tests
#: may load the 2 cores.
TIMEOUT = 20.0
#: Where the domain locks live.
LOCK_DIR = Path("/tmp/aes_swarm_ros_domains")
#: Domain ids handed to tests (0 is left to users; Linux allows up to 101).
DOMAIN_IDS = range(1, 101)


@contextlib.contextmanager
def reserved_domain_id() -> Iterator[int]:
    """Hold an unused ROS_DOMAIN_ID for the duration of the block: one no other test
    holds and no live process is in (a process an earlier test left, still exiting, would
    talk to this test's nodes and count as its orphan)."""
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
        if _domain_processes(str(domain)):
            fcntl.flock(fh, fcntl.LOCK_UN)
            fh.close()
            continue
        try:
            yield domain
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)
            fh.close()
        return
    raise RuntimeError("no free ROS_DOMAIN_ID")


def ros_variables(domain: int) -> dict[str, str]:
    """The variables that put a process in ``domain``, discovering on this host only."""
    return {
        "ROS_DOMAIN_ID": str(domain),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "PYTHONUNBUFFERED": "1",
    }


def shell_variables(script: Path) -> dict[str, str | None]:
    """What sourcing ``script`` (``export NAME=value`` and ``unset NAME …`` lines, as in
    a launch's ``ros_env.sh``) does to the environment (None: unset)."""
    out: dict[str, str | None] = {}
    for line in Path(script).read_text().splitlines():
        words = shlex.split(line, comments=True)
        if words[:1] == ["export"]:
            out.update(word.split("=", 1) for word in words[1:])  # type: ignore[misc]
        elif words[:1] == ["unset"]:
            out.update((name, None) for name in words[1:])
    return out


@contextlib.contextmanager
def shell_environment(script: Path) -> Iterator[dict[str, str | None]]:
    """``os.environ`` as after sourcing ``script`` for the block (rclpy contexts made
    in it use it); restored after, and Fast DDS made to forget the discovery server:
    it keeps the last ``ROS_DISCOVERY_SERVER`` it read in a process and would make
    every later participant of the test process a client of that server
    (:mod:`aes_ros.ros.discovery`)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    changes = shell_variables(script)
    old = {name: os.environ.get(name) for name in changes}
    try:
        set_environ(changes)
        yield changes
    finally:
        set_environ({"ROS_DISCOVERY_SERVER": "", "ROS_SUPER_CLIENT": None})
        context = rclpy.Context()  # a participant (made with its first node) reads the ""
        rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node("forget_discovery_server", context=context)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        set_environ({"ROS_DISCOVERY_SERVER": None, **old})


def wait_for(predicate: Callable[[], object], timeout: float, interval: float = 0.05) -> bool:
    """Poll ``predicate`` until it is true or ``timeout`` s pass; its last value as a bool."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())


def processes_in_domain(domain: str) -> list[str]:
    """Command lines of live processes (other than this one) with this ROS_DOMAIN_ID."""
    return [cmdline for _, cmdline in _domain_processes(domain)]


def find_process(domain: str, needle: str) -> int:
    """The pid of the one live process of the domain whose command line holds ``needle``."""
    found = [pid for pid, cmdline in _domain_processes(domain) if needle in cmdline]
    assert len(found) == 1, f"{len(found)} processes match {needle!r}"
    return found[0]


def shm_files(domain: int | None = None) -> set[str]:
    """Fast DDS's shared-memory files (/dev/shm); with ``domain``, those of its own ports
    only: tests beside this one (``pytest -n``) make and leave files of their domains, and
    of the ports below 7400 that every domain shares, which no test can tell apart."""
    if domain is None:
        return {p.name for p in Path("/dev/shm").glob("*fastrtps*")}
    ports = domain_port_files(domain)
    return {p.name for port, files in ports.items() if port >= 7400 for p in files}


def abandoned_shm(before: set[str], domain: int | None = None) -> set[str]:
    """Fast DDS shared-memory files (of ``domain``) made since ``before`` that no live
    process maps: what processes that are gone left behind (a file the test's own probe
    still maps, as a peer of a dead process, is not abandoned yet)."""
    return {name for name in shm_files(domain) - before if not mapped(SHM_DIR / name)}


def _domain_processes(domain: str) -> list[tuple[int, str]]:
    return [(pid, " ".join(argv).strip()) for pid, argv in domain_processes(domain).items()]


def assert_no_orphans(ros_env: dict[str, str], timeout: float = 15.0) -> None:
    """Within ``timeout`` s, no process of the test's domain is left."""
    domain = ros_env["ROS_DOMAIN_ID"]
    deadline = time.monotonic() + timeout
    while processes_in_domain(domain) and time.monotonic() < deadline:
        time.sleep(0.2)
    left = _domain_processes(domain)  # (helpers get no assertion rewriting: name them)
    assert left == [], f"processes of domain {domain} left after {timeout:g} s: {left}"


class Processes:
    """The processes of one test: started with the test's ROS environment, each
    logging to ``<log_dir>/<name>.log`` (appended to: a process restarted under the
    same name keeps one log), all stopped by :meth:`stop_all`.

    ``env`` may be replaced before a :meth:`start` (e.g. another discovery range).
    """

    #: SIGINT, then SIGKILL after this many seconds.
    STOP_TIMEOUT = 10.0

    def __init__(self, env: dict[str, str], log_dir: Path) -> None:
        self._set = ProcessSet(log_dir, env)

    @property
    def env(self) -> dict[str, str]:
        return self._set.env

    @env.setter
    def env(self, value: dict[str, str]) -> None:
        self._set.env = {**value, "PYTHONUNBUFFERED": "1"}

    def start(self, *cmd: str, name: str | None = None) -> subprocess.Popen:
        """Start ``cmd`` (``cmd[0]`` a console script of this environment, a command
        on PATH or a path) as ``name`` (default: the command's name)."""
        return self._set.start(name or Path(cmd[0]).name, cmd).proc

    @property
    def procs(self) -> list[subprocess.Popen]:
        """Every process started, in order (a restarted one is there twice)."""
        return [c.proc for c in self._set.children]

    def _child(self, proc: subprocess.Popen) -> Child:
        return next(c for c in self._set.children if c.proc is proc)

    def log(self, proc: subprocess.Popen) -> Path:
        """The log file of ``proc``."""
        return self._child(proc).log

    def stop(self, proc: subprocess.Popen, timeout: float = STOP_TIMEOUT) -> int:
        """SIGINT the process group, SIGKILL it if it has not exited in ``timeout`` s;
        returns the exit code."""
        self._set.stop([self._child(proc)], timeout)
        return proc.returncode

    def stop_all(self) -> None:
        """Stop every process and remove Fast DDS's shared-memory leftovers."""
        self._set.stop_all(self.STOP_TIMEOUT)

    def logs(self, chars: int = 3000) -> str:
        """The end of every log (once per log file)."""
        seen: dict[Path, Child] = {}
        for child in self._set.children:
            seen.setdefault(child.log, child)
        return "\n".join(f"--- {log.name}\n{c.tail(chars)}" for log, c in seen.items())

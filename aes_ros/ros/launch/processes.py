"""Node processes in their own process groups, logging to files, stopped cleanly.

Used by the launcher and by the system tests (one implementation of "start a
ROS process, stop it with SIGINT, SIGKILL it if it hangs, clean up after it").
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from aes_ros.ros.launch.plan import LaunchError
from aes_ros.ros.launch.shared_memory import clean_shared_memory


def executable(name: str) -> str:
    """A console script of this environment (next to the interpreter), else from PATH;
    a path is returned as it is."""
    if os.sep in name:
        return name
    local = Path(sys.executable).parent / name
    if local.exists():
        return str(local)
    found = shutil.which(name)
    if found is None:
        raise LaunchError(f"{name}: console script not found (is aes-swarm installed?)")
    return found


@dataclass
class Child:
    """A started process: its name, command line, handle and log file."""

    name: str
    cmd: list[str]
    proc: subprocess.Popen
    log: Path

    def tail(self, chars: int = 2000) -> str:
        """The last ``chars`` characters of the log ("" if unreadable)."""
        try:
            text = self.log.read_text(errors="replace")
        except OSError:
            return ""
        return text[-chars:]


class ProcessSet:
    """Child processes, each in its own session/process group, logging to
    ``log_dir/<name>.log`` (appended to, so a restarted process keeps one log).

    With ``pid_file`` the pids of the live children are kept in that file (one per
    line, rewritten at every start) for :mod:`aes_ros.ros.launch.reaper`.
    """

    def __init__(
        self, log_dir: Path, env: dict[str, str] | None = None, pid_file: Path | None = None
    ) -> None:
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = {**os.environ, **(env or {}), "PYTHONUNBUFFERED": "1"}
        self.children: list[Child] = []
        self.pid_file = pid_file

    def start(self, name: str, cmd: Sequence[str]) -> Child:
        """Start ``cmd`` (``cmd[0]`` a console script name or a path) as ``name``."""
        argv = [executable(cmd[0]), *cmd[1:]]
        log = self.log_dir / f"{name}.log"
        with open(log, "a") as fh:
            proc = subprocess.Popen(
                argv,
                env=self.env,
                stdin=subprocess.DEVNULL,
                stdout=fh,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                preexec_fn=_die_with_parent,
            )
        child = Child(name, argv, proc, log)
        self.children.append(child)
        if self.pid_file is not None:
            live = [str(c.proc.pid) for c in self.children if c.proc.poll() is None]
            temporary = self.pid_file.with_name("." + self.pid_file.name + ".tmp")
            temporary.write_text("\n".join(live) + "\n")
            os.replace(temporary, self.pid_file)
        return child

    def dead(self) -> list[Child]:
        """Children that have exited."""
        return [c for c in self.children if c.proc.poll() is not None]

    def stop(self, children: Sequence[Child], timeout: float) -> list[str]:
        """SIGINT each child's process group, SIGKILL the groups still alive after
        ``timeout`` s. Returns the names of the killed ones."""
        for c in children:
            if c.proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(c.proc.pid, signal.SIGINT)
        deadline = time.monotonic() + timeout
        killed = []
        for c in children:
            try:
                c.proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                killed.append(c.name)
            # Anything left in the group (a grandchild, or the child itself) goes now.
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(c.proc.pid, signal.SIGKILL)
            c.proc.wait()
        return killed

    def stop_all(self, timeout: float, last: Sequence[Child] = ()) -> list[str]:
        """Stop every child; those in ``last`` only after all others have exited; then
        remove the shared-memory files they left (in their ROS domain)."""
        first = [c for c in self.children if c not in last]
        killed = self.stop(first, timeout) + self.stop(list(last), timeout)
        clean_shared_memory(ros_domain(self.env))
        return killed


def _die_with_parent() -> None:
    """In the child before exec: get SIGTERM if the parent dies (Linux), so that
    even a SIGKILLed launcher leaves no orphans behind."""
    with contextlib.suppress(Exception):
        import ctypes

        PR_SET_PDEATHSIG = 1
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


#: The Fast DDS profile of the processes a launch starts (faster rediscovery).
FASTDDS_PROFILE = Path(__file__).resolve().parents[1] / "fastdds_profile.xml"
PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


def fastdds_environment(env: dict[str, str]) -> dict[str, str]:
    """``env`` with :data:`FASTDDS_PROFILE` as the default profile, unless it names one."""
    if any(env.get(name) for name in PROFILE_VARIABLES):
        return dict(env)
    return {**env, "FASTRTPS_DEFAULT_PROFILES_FILE": str(FASTDDS_PROFILE)}


def ros_domain(env: dict[str, str]) -> int:
    """The ROS domain id of an environment (0 when unset or not a number)."""
    value = env.get("ROS_DOMAIN_ID", "0")
    return int(value) if value.isdigit() else 0

"""Node processes in their own process groups, logging to files, stopped cleanly.

Used by the launcher and by the system tests (one implementation of "start a
ROS process, stop it with SIGINT, SIGKILL it if it hangs, clean up after it").
"""

from __future__ import annotations

import contextlib
import functools
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from aes_ros.ros.launch.shared_memory import clean_shared_memory
from aes_ros.ros.programs import LaunchError, executable


@dataclass
class Child:
    """A started process: its name, command line, handle and log file; ``start`` is
    the byte of the log where this process's output begins (a log is appended to: by a
    restarted process, and by every launch into the same output directory)."""

    name: str
    cmd: list[str]
    proc: subprocess.Popen
    log: Path
    start: int = 0

    def output(self) -> str:
        """What this process has written to its log ("" if unreadable): never an earlier
        process's, whose ready line would end a wait at once."""
        try:
            with open(self.log, "rb") as fh:
                fh.seek(self.start)
                return fh.read().decode(errors="replace")
        except OSError:
            return ""

    def tail(self, chars: int = 2000) -> str:
        """The last ``chars`` characters of this process's output."""
        return self.output()[-chars:]

    def last_line(self) -> str:
        """The last line of this process's output ("" if there is none)."""
        lines = self.tail(300).strip().splitlines()
        return lines[-1] if lines else ""

    def line_after(self, text: str) -> str | None:
        """What follows ``text`` on the first line of this process's output that holds it
        (stripped)."""
        for line in self.tail(100_000).splitlines():
            if text in line:
                return line.split(text, 1)[1].strip()
        return None

    def check_running(self) -> None:
        """LaunchError with the end of its log if it has exited."""
        if self.proc.poll() is not None:
            code = self.proc.returncode
            raise LaunchError(f"{self.name} exited with code {code}:\n{self.tail()}")

    def wait_for(
        self, text: str, timeout: float, stopped: Callable[[], bool] = lambda: False
    ) -> None:
        """Wait until the log holds ``text`` (a ready signal, :mod:`aes_ros.ros.interface`)
        or ``stopped()``; LaunchError if the process exits or ``timeout`` s pass first."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.tail(100_000) or stopped():
                return
            if self.proc.poll() is not None:
                raise LaunchError(f"{self.name} exited with {self.proc.returncode}:\n{self.tail()}")
            time.sleep(0.05)
        raise LaunchError(f"{self.name} did not start within {timeout:.0f} s")


class ProcessSet:
    """Child processes, each in its own session/process group, logging to
    ``log_dir/<name>.log`` (appended to, so a restarted process keeps one log).

    Each child gets SIGTERM from the kernel when the thread that started it dies
    (:func:`die_with_parent`). With ``pid_file`` the live children are kept in that
    file (a line ``<pid> <start time>`` each, rewritten at every start) for
    :mod:`aes_ros.ros.launch.reaper`. ``env_for``
    holds what differs from ``env`` for a process of a given name, at every start of it
    (e.g. the recorder as a discovery server's super client).
    """

    def __init__(
        self, log_dir: Path, env: dict[str, str] | None = None, pid_file: Path | None = None
    ) -> None:
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = {**os.environ, **(env or {}), "PYTHONUNBUFFERED": "1"}
        self.env_for: dict[str, dict[str, str]] = {}
        self.children: list[Child] = []
        self.pid_file = pid_file

    def start(self, name: str, cmd: Sequence[str]) -> Child:
        """Start ``cmd`` (``cmd[0]`` a console script name or a path) as ``name``."""
        argv = [executable(cmd[0]), *cmd[1:]]
        log = self.log_dir / f"{name}.log"
        with open(log, "a") as fh:
            start = fh.tell()
            proc = subprocess.Popen(
                [*die_with_parent(), *argv],
                env={**self.env, **self.env_for.get(name, {})},
                stdin=subprocess.DEVNULL,
                stdout=fh,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        child = Child(name, argv, proc, log, start)
        self.children.append(child)
        if self.pid_file is not None:
            live = [c.proc.pid for c in self.children if c.proc.poll() is None]
            started = {pid: start_time(pid) for pid in live}  # not reaped yet: still there
            lines = "".join(f"{pid} {t}\n" for pid, t in started.items() if t is not None)
            temporary = self.pid_file.with_name("." + self.pid_file.name + ".tmp")
            temporary.write_text(lines)
            os.replace(temporary, self.pid_file)
        return child

    def dead(self) -> list[Child]:
        """Children that have exited."""
        return [c for c in self.children if c.proc.poll() is not None]

    def check_alive(self) -> None:
        """LaunchError naming the first child that has exited, with the end of its log."""
        dead = self.dead()
        if dead:
            c = dead[0]
            raise LaunchError(
                f"{c.name} exited with code {c.proc.returncode} during the run; "
                f"its log ({c.log}) ends:\n{c.tail()}"
            )

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

    def exit_codes(self) -> dict[str, int]:
        """Each process's exit code (its last instance: the earlier ones of a restarted
        process had their say in events.csv)."""
        return {c.name: c.proc.returncode for c in self.children}

    def stop_summary(self, killed: Sequence[str]) -> str:
        """One line on how the children stopped (``killed``: those SIGKILLed)."""
        codes = self.exit_codes()
        unclean = {k: v for k, v in codes.items() if v != 0 and k not in killed}
        if unclean:
            listed = ", ".join(f"{k} ({v})" for k, v in unclean.items())
            return (
                "exit codes other than 0 (-N: ended by signal N before its node was up): "
                f"{listed}; logs in {self.log_dir}"
            )
        if not killed:
            return f"all {len(codes)} processes stopped cleanly"
        return f"{len(codes) - len(killed)} of {len(codes)} processes stopped cleanly"


@functools.cache
def die_with_parent() -> tuple[str, ...]:
    """The command prefix that makes a child get SIGTERM when its parent dies (Linux's
    parent-death signal), so that even a SIGKILLed launcher leaves no orphans behind:
    util-linux's ``setpriv``, one exec more, since a launcher runs threads and a
    ``preexec_fn`` may deadlock in a child forked from one. Empty where there is no
    ``setpriv`` with ``--pdeathsig``: then the reaper SIGKILLs the orphans (as it
    does a child whose parent died in the milliseconds before ``setpriv`` set the
    signal)."""
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        return ()
    try:
        usage = subprocess.run([setpriv, "--help"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return ()
    return (setpriv, "--pdeathsig", "TERM", "--") if "--pdeathsig" in usage.stdout else ()


def start_time(pid: int) -> int | None:
    """When process ``pid`` started, in clock ticks since boot (``/proc/<pid>/stat``
    field 22), or None if there is no such process: with the pid, it names one process
    (a pid alone may be another process's by now)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return int(stat.rsplit(")", 1)[1].split()[19])


#: The Fast DDS profile of the processes a launch starts (faster rediscovery).
FASTDDS_PROFILE = Path(__file__).resolve().parents[1] / "fastdds_profile.xml"
PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


#: The simulated camera's profile: :data:`FASTDDS_PROFILE` with a 32 MB shared-memory
#: segment, so that its frames go through shared memory rather than UDP.
IMAGES_PROFILE = FASTDDS_PROFILE.with_name("fastdds_images.xml")


def names_a_profile(env: Mapping[str, str]) -> bool:
    """Whether ``env`` names a Fast DDS profile file of its own (the caller's wins)."""
    return any(env.get(name) for name in PROFILE_VARIABLES)


def images_environment(env: Mapping[str, str]) -> dict[str, str]:
    """What the camera's environment adds to the launch's: :data:`IMAGES_PROFILE`, unless
    ``env`` (the caller's) names a profile of its own."""
    if names_a_profile(env):
        return {}
    return {"FASTRTPS_DEFAULT_PROFILES_FILE": str(IMAGES_PROFILE)}


def fastdds_environment(env: dict[str, str]) -> dict[str, str]:
    """``env`` with :data:`FASTDDS_PROFILE` as the default profile, unless it names one."""
    if names_a_profile(env):
        return dict(env)
    return {**env, "FASTRTPS_DEFAULT_PROFILES_FILE": str(FASTDDS_PROFILE)}


def ros_domain(env: dict[str, str]) -> int:
    """The ROS domain id of an environment (0 when unset or not a number)."""
    value = env.get("ROS_DOMAIN_ID", "0")
    return int(value) if value.isdigit() else 0


def domain_processes(domain: str | int) -> dict[int, list[str]]:
    """pid -> command line of the live processes (zombies and this one left out) whose
    environment has ``ROS_DOMAIN_ID=domain``: what a launch in that domain left running."""
    found = {}
    needle = f"ROS_DOMAIN_ID={domain}".encode()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if needle not in (entry / "environ").read_bytes().split(b"\0"):
                continue
            if (entry / "stat").read_text().rsplit(")", 1)[1].split()[0] == "Z":
                continue
            found[int(entry.name)] = (entry / "cmdline").read_bytes().decode().split("\0")
        except OSError:
            continue
    return found

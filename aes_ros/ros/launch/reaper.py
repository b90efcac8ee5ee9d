"""Cleans up after a launcher that died: ``python -m aes_ros.ros.launch.reaper PIDS_FILE``.

The launcher starts it first, in a session of its own, with a pipe as its
standard input, and never writes to the pipe. When the launcher exits (cleanly
or killed with SIGKILL) the pipe closes and this process wakes up: it waits up
to ``--grace`` seconds for the node processes listed in ``PIDS_FILE`` (one pid
per line; they get SIGTERM from the kernel when their parent dies and shut down
cleanly), SIGKILLs what is left, and removes the Fast DDS shared-memory files
they left in the launcher's ROS domain
(:func:`aes_ros.ros.launch.shared_memory.clean_shared_memory`).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from aes_ros.ros.launch.processes import ros_domain
from aes_ros.ros.launch.shared_memory import clean_shared_memory

#: Seconds the reaper waits for live peers (a ``ros2 topic echo``, a test's probe) to let
#: go of the dead processes' ports before it removes them. Nobody waits for the reaper,
#: so it waits longer than a launch's own stop (2 s): on a loaded machine a peer held a
#: port for more than 2 s, and the file was left behind once it let go (seen in CI).
SETTLE = 10.0


def alive(pid: int) -> bool:
    """True if ``pid`` runs and is not a zombie."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def start_reaper(pid_file: Path, log: Path) -> int:
    """Start a reaper for the processes listed in ``pid_file``; returns the write end
    of its pipe, which the caller keeps open until it is done (never writes to it)."""
    read_end, write_end = os.pipe()
    with open(log, "a") as out:
        subprocess.Popen(
            [sys.executable, "-m", "aes_ros.ros.launch.reaper", str(pid_file)],
            stdin=read_end,
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    os.close(read_end)
    return write_end


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pids", type=Path, help="file with the pids to wait for")
    parser.add_argument("--grace", type=float, default=15.0, help="seconds to wait for them")
    args = parser.parse_args(argv)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a Ctrl-C meant for the launcher
    while os.read(sys.stdin.fileno(), 4096):  # until the launcher's end of the pipe closes
        pass
    try:
        pids = [int(p) for p in args.pids.read_text().split()]
    except (OSError, ValueError):
        pids = []
    deadline = time.monotonic() + args.grace
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    for pid in pids:
        if alive(pid):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(pid, signal.SIGKILL)
    clean_shared_memory(ros_domain(dict(os.environ)), settle=SETTLE)
    return 0


if __name__ == "__main__":
    sys.exit(main())

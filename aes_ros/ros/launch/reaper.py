"""Cleans up after a launcher that died: ``python -m aes_ros.ros.launch.reaper PIDS_FILE``.

The launcher starts it first, in a session of its own, with a pipe as its
standard input, and writes to the pipe only :data:`STOPPED`, once it has stopped
every process itself without a SIGKILL. When the launcher exits (cleanly or killed
with SIGKILL) the pipe closes and this process wakes up: it waits up to ``--grace``
seconds for the node processes listed in ``PIDS_FILE`` (a line ``<pid> <start
time>`` each; they get SIGTERM from the kernel when their parent dies and shut down
cleanly), SIGKILLs the process groups of those left, and removes the Fast DDS
shared-memory files they left in the launcher's ROS domain
(:func:`aes_ros.ros.launch.shared_memory.clean_shared_memory`), for :data:`LINGER`
seconds unless the launcher said :data:`STOPPED`. A pid whose process started at
another time than listed is another process's by now: it is left alone.
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

from aes_ros.ros.launch.processes import ros_domain, start_time
from aes_ros.ros.launch.shared_memory import clean_shared_memory

#: Seconds the reaper goes on cleaning after the children are gone. A live peer (a
#: ``ros2 topic echo``, a test's probe) keeps sending to a killed participant's port (the
#: launcher's own, or a child's SIGKILLed after the grace) until that participant's lease
#: runs out (Fast DDS's default, 20 s), and makes the port again if it was removed; once
#: it drops the participant it removes the port but may leave its lock file and mutex
#: (seen in CI: a clean that ended at once left them). So a lease and a margin.
LINGER = 30.0
#: What a launcher writes to the reaper's pipe once it has stopped every process,
#: none SIGKILLed (each said goodbye, so no peer makes a port of theirs again).
STOPPED = b"stopped"
#: Seconds at most the reaper waits for live peers to let go of the dead processes'
#: ports (a peer that still maps one) before it gives up on them.
SETTLE = 40.0
#: Seconds :func:`reap` waits for the processes it SIGKILLed to be gone.
KILL_WAIT = 10.0


def alive(pid: int, started: int) -> bool:
    """True if ``pid`` is still the process that started at ``started`` (clock ticks
    since boot) and is not a zombie."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return False
    return fields[0] != "Z" and int(fields[19]) == started


def read_pid_file(path: Path) -> list[tuple[int, int]]:
    """The (pid, start time) pairs of a pid file; lines that are not two numbers are
    skipped (a pid without its start time cannot be told from a reused one)."""
    try:
        lines = path.read_text().splitlines()
    except OSError:
        return []
    entries = []
    for line in lines:
        words = line.split()
        if len(words) == 2 and all(word.isdigit() for word in words):
            entries.append((int(words[0]), int(words[1])))
    return entries


def reap(entries: list[tuple[int, int]], grace: float) -> list[int]:
    """Wait up to ``grace`` s for the processes of ``entries`` (pid, start time) to
    exit, then SIGKILL the process groups of those still running and wait (up to
    :data:`KILL_WAIT` s) until they are gone; returns their pids.
    A pid running another process than the one listed is left alone (and said so)."""
    _wait_gone(entries, grace, 0.1)
    killed = []
    for pid, started in entries:
        if alive(pid, started):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(pid, signal.SIGKILL)
                killed.append((pid, started))
        elif (now := start_time(pid)) is not None:
            print(f"reaper: pid {pid} is another process now (started at {now}, "
                  f"not {started}): left alone", flush=True)  # fmt: skip
    # A killed process tears its memory down before it closes its files: until it is
    # gone its Fast DDS locks look live, and the clean after this would leave its ports.
    _wait_gone(killed, KILL_WAIT, 0.02)
    return [pid for pid, _ in killed]


def _wait_gone(entries: list[tuple[int, int]], timeout: float, poll: float) -> None:
    """Wait up to ``timeout`` s, polling every ``poll`` s, until none of the processes of
    ``entries`` (pid, start time) is :func:`alive`."""
    deadline = time.monotonic() + timeout
    while any(alive(*entry) for entry in entries) and time.monotonic() < deadline:
        time.sleep(poll)


def start_reaper(pid_file: Path, log: Path) -> int:
    """Start a reaper for the processes listed in ``pid_file``; returns the write end
    of its pipe, which the caller keeps open until it is done, and writes
    :data:`STOPPED` to before it closes it if it stopped every process itself."""
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
    said = b""
    while chunk := os.read(sys.stdin.fileno(), 4096):  # until the launcher's end closes
        said += chunk
    reap(read_pid_file(args.pids), args.grace)
    # after a clean stop every participant said goodbye: no peer makes a port again
    linger = 0.0 if said == STOPPED else LINGER
    clean_shared_memory(ros_domain(dict(os.environ)), settle=SETTLE, linger=linger)
    return 0


if __name__ == "__main__":
    sys.exit(main())

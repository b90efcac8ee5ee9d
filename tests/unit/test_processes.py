"""The launch's child processes (:mod:`aes_ros.ros.launch.processes`)."""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from aes_ros.ros.launch.processes import ProcessSet, die_with_parent, start_time
from aes_ros.ros.launch.reaper import STOPPED, alive, read_pid_file, reap
from aes_ros.ros.programs import LaunchError


def test_a_wait_reads_only_this_process_s_output(tmp_path: Path) -> None:
    """A log is appended to (by a restarted process, by a second launch into the same
    ``--out``): the ready line of the earlier process must not end the new one's wait,
    nor give its ``line_after`` (a dashboard's URL)."""
    procs = ProcessSet(tmp_path)
    ready = [sys.executable, "-c", "print('dashboard ready at http://old', flush=True)"]
    first = procs.start("dashboard", ready)
    first.wait_for("dashboard ready", 30.0)
    first.proc.wait(30)
    slow = [sys.executable, "-c", "import time; print('starting', flush=True); time.sleep(30)"]
    second = procs.start("dashboard", slow)
    try:
        with pytest.raises(LaunchError, match="did not start"):
            second.wait_for("dashboard ready", 1.0)
        assert second.line_after("dashboard ready at") is None
        assert second.tail().strip() == "starting"
        assert "http://old" in (tmp_path / "dashboard.log").read_text()  # one log, kept
    finally:
        procs.stop_all(5.0)


def test_a_pid_file_names_each_live_child_with_its_start_time(tmp_path: Path) -> None:
    procs = ProcessSet(tmp_path, pid_file=tmp_path / "pids")
    try:
        children = [procs.start(f"sleep_{k}", ["sleep", "30"]) for k in range(2)]
        entries = read_pid_file(tmp_path / "pids")
        assert entries == [(c.proc.pid, start_time(c.proc.pid)) for c in children]
        assert all(alive(*entry) for entry in entries)
    finally:
        procs.stop_all(5.0)


def test_the_reaper_kills_only_the_processes_it_was_given(tmp_path: Path) -> None:
    """A listed pid whose process started at another time than listed (the pid was
    reused by then) is left alone; the listed process itself is killed."""
    listed = subprocess.Popen(["sleep", "30"], start_new_session=True)
    reused = subprocess.Popen(["sleep", "30"], start_new_session=True)
    try:
        started = start_time(listed.pid)
        wrong = start_time(reused.pid) - 1  # type: ignore[operator]
        assert started is not None
        killed = reap([(listed.pid, started), (reused.pid, wrong)], grace=0.2)
        assert killed == [listed.pid]
        assert listed.wait(10) == -signal.SIGKILL
        assert reused.poll() is None
    finally:
        for proc in (listed, reused):
            proc.kill()
            proc.wait()


HOLDS_A_LOCK = """
import fcntl, signal, sys, time
signal.signal(signal.SIGTERM, signal.SIG_IGN)  # a node that does not stop in time
lock = open(sys.argv[1], "w")
fcntl.flock(lock, fcntl.LOCK_EX)
memory = bytearray(1 << 30)
memory[:: 1 << 12] = b"\\1" * (len(memory) >> 12)  # 1 GiB in use: a slow exit
print("ready", flush=True)
time.sleep(60)
"""


def test_a_process_the_reaper_kills_has_let_go_of_its_files_when_reap_returns(
    tmp_path: Path,
) -> None:
    """The reaper cleans shared memory right after :func:`reap`: a lock still held by a
    process killed but not yet gone would make its port look live and be left behind
    (a dying process tears its memory down before it closes its files)."""
    lock_path = tmp_path / "port_el"
    child = subprocess.Popen(
        [sys.executable, "-c", HOLDS_A_LOCK, str(lock_path)],
        stdout=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    try:
        assert child.stdout is not None and child.stdout.readline() == "ready\n"
        started = start_time(child.pid)
        assert started is not None
        assert reap([(child.pid, started)], grace=0.2) == [child.pid]
        with open(lock_path) as lock:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)  # free: raises if still held
    finally:
        child.kill()
        child.wait()


def test_the_reaper_lingers_only_after_a_launcher_that_did_not_stop_its_processes(
    tmp_path: Path,
) -> None:
    """A launcher that stopped every process itself writes STOPPED to the reaper's pipe:
    the reaper cleans once and exits. A killed one writes nothing: the reaper goes on
    cleaning for LINGER seconds (peers may make a dead participant's port again)."""
    pids = tmp_path / "pids"
    pids.write_text("")
    env = {**os.environ, "ROS_DOMAIN_ID": "231"}  # a domain no test uses: nothing to remove

    def reaper(said: bytes) -> subprocess.Popen:
        proc = subprocess.Popen(
            [sys.executable, "-m", "aes_ros.ros.launch.reaper", str(pids)],
            stdin=subprocess.PIPE, env=env, start_new_session=True,
        )  # fmt: skip
        assert proc.stdin is not None
        proc.stdin.write(said)
        proc.stdin.close()  # the launcher exits
        return proc

    told, killed = reaper(STOPPED), reaper(b"")
    try:
        assert told.wait(20) == 0
        time.sleep(1.0)
        assert killed.poll() is None  # still cleaning
    finally:
        for proc in (told, killed):
            proc.kill()
            proc.wait()


def test_the_reaper_starts_alone_and_without_a_warning() -> None:
    """Every launch starts the reaper (``python -m aes_ros.ros.launch.reaper``) beside its
    nodes: it loads neither the launcher nor rclpy, and runpy has no module of the
    package loaded twice to warn about in its log."""
    probe = (
        "import runpy, sys, warnings\n"
        "warnings.simplefilter('error')\n"
        "sys.argv = ['reaper', '--help']\n"
        "try:\n"
        "    runpy.run_module('aes_ros.ros.launch.reaper', run_name='__main__')\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(*sorted(m for m in ('rclpy', 'numba', 'aes_ros.ros.launch.launcher')"
        " if m in sys.modules))\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == ""


#: A launcher stand-in: starts a child through a ProcessSet from a thread (the launcher
#: runs threads), says its pid, and waits to be killed.
PARENT = """
import sys, threading, time
from pathlib import Path
from aes_ros.ros.launch.processes import ProcessSet
procs = ProcessSet(Path(sys.argv[1]))
threading.Thread(target=time.sleep, args=(60,), daemon=True).start()
print(procs.start("sleep", ["sleep", "60"]).proc.pid, flush=True)
time.sleep(60)
"""


@pytest.mark.skipif(not die_with_parent(), reason="no setpriv with --pdeathsig")
def test_children_of_a_killed_parent_get_sigterm(tmp_path: Path) -> None:
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, str(tmp_path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert parent.stdout is not None
        child = int(parent.stdout.readline())
        started = start_time(child)
        assert started is not None and alive(child, started)
        cmdline = Path(f"/proc/{child}/cmdline")
        deadline = time.monotonic() + 10.0
        while Path(cmdline.read_bytes().split(b"\0")[0].decode()).name != "sleep":
            assert time.monotonic() < deadline, "the child never ran its command"
            time.sleep(0.01)  # setpriv has set the signal once it has exec'd the command
    finally:
        parent.kill()
        parent.wait()
    deadline = time.monotonic() + 10.0
    while alive(child, started) and time.monotonic() < deadline:
        time.sleep(0.05)
    if alive(child, started):
        os.kill(child, signal.SIGKILL)
        pytest.fail("the child outlived its killed parent")

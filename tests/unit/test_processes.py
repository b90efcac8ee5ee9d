"""The launch's child processes (:mod:`aes_ros.ros.launch.processes`)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from aes_ros.ros.launch.plan import LaunchError
from aes_ros.ros.launch.processes import ProcessSet


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

"""``aes-swarm steer --disable`` / ``--enable`` and ``scripts/steer.sh off`` against a real
supervisor: the latched ``/swarm/enabled`` follows, the answer is printed."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from helpers.ros_env import TIMEOUT
from std_msgs.msg import Bool

from aes_ros.ros import interface as names
from aes_ros.ros.qos import LATCHED

REPO = Path(__file__).resolve().parents[2]
SUPERVISOR = ["aes-supervisor", "--ros-args", "-p", "scenario:=linear", "-p", "num_robots:=4"]


def run(env: dict[str, str], *cmd: str) -> subprocess.CompletedProcess[str]:
    path = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return subprocess.run(
        cmd, env={**env, "PATH": path}, capture_output=True, text=True, timeout=3 * TIMEOUT
    )


def test_steer_disables_and_enables_the_swarm(spawn, probe, ros_env):
    enabled = probe.record(Bool, names.ENABLED, LATCHED)
    timeout = ["--timeout", f"{TIMEOUT:g}"]
    # nobody answers yet: exit 1 with the reason, nothing changed
    early = run(ros_env, "aes-swarm", "steer", "--disable", "--timeout", "1")
    assert early.returncode == 1 and "no /swarm/enable service" in early.stderr

    spawn.start(*SUPERVISOR, name="supervisor")
    probe.wait(lambda: enabled, TIMEOUT, "the latched /swarm/enabled")
    assert enabled[-1].data is True

    off = run(ros_env, str(REPO / "scripts" / "steer.sh"), "off")
    assert off.returncode == 0, off.stderr
    assert off.stdout.strip() == "steer: /swarm/enable false: disabled"
    probe.wait(lambda: enabled[-1].data is False, TIMEOUT, "/swarm/enabled false")

    on = run(ros_env, "aes-swarm", "steer", "--enable", *timeout)
    assert on.returncode == 0, on.stderr
    assert on.stdout.strip() == "steer: /swarm/enable true: enabled"
    probe.wait(lambda: enabled[-1].data is True, TIMEOUT, "/swarm/enabled true")

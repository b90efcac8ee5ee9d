"""Throttled warnings and publish counters shared by the nodes (aes_ros.ros.node_tools)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from aes_ros.ros import node_tools
from aes_ros.ros.node_tools import PublishCounter, ThrottledWarnings


class Logger:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def warning(self, text: str) -> None:
        self.lines.append(text)


def test_warnings_are_throttled_per_kind(monkeypatch: pytest.MonkeyPatch) -> None:
    now = [100.0]
    monkeypatch.setattr(node_tools.time, "monotonic", lambda: now[0])
    log = Logger()
    warn = ThrottledWarnings(log, period=5.0)
    assert warn("dropped /swarm/poses: NaN")
    assert not warn("dropped /swarm/poses: 3 poses")  # same kind, within 5 s
    assert warn("dropped odom: NaN")  # another kind is not silenced by the first
    now[0] += 5.0
    assert warn("dropped /swarm/poses: 3 poses")
    assert log.lines == [
        "dropped /swarm/poses: NaN",
        "dropped odom: NaN",
        "dropped /swarm/poses: 3 poses",
    ]


class Publisher:
    def __init__(self, topic: str) -> None:
        self.topic_name = topic
        self.sent: list[object] = []

    def publish(self, msg: object) -> None:
        self.sent.append(msg)


def test_publish_counter_publishes_and_counts_per_topic() -> None:
    counter = PublishCounter()
    cmd, enabled = Publisher("/mona_3/cmd_vel"), Publisher("/swarm/enabled")
    for i in range(3):
        counter.publish(cmd, i)
    counter.publish(enabled, True)
    assert cmd.sent == [0, 1, 2] and enabled.sent == [True]
    assert counter.counts == {"/mona_3/cmd_vel": 3, "/swarm/enabled": 1}
    assert counter.line("/mona_3") == "/mona_3: /mona_3/cmd_vel 3, /swarm/enabled 1"


@pytest.mark.parametrize(
    "script", ["aes-robot-host", "aes-robot-node", "aes-sim-bridge", "aes-supervisor"]
)
def test_help_prints_the_usage_and_starts_no_node(script: str) -> None:
    """rclpy ignores --help: a node script must answer it instead of starting a node
    (``aes-robot-host --help`` once ran a 100-robot host in domain 0 for minutes)."""
    exe = Path(sys.executable).with_name(script)
    done = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"usage: {script} [--ros-args")
    assert "Parameters" in done.stdout or "parameters" in done.stdout

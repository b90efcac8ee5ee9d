"""Throttled warnings and publish counters shared by the nodes (aes_ros.ros.node_tools)."""

from __future__ import annotations

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

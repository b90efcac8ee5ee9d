"""bench/firmware_latency.py's matching of PWM changes and wheel_cmd messages to the
cmd_vel publications that caused them (a script, loaded by path; no ROS)."""

from __future__ import annotations

from collections.abc import Iterator
from types import ModuleType

import pytest
from helpers.bench import bench_module


@pytest.fixture(scope="module")
def latency() -> Iterator[ModuleType]:
    with bench_module("firmware_latency") as module:
        yield module


def test_each_change_is_timed_from_the_publication_of_its_speed(latency: ModuleType) -> None:
    sends = [(0.00, 1), (0.05, 0), (0.10, 1), (0.15, 0)]
    # speed 1 seen 3 ms after its publication, speed 0 late (after the next publication)
    events = [(0.003, 1), (0.052, 0), (0.112, 1), (0.160, 0)]
    assert latency.latencies_ms(sends, events) == pytest.approx([3.0, 2.0, 12.0, 10.0])


def test_repeats_and_events_without_a_publication_are_not_latencies(
    latency: ModuleType,
) -> None:
    sends = [(1.0, 1), (1.05, 0)]
    # before any publication; the same speed again (a republish); far too late
    events = [(0.5, 0), (1.002, 1), (1.03, 1), (1.06, 0)]
    assert latency.latencies_ms(sends, events) == pytest.approx([2.0, 10.0])
    assert latency.latencies_ms(sends, [(1.5, 0)]) == []

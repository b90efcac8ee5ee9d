"""The bridge's pure parts: the lockstep barrier and the control-loop figures."""

from __future__ import annotations

import pytest

from sim_bridge.lockstep import LockstepBarrier
from sim_bridge.loop_stats import ControlLoopStats


def test_barrier_opens_only_when_every_robot_answered() -> None:
    barrier = LockstepBarrier(3)
    assert not barrier.complete and barrier.missing().tolist() == [0, 1, 2]
    barrier.arrived(2)
    barrier.arrived(2)  # a second command of the same robot does not count twice
    barrier.arrived(0)
    assert not barrier.complete and barrier.missing().tolist() == [1]
    barrier.arrived(1)
    assert barrier.complete
    barrier.next_step()
    assert not barrier.complete and barrier.missing().tolist() == [0, 1, 2]


def test_loop_stats_give_rates_latencies_and_real_time_factor() -> None:
    stats = ControlLoopStats(n=2, now=10.0, step=0, dt=0.05)
    for k in range(20):  # robot 0 answers every step, robot 1 every other one
        stats.command(0, 0.004)
        if k % 2 == 0:
            stats.command(1, 0.010)
    snap = stats.snapshot(now=11.0, step=20)
    assert snap["wall_s"] == pytest.approx(1.0) and snap["sim_s"] == pytest.approx(1.0)
    assert snap["real_time_factor"] == pytest.approx(1.0)
    assert (snap["rate_min_hz"], snap["rate_median_hz"], snap["commands"]) == (10.0, 15.0, 30)
    assert snap["latency_p50_ms"] == pytest.approx(4.0) and snap["latency_max_ms"] == 10.0
    again = stats.snapshot(now=12.0, step=30)  # counters start over
    assert again["commands"] == 0 and again["latency_p99_ms"] is None
    assert again["real_time_factor"] == pytest.approx(0.5)

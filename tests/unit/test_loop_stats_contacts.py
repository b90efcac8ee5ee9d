"""The bridge's /sim/stats figures of the bodies (sim_bridge.loop_stats): contacts per
second of sim time and the smallest centre distance, per window between snapshots."""

from __future__ import annotations

import json
import math

import pytest

from sim_bridge.loop_stats import ControlLoopStats


def test_contacts_per_second_and_closest_distance_per_window() -> None:
    stats = ControlLoopStats(n=3, now=0.0, step=0, dt=0.05)
    for count, closest in [(2, 0.081), (0, 0.0795), (1, 0.09), (3, 0.08)]:
        stats.bodies(count, closest)
    first = stats.snapshot(now=1.0, step=4)  # 4 steps = 0.2 s of sim time
    assert first["contacts"] == 6
    assert first["contacts_per_s"] == pytest.approx(30.0)
    assert first["min_centre_distance_m"] == 0.0795
    # the next window starts afresh; no step: no distance, no contacts
    second = stats.snapshot(now=2.0, step=4)
    assert second["contacts"] == 0 and second["contacts_per_s"] == 0.0
    assert second["min_centre_distance_m"] is None
    json.dumps(second, allow_nan=False)  # what /sim/stats sends is plain JSON


def test_one_robot_has_no_centre_distance() -> None:
    stats = ControlLoopStats(n=1, now=0.0, step=0, dt=0.05)
    stats.bodies(1, math.inf)  # touching a wall
    out = stats.snapshot(now=1.0, step=1)
    assert out["contacts_per_s"] == pytest.approx(20.0)
    assert out["min_centre_distance_m"] is None
    json.dumps(out, allow_nan=False)

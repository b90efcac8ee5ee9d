"""The robot's IR input without ROS (robot_node.ir_readings, robot_node.controller): which
readings reach the control law, which are dropped, and when a reading is too old."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aes_ros.model import Gains, SwarmCommand
from aes_ros.robot_batch import evaluate_robots
from robot_node.controller import RobotController, RobotSettings
from robot_node.ir_readings import MAX_AGE, IrReadings
from robot_node.rotation_center import rotation_center_rule

S = 1_000_000_000  # ns per second
XY = np.array([[0.0, 0.0], [0.2, 0.0]])
YAW = np.zeros(2)


def controller(w_o: float) -> RobotController:
    command = SwarmCommand((1.0, 0.0), 0.0, None)
    settings = RobotSettings(
        robot_id=0,
        neighbors=(1,),
        rest_lengths=(0.2,),
        gains=Gains(d_r=0.0, d_theta=0.0, w_o=w_o),
        limits=None,
        neighbor_timeout=1.0,
        seed=0,
        neighbor_source="poses",
    )
    return RobotController(settings, command, center=rotation_center_rule(command))


def test_fresh_readings_reach_the_law_and_old_ones_count_as_nothing_seen() -> None:
    ir = IrReadings()
    assert ir.ranges(0) is None  # nothing heard yet
    for k in range(5):
        assert ir.heard(k, 1 * S, 0.02 * (k + 1)) is None
    np.testing.assert_array_equal(ir.ranges(1 * S), [0.02, 0.04, 0.06, 0.08, 0.10])
    ir.heard(0, 2 * S, 0.05)  # only sensor 0 keeps talking
    late = int((1 + MAX_AGE) * S) + 1
    ranges = ir.ranges(late)
    assert ranges[0] == 0.05 and np.isnan(ranges[1:]).all()
    assert ir.ranges(3 * S) is None  # all older than MAX_AGE: no sensors at all


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, -0.01, 5.0])
def test_a_reading_that_is_no_distance_is_dropped_with_a_reason(bad: float) -> None:
    ir = IrReadings()
    ir.heard(3, 1 * S, 0.04)
    reason = ir.heard(3, 1 * S + 1, bad)
    assert reason is not None and reason.startswith("dropped ir_3:") and "[0, 1] m" in reason
    assert ir.ranges(1 * S)[3] == 0.04  # the last good one stays


def test_the_controller_passes_ranges_only_with_w_o() -> None:
    for w_o, expect in ((0.0, False), (2.0, True)):
        ctl = controller(w_o)
        ctl.ir.heard(0, 1 * S, 0.02)
        job = ctl.poses_input(1 * S, XY, YAW, XY.mean(axis=0))
        assert (job.ir_ranges is not None) == expect


def test_an_obstacle_ahead_slows_the_robot_and_one_on_the_left_turns_it_right() -> None:
    free = controller(2.0)
    (ahead_free,) = evaluate_robots([free.poses_input(1 * S, XY, YAW, XY.mean(axis=0))])
    blocked = controller(2.0)
    blocked.ir.heard(0, 1 * S, 0.02)
    (ahead,) = evaluate_robots([blocked.poses_input(1 * S, XY, YAW, XY.mean(axis=0))])
    assert ahead.linear < ahead_free.linear
    assert ahead.angular == pytest.approx(ahead_free.angular)
    left = controller(2.0)
    left.ir.heard(1, 1 * S, 0.02)  # +37°
    (turned,) = evaluate_robots([left.poses_input(1 * S, XY, YAW, XY.mean(axis=0))])
    assert turned.angular < ahead_free.angular - 0.1  # clockwise: right


def test_a_clock_that_goes_back_forgets_the_readings() -> None:
    ctl = controller(2.0)
    ctl.poses_input(5 * S, XY, YAW, XY.mean(axis=0))
    ctl.ir.heard(0, 5 * S, 0.02)
    job = ctl.poses_input(1 * S, XY, YAW, XY.mean(axis=0))  # a restarted simulator
    assert job.ir_ranges is None

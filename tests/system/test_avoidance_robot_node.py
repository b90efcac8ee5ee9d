"""A robot node as a real process reads its IR ranges over DDS while ``w_o > 0`` and its
command is the control law with the avoidance term: an obstacle ahead slows it, one on
the left turns it right; old readings, readings that are no distance and ``w_o = 0``
leave the command as it is without sensors."""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseArray
from helpers.messages import poses_msg, stamp
from helpers.robot import NODE_1, NOISE_OFF, REST_1, record_outputs, robot_1
from rclpy.parameter import Parameter
from sensor_msgs.msg import Range

from aes_ros import scenario as scenario_mod
from aes_ros.model import Gains, RobotCommand, SwarmCommand, robot_command
from aes_ros.ros import interface as names
from aes_ros.ros.interface import robot_topic
from aes_ros.ros.qos import SENSOR

XY = np.array([[0.5, 0.05], [0.0, 0.0], [0.5, -0.05]])
YAW = np.array([0.0, 0.3, 0.0])


def range_msg(distance: float, t: float) -> Range:
    msg = Range()
    msg.header.stamp = stamp(t)
    msg.radiation_type = Range.INFRARED
    msg.min_range, msg.max_range, msg.range = 0.01, 0.1, distance
    return msg


def law(gains: Gains, ir_ranges: np.ndarray | None) -> RobotCommand:
    """Robot 1's command at XY, YAW before the supervisor speaks."""
    command = SwarmCommand((-1.0, 0.0), -0.7, tuple(XY.mean(axis=0)))
    return robot_command(
        XY[1], YAW[1], XY[[0, 2]], np.array(REST_1), gains, command, 0.05, ir_ranges=ir_ranges
    )


def test_robot_node_turns_away_from_what_its_ir_sensors_see(spawn, probe):
    proc = spawn.start(*robot_1(*NOISE_OFF, "-p", "w_o:=3.0"), name="robot")
    cmds, _ = record_outputs(probe, 1)
    poses = probe.publisher(PoseArray, names.POSES, SENSOR)
    # w_o > 0: the node subscribes to all five of its sensors.
    ir = [probe.publisher(Range, robot_topic(1, f"{names.IR}_{k}"), SENSOR) for k in range(5)]
    values = scenario_mod.load("combined").values
    gains = Gains.from_mapping({**values, "d_r": 0.0, "d_theta": 0.0, "w_o": 3.0})
    free = law(gains, None)

    def is_command(want: RobotCommand) -> bool:
        return (
            bool(cmds)
            and abs(cmds[-1].linear.x - want.linear) < 1e-12
            and abs(cmds[-1].angular.z - want.angular) < 1e-12
        )

    def sender(t: float, readings: dict[int, float]):
        """What sends the IR readings and the poses, all stamped ``t``."""

        def send() -> None:
            for k, distance in readings.items():
                ir[k].publish(range_msg(distance, t))
            poses.publish(poses_msg(XY, YAW, t))

        return send

    # Nothing heard yet: the law without the term.
    probe.until(sender(1.0, {}), lambda: is_command(free))

    # Something 2 cm ahead and 3 cm to the left (+37°): slower, and turning right.
    # (sensor_msgs/Range carries float32)
    ranges = np.array([0.02, 0.03, np.nan, np.nan, np.nan], dtype=np.float32).astype(float)
    want = law(gains, ranges)
    assert want.linear < free.linear - 0.05 and want.angular < free.angular - 0.5
    probe.until(sender(1.1, {0: 0.02, 1: 0.03}), lambda: is_command(want))

    # Readings older than 0.5 s count as nothing seen.
    probe.until(sender(2.0, {}), lambda: is_command(free))

    # A reading that is no distance is dropped with a warning; the node keeps going.
    probe.until(
        sender(2.1, {0: float("nan"), 1: -1.0}),
        lambda: "dropped ir_0" in spawn.log(proc).read_text(),
    )
    assert is_command(free) and proc.poll() is None

    # w_o = 0 at runtime: the subscriptions go, readings no longer count.
    results = probe.set_parameters(NODE_1, [Parameter("w_o", value=0.0)])
    assert all(r.successful for r in results), results
    probe.wait(
        lambda: all(pub.get_subscription_count() == 0 for pub in ir), 10.0, "IR unsubscribed"
    )
    off = law(Gains.from_mapping({**values, "d_r": 0.0, "d_theta": 0.0}), None)
    probe.until(sender(2.2, {0: 0.02}), lambda: is_command(off))
    assert "Traceback" not in spawn.log(proc).read_text()

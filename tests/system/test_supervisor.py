"""The supervisor as a real process (``aes-supervisor``), driven from an rclpy node in
the test process: steering by topic and by parameter, the enable service, the live
centroid and the metrics E7–E9.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from geometry_msgs.msg import PointStamped, PoseArray, Twist, TwistStamped
from helpers.messages import poses_msg, stamp, twist
from helpers.ros_env import TIMEOUT
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64
from std_srvs.srv import SetBool

from aes_ros import scenario as scenario_mod
from aes_ros.metrics import alignment_order, heading_order, total_force
from aes_ros.model import SwarmCommand, total_forces
from aes_ros.ros import interface as names
from aes_ros.ros.qos import COMMAND, LATCHED, SENSOR

NODE = "/" + names.SUPERVISOR_NODE
SUPERVISOR = ["aes-supervisor", "--ros-args", "-p", "scenario:=linear", "-p", "num_robots:=4"]


def drive(msg: TwistStamped) -> tuple[float, float, float]:
    return (msg.twist.linear.x, msg.twist.linear.y, msg.twist.angular.z)


def test_steering_by_topic_and_parameter(spawn, probe):
    """/swarm/cmd and parameter sets both change /swarm/desired_velocity at once, and the
    parameters agree with the topic; bad values are rejected or dropped."""
    proc = spawn.start(*SUPERVISOR, name="supervisor")
    velocity = probe.record(TwistStamped, names.DESIRED_VELOCITY, LATCHED)
    probe.wait(lambda: velocity, TIMEOUT, "the latched desired velocity")
    assert drive(velocity[-1]) == (-1.0, 0.0, 0.0)  # the linear scenario: west

    cmd = probe.publisher(Twist, names.CMD, COMMAND)
    cmd.publish(twist(vy=1.0, w=0.3))
    probe.wait(lambda: drive(velocity[-1]) == (0.0, 1.0, 0.3), TIMEOUT, "north from /swarm/cmd")
    assert probe.get_parameters(NODE, ["desired_direction", "rotation_rate"]) == [
        [0.0, 1.0],
        0.3,
    ]

    (result,) = probe.set_parameters(NODE, [Parameter("rotation_rate", value=-0.2)])
    assert result.successful
    probe.wait(lambda: drive(velocity[-1]) == (0.0, 1.0, -0.2), TIMEOUT, "the new rotation_rate")

    for bad in (
        Parameter("rotation_rate", value=50.0),
        Parameter("desired_direction", value=[0.0, 20.0]),
        Parameter("desired_direction", value=[1.0]),
        Parameter("rotation_center_mode", value="moon"),
        Parameter("k", value=-1.0),
    ):
        (result,) = probe.set_parameters(NODE, [bad])
        assert not result.successful and result.reason, bad.name
    cmd.publish(twist(vx=float("nan")))
    cmd.publish(twist(vx=100.0))
    time.sleep(0.5)
    assert drive(velocity[-1]) == (0.0, 1.0, -0.2)
    assert probe.get_parameters(NODE, ["desired_direction", "rotation_rate"]) == [
        [0.0, 1.0],
        -0.2,
    ]
    assert proc.poll() is None
    assert spawn.stop(proc) == 0
    assert "Traceback" not in spawn.log(proc).read_text()


def test_enable_service(spawn, probe):
    """/swarm/enable toggles the latched /swarm/enabled (and the ``enabled`` parameter)."""
    spawn.start(*SUPERVISOR, name="supervisor")
    enabled = probe.record(Bool, names.ENABLED, LATCHED)
    probe.wait(lambda: enabled, TIMEOUT, "the latched /swarm/enabled")
    assert enabled[-1].data is True
    response = probe.call(SetBool, names.ENABLE, SetBool.Request(data=False))
    assert response.success and response.message == "disabled"
    probe.wait(lambda: enabled[-1].data is False, TIMEOUT, "enabled false")
    assert probe.get_parameters(NODE, ["enabled"]) == [False]
    response = probe.call(SetBool, names.ENABLE, SetBool.Request(data=True))
    assert response.success
    probe.wait(lambda: enabled[-1].data is True, TIMEOUT, "enabled true")


def test_centroid_and_metrics(spawn, probe):
    """The live centroid of /swarm/poses (stamped like them) or a fixed point is published
    as /swarm/rotation_center; ψ, ψ_heading and F equal the core metrics and follow the
    sim-time clock."""
    spawn.start(
        *SUPERVISOR, "-p", "publish_rate:=10.0", "-p", "use_sim_time:=true", name="supervisor"
    )
    centers = probe.record(PointStamped, names.ROTATION_CENTER, LATCHED)
    metrics = {
        name: probe.record(Float64, f"/swarm/{name}", LATCHED)
        for name in ("alignment", "heading_order", "total_force")
    }
    poses = probe.publisher(PoseArray, names.POSES, SENSOR)
    scen = scenario_mod.load("linear").with_robots(4)
    xy, yaw = scen.initial_state(seed=5)
    msg = poses_msg(xy, yaw, 3.0)
    center = probe.exchange(lambda: poses.publish(msg), centers)
    assert (center.point.x, center.point.y) == tuple(xy.mean(axis=0))
    assert center.header.stamp == msg.header.stamp and center.header.frame_id == "odom"

    _, neighbors, rest = scen.sheet()
    forces = total_forces(xy, neighbors, rest, scen.gains, SwarmCommand((-1.0, 0.0), 0.0, None))
    want = {
        "alignment": alignment_order(forces, yaw),
        "heading_order": heading_order(yaw),
        "total_force": total_force(forces),
    }
    time.sleep(0.5)
    assert not any(metrics.values())  # the metrics timer runs on sim time: no /clock yet
    clock = probe.publisher(Clock, names.CLOCK, SENSOR, wait=False)
    sim_time = [3.0]

    def tick() -> None:
        sim_time[0] += 0.05
        clock.publish(Clock(clock=stamp(sim_time[0])))

    probe.every(0.02, tick)
    for name, received in metrics.items():
        probe.wait(lambda received=received: received, TIMEOUT, f"/swarm/{name}")
        assert received[-1].data == pytest.approx(want[name], abs=1e-12), name
    assert 0.0 <= want["alignment"] <= 1.0 and want["total_force"] > 0.0

    (result,) = probe.set_parameters(
        NODE,
        [
            Parameter("rotation_center", value=[1.0, 2.0]),
        ],
    )
    assert result.successful
    (result,) = probe.set_parameters(NODE, [Parameter("rotation_center_mode", value="fixed")])
    assert result.successful
    probe.wait(
        lambda: (centers[-1].point.x, centers[-1].point.y) == (1.0, 2.0), TIMEOUT, "fixed centre"
    )
    count = len(centers)
    for _ in range(3):  # fixed: poses no longer move the centre
        poses.publish(poses_msg(xy + np.array([1.0, 0.0]), yaw, 4.0))
        time.sleep(0.1)
    assert len(centers) == count


def test_bad_startup_parameter_fails_cleanly(spawn):
    """An out-of-range value at start is reported by name and the process exits 1."""
    proc = spawn.start(*SUPERVISOR, "-p", "desired_direction:=[0.0,20.0]", name="supervisor")
    assert proc.wait(timeout=TIMEOUT) == 1
    log = spawn.log(proc).read_text()
    assert "desired_direction" in log and "Traceback" not in log

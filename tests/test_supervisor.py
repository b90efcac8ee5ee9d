"""The supervisor as a real process (``aes-supervisor``), driven from an rclpy node in
the test process: steering by topic and by parameter, the enable service, the live
centroid and the metrics E7–E9.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import wait_for
from geometry_msgs.msg import PointStamped, PoseArray, Twist, TwistStamped
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64
from std_srvs.srv import SetBool
from test_robot_node import TIMEOUT, Driver, exchange, poses_msg, stamp

from aes_ros import scenario as scenario_mod
from aes_ros.metrics import alignment_order, heading_order, total_force
from aes_ros.model import SwarmCommand, total_forces
from aes_ros.ros.qos import COMMAND, LATCHED, SENSOR

pytestmark = pytest.mark.ros

NODE = "/supervisor"
SUPERVISOR = ["aes-supervisor", "--ros-args", "-p", "scenario:=linear", "-p", "num_robots:=4"]


@pytest.fixture
def driver(ros_env):
    d = Driver()
    try:
        yield d
    finally:
        d.close()


def drive(msg: TwistStamped) -> tuple[float, float, float]:
    return (msg.twist.linear.x, msg.twist.linear.y, msg.twist.angular.z)


def test_steering_by_topic_and_parameter(spawn, driver):
    """/swarm/cmd and parameter sets both change /swarm/desired_velocity at once, and the
    parameters agree with the topic; bad values are rejected or dropped."""
    proc = spawn.start(*SUPERVISOR, name="supervisor")
    velocity = driver.record(TwistStamped, "/swarm/desired_velocity", LATCHED)
    assert wait_for(lambda: velocity, TIMEOUT)
    assert drive(velocity[-1]) == (-1.0, 0.0, 0.0)  # the linear scenario: west

    cmd = driver.publisher(Twist, "/swarm/cmd", COMMAND)
    north = Twist()
    north.linear.y, north.angular.z = 1.0, 0.3
    cmd.publish(north)
    assert wait_for(lambda: drive(velocity[-1]) == (0.0, 1.0, 0.3), TIMEOUT)
    assert driver.get_parameters(NODE, ["desired_direction", "rotation_rate"]) == [
        [0.0, 1.0],
        0.3,
    ]

    (result,) = driver.set_parameters(NODE, [Parameter("rotation_rate", value=-0.2)])
    assert result.successful
    assert wait_for(lambda: drive(velocity[-1]) == (0.0, 1.0, -0.2), TIMEOUT)

    for bad in (
        Parameter("rotation_rate", value=50.0),
        Parameter("desired_direction", value=[0.0, 20.0]),
        Parameter("desired_direction", value=[1.0]),
        Parameter("rotation_center_mode", value="moon"),
        Parameter("k", value=-1.0),
    ):
        (result,) = driver.set_parameters(NODE, [bad])
        assert not result.successful and result.reason, bad.name
    nan = Twist()
    nan.linear.x = float("nan")
    cmd.publish(nan)
    far = Twist()
    far.linear.x = 100.0
    cmd.publish(far)
    time.sleep(0.5)
    assert drive(velocity[-1]) == (0.0, 1.0, -0.2)
    assert driver.get_parameters(NODE, ["desired_direction", "rotation_rate"]) == [
        [0.0, 1.0],
        -0.2,
    ]
    assert proc.poll() is None
    assert spawn.stop(proc) == 0
    assert "Traceback" not in spawn.procs[0][1].read_text()


def test_enable_service(spawn, driver):
    """/swarm/enable toggles the latched /swarm/enabled (and the ``enabled`` parameter)."""
    spawn.start(*SUPERVISOR, name="supervisor")
    enabled = driver.record(Bool, "/swarm/enabled", LATCHED)
    assert wait_for(lambda: enabled, TIMEOUT) and enabled[-1].data is True
    response = driver.call(SetBool, "/swarm/enable", SetBool.Request(data=False))
    assert response.success and response.message == "disabled"
    assert wait_for(lambda: enabled[-1].data is False, TIMEOUT)
    assert driver.get_parameters(NODE, ["enabled"]) == [False]
    response = driver.call(SetBool, "/swarm/enable", SetBool.Request(data=True))
    assert response.success
    assert wait_for(lambda: enabled[-1].data is True, TIMEOUT)


def test_centroid_and_metrics(spawn, driver):
    """The live centroid of /swarm/poses (stamped like them) or a fixed point is published
    as /swarm/rotation_center; ψ, ψ_heading and F equal the core metrics and follow the
    sim-time clock."""
    spawn.start(
        *SUPERVISOR, "-p", "publish_rate:=10.0", "-p", "use_sim_time:=true", name="supervisor"
    )
    centers = driver.record(PointStamped, "/swarm/rotation_center", LATCHED)
    metrics = {
        name: driver.record(Float64, f"/swarm/{name}", LATCHED)
        for name in ("alignment", "heading_order", "total_force")
    }
    poses = driver.publisher(PoseArray, "/swarm/poses", SENSOR)
    scen = scenario_mod.load("linear").with_robots(4)
    xy, yaw = scen.initial_state(seed=5)
    msg = poses_msg(xy, yaw, 3.0)
    center = exchange(lambda: poses.publish(msg), centers)
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
    clock = driver.publisher(Clock, "/clock", SENSOR, wait=False)
    sim_time = [3.0]

    def tick() -> None:
        sim_time[0] += 0.05
        clock.publish(Clock(clock=stamp(sim_time[0])))

    driver.node.create_timer(0.02, tick)
    for name, received in metrics.items():
        assert wait_for(lambda received=received: received, TIMEOUT), name
        assert received[-1].data == pytest.approx(want[name], abs=1e-12), name
    assert 0.0 <= want["alignment"] <= 1.0 and want["total_force"] > 0.0

    (result,) = driver.set_parameters(
        NODE,
        [
            Parameter("rotation_center", value=[1.0, 2.0]),
        ],
    )
    assert result.successful
    (result,) = driver.set_parameters(NODE, [Parameter("rotation_center_mode", value="fixed")])
    assert result.successful
    assert wait_for(lambda: (centers[-1].point.x, centers[-1].point.y) == (1.0, 2.0), TIMEOUT)
    count = len(centers)
    for _ in range(3):  # fixed: poses no longer move the centre
        poses.publish(poses_msg(xy + np.array([1.0, 0.0]), yaw, 4.0))
        time.sleep(0.1)
    assert len(centers) == count


def test_bad_startup_parameter_fails_cleanly(spawn):
    """An out-of-range value at start is reported by name and the process exits 1."""
    proc = spawn.start(*SUPERVISOR, "-p", "desired_direction:=[0.0,20.0]", name="supervisor")
    assert proc.wait(timeout=TIMEOUT) == 1
    log = spawn.procs[0][1].read_text()
    assert "desired_direction" in log and "Traceback" not in log

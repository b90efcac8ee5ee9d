"""The ``aes-sim-bridge`` process seen from another ROS node (real processes, own domain)."""

from __future__ import annotations

import dataclasses
import math
import signal
import time

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PoseArray, Twist
from nav_msgs.msg import Odometry
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_srvs.srv import SetBool, Trigger

from aes_ros.model import robot_command, unicycle_step
from aes_ros.ros.conversions import poses_to_arrays, quaternion_to_yaw
from aes_ros.ros.qos import COMMAND, SENSOR
from aes_ros.scenario import load
from aes_ros.simulator import simulate

pytestmark = pytest.mark.ros


class Probe:
    """The test's own node: records what the bridge publishes, sends commands."""

    def __init__(self, n: int) -> None:
        self.node = rclpy.create_node("bridge_probe")
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.clock: list[float] = []
        self.poses: list[tuple[float, np.ndarray, np.ndarray]] = []
        self.odom: list[Odometry] = []
        self.on_poses = None  # optional hook called with each PoseArray
        best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.node.create_subscription(Clock, "/clock", self._on_clock, best_effort)
        self.node.create_subscription(PoseArray, "/swarm/poses", self._on_poses, SENSOR)
        self.node.create_subscription(Odometry, "/mona_1/odom", self.odom.append, SENSOR)
        self.cmd = [
            self.node.create_publisher(Twist, f"/mona_{i}/cmd_vel", COMMAND) for i in range(n)
        ]
        self.reset = self.node.create_client(Trigger, "/sim/reset")
        self.pause = self.node.create_client(SetBool, "/sim/pause")
        self.params = self.node.create_client(SetParameters, "/sim_bridge/set_parameters")

    def _on_clock(self, msg: Clock) -> None:
        self.clock.append(msg.clock.sec + 1e-9 * msg.clock.nanosec)

    def _on_poses(self, msg: PoseArray) -> None:
        assert msg.header.frame_id == "odom"
        pos, head = poses_to_arrays(msg)
        self.poses.append((msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec, pos, head))
        if self.on_poses is not None:
            self.on_poses(msg)

    def spin_until(self, predicate, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.02)
        return bool(predicate())

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)

    def send(self, robot: int, linear: float, angular: float = 0.0) -> None:
        msg = Twist()
        msg.linear.x, msg.angular.z = linear, angular
        self.cmd[robot].publish(msg)

    def call(self, client, request):
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(request)
        assert self.spin_until(future.done, 10.0)
        return future.result()

    def set_param(self, name: str, value) -> tuple[bool, str]:
        request = SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()]
        )
        result = self.call(self.params, request).results[0]
        return result.successful, result.reason

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def probe_factory(ros_env):
    rclpy.init()
    probes: list[Probe] = []

    def make(n: int) -> Probe:
        probes.append(Probe(n))
        return probes[-1]

    try:
        yield make
    finally:
        for p in probes:
            p.close()
        rclpy.try_shutdown()


def start_bridge(spawn, *params: str):
    args = ["aes-sim-bridge", "--ros-args"]
    for p in params:
        args += ["-p", p]
    return spawn.start(*args, name="sim_bridge")


def test_bridge_publishes_the_scenario_and_follows_cmd_vel(spawn, probe_factory):
    scenario = load("linear").with_robots(4)
    start_pos, start_head = scenario.initial_state(3)
    proc = start_bridge(spawn, "scenario:=linear", "num_robots:=4", "seed:=3", "cmd_timeout:=0.5")
    probe = probe_factory(4)
    assert probe.spin_until(lambda: len(probe.poses) >= 3 and len(probe.odom) >= 2, 20.0), (
        "no /swarm/poses or odom from the bridge"
    )

    # /clock advances with the poses' stamps; N poses = the seeded initial state
    assert probe.spin_until(lambda: len(probe.clock) >= 3, 5.0)
    assert probe.clock[-1] > probe.clock[0]
    stamp, pos, head = probe.poses[-1]
    assert stamp > 0.0
    np.testing.assert_allclose(pos, start_pos, atol=1e-12)
    np.testing.assert_allclose(np.cos(head - start_head), 1.0, atol=1e-12)
    odom = probe.odom[-1]
    assert odom.header.frame_id == "odom" and odom.child_frame_id == "mona_1/base_link"
    assert odom.pose.pose.position.x == pytest.approx(start_pos[1, 0], abs=1e-12)
    assert quaternion_to_yaw(odom.pose.pose.orientation) == pytest.approx(start_head[1])

    # a non-finite command is dropped; a valid one drives robot 1 forward
    probe.send(1, math.nan, 0.0)
    probe.spin_for(0.3)
    t_end = time.monotonic() + 1.5
    while time.monotonic() < t_end:
        probe.send(1, 0.1, 0.0)
        probe.spin_for(0.05)
    _, pos, head = probe.poses[-1]
    moved = pos - start_pos
    heading = np.array([np.cos(start_head[1]), np.sin(start_head[1])])
    assert moved[1] @ heading > 0.05  # forward, ~0.1 m/s for ~1.5 s
    assert abs(moved[1] @ [-heading[1], heading[0]]) < 1e-9  # never sideways
    assert head[1] == pytest.approx(start_head[1], abs=1e-9)
    np.testing.assert_allclose(moved[[0, 2, 3]], 0.0, atol=1e-12)
    assert probe.odom[-1].twist.twist.linear.x == pytest.approx(0.1)

    # silence: after cmd_timeout (0.5 s of sim time) robot 1 stops
    probe.spin_for(1.5)
    (t1, p1, _), (t2, p2, _) = probe.poses[-5], probe.poses[-1]
    assert t2 > t1
    np.testing.assert_array_equal(p1, p2)
    assert probe.odom[-1].twist.twist.linear.x == 0.0

    assert spawn.stop(proc) == 0  # SIGINT: clean exit
    assert "Traceback" not in spawn.logs()


def test_lockstep_steps_once_per_round_of_commands(spawn, probe_factory):
    start_bridge(
        spawn, "num_robots:=2", "seed:=5", "lockstep:=true", "real_time_factor:=0.0", "clip:=false"
    )
    probe = probe_factory(2)
    answered: set[float] = set()
    answer = {"robots": [0, 1]}
    commands = {0: (0.1, 0.5), 1: (-0.05, -1.0)}

    def reply(msg: PoseArray) -> None:
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        if stamp not in answered:
            answered.add(stamp)
            for i in answer["robots"]:
                probe.send(i, *commands[i])

    probe.on_poses = reply
    assert probe.spin_until(lambda: len(answered) >= 41, 30.0), "lockstep did not advance"
    stamps = sorted(answered)
    np.testing.assert_allclose(np.diff(stamps[:41]), 0.05, atol=1e-9)  # no step skipped

    # the bridge integrated exactly the offline model with these commands
    pos, head = load("combined").with_robots(2).initial_state(5)
    u, turn = np.array([0.1, -0.05]), np.array([0.5, -1.0])
    target = round(stamps[-1] / 0.05)
    for _ in range(target):
        pos, head = unicycle_step(pos, head, u, turn, 0.05)
    got = next(p for p in reversed(probe.poses) if round(p[0] / 0.05) == target)
    np.testing.assert_allclose(got[1], pos, atol=1e-9)
    np.testing.assert_allclose(np.cos(got[2] - head), 1.0, atol=1e-12)

    # robot 1 falls silent: the bridge waits (re-publishing the same state)
    answer["robots"] = [0]
    probe.spin_for(0.5)
    stuck = max(answered)
    probe.spin_for(2.5)
    assert max(answered) == stuck
    assert max(p[0] for p in probe.poses) == stuck
    # robot 1 answers again: the bridge resumes
    probe.send(1, *commands[1])
    answer["robots"] = [0, 1]
    assert probe.spin_until(lambda: max(answered) >= stuck + 0.5, 10.0)


def test_reset_and_pause_services(spawn, probe_factory):
    proc = start_bridge(spawn, "num_robots:=2", "seed:=1", "cmd_timeout:=10.0")
    probe = probe_factory(2)
    start_pos, _ = load("combined").with_robots(2).initial_state(1)
    assert probe.spin_until(lambda: len(probe.poses) >= 2, 20.0)
    probe.send(0, 0.1, 0.3)
    probe.spin_for(1.0)
    assert np.linalg.norm(probe.poses[-1][1][0] - start_pos[0]) > 0.05

    # pause: the clock and the robots stop; resume: both go on
    result = probe.call(probe.pause, SetBool.Request(data=True))
    assert result.success and result.message == "paused"
    probe.spin_for(0.3)
    clock, moved = probe.clock[-1], probe.poses[-1][1]
    probe.spin_for(1.0)
    assert probe.clock[-1] == clock
    np.testing.assert_array_equal(probe.poses[-1][1], moved)
    result = probe.call(probe.pause, SetBool.Request(data=False))
    assert result.success and result.message == "running"
    assert probe.spin_until(lambda: probe.clock[-1] > clock + 0.2, 5.0)

    # reset: back to the initial poses, every robot stopped, the clock goes on
    t_before = probe.clock[-1]
    result = probe.call(probe.reset, Trigger.Request())
    assert result.success
    probe.spin_for(1.0)
    stamp, pos, _ = probe.poses[-1]
    assert stamp > t_before
    np.testing.assert_allclose(pos, start_pos, atol=1e-12)

    proc.send_signal(signal.SIGTERM)  # also a clean exit
    assert proc.wait(10.0) == 0


def test_runtime_parameters_and_dynamic_mode(spawn, probe_factory):
    start_bridge(spawn, "num_robots:=2", "seed:=2", "mode:=dynamic", "cmd_timeout:=10.0")
    probe = probe_factory(2)
    start_pos, start_head = load("combined").with_robots(2).initial_state(2)
    assert probe.spin_until(lambda: len(probe.poses) >= 2 and probe.odom, 20.0)

    # out of range: rejected with a reason, the bridge keeps its value and runs on
    ok, reason = probe.set_param("real_time_factor", -1.0)
    assert not ok and "real_time_factor" in reason
    ok, _ = probe.set_param("mode", "kinematic")  # read-only
    assert not ok
    # twice real time: sim time runs ahead of the wall clock
    assert probe.set_param("real_time_factor", 2.0)[0]
    wall, sim = time.monotonic(), probe.clock[-1]
    probe.spin_for(2.0)
    assert probe.clock[-1] - sim > 1.3 * (time.monotonic() - wall)

    # dynamic mode: wheel motors drive robot 1 forward, robot 0 turns on the spot (CCW)
    t_end = time.monotonic() + 1.0
    while time.monotonic() < t_end:
        probe.send(0, 0.0, 1.0)
        probe.send(1, 0.1, 0.0)
        probe.spin_for(0.05)
    probe.spin_for(0.2)
    _, pos, head = probe.poses[-1]
    heading = np.array([np.cos(start_head[1]), np.sin(start_head[1])])
    assert (pos[1] - start_pos[1]) @ heading > 0.05
    assert np.linalg.norm(pos[0] - start_pos[0]) < 0.01
    assert np.sin(head[0] - start_head[0]) > 0.3
    assert probe.odom[-1].twist.twist.linear.x == pytest.approx(0.1, abs=0.02)


def test_lockstep_bridge_with_the_control_law_equals_the_offline_simulator(spawn, probe_factory):
    """The test plays 4 noise-free robots with aes_ros.model.robot_command: 10 s in lockstep
    end where the offline simulator ends from the same seed."""
    scenario = load("combined").with_robots(4).with_overrides({"duration": 10.0})
    start_bridge(
        spawn, "num_robots:=4", "seed:=7", "lockstep:=true", "real_time_factor:=0.0", "clip:=false"
    )
    probe = probe_factory(4)
    _, neighbors, rest = scenario.sheet()
    states: dict[int, np.ndarray] = {}

    def control(msg: PoseArray) -> None:
        step = round((msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec) / scenario.dt)
        if step in states:
            return  # a re-published state was answered already
        pos, head = poses_to_arrays(msg, expected=4)
        states[step] = pos
        command = dataclasses.replace(scenario.command, center=tuple(pos.mean(axis=0)))
        for i in range(4):
            mine = neighbors[i] >= 0
            out = robot_command(
                pos[i],
                head[i],
                pos[neighbors[i][mine]],
                rest[i][mine],
                scenario.gains,
                command,
                scenario.dt,
            )
            probe.send(i, out.linear, out.angular)

    probe.on_poses = control
    assert probe.spin_until(lambda: scenario.n_steps in states, 60.0), max(states, default=None)
    offline = simulate(scenario, 7, noise=False).positions[0]
    assert np.linalg.norm(offline[-1] - offline[0], axis=-1).min() > 0.3  # the swarm moved
    # The contract is < 1 mm; the bridge integrates the very same Euler step, so
    # (as measured) the positions agree to rounding.
    np.testing.assert_allclose(states[scenario.n_steps], offline[-1], atol=1e-9)
    np.testing.assert_allclose(states[100], offline[100], atol=1e-9)

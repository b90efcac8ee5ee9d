"""Robot nodes as real processes (``aes-robot-node``, ``aes-robot-host``), driven from
an rclpy node in the test process: the published command is the control law of
:func:`aes_ros.model.robot_command`, for both neighbour sources; parameters are
checked at runtime; bad input is dropped.
"""

from __future__ import annotations

import math
import os
import signal
import threading
import time
from typing import Any

import numpy as np
import pytest
import rclpy
from conftest import wait_for
from geometry_msgs.msg import PointStamped, PoseArray, Twist, Vector3Stamped
from nav_msgs.msg import Odometry
from rcl_interfaces.srv import GetParameters, SetParameters, SetParametersAtomically
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Bool

from aes_ros import scenario as scenario_mod
from aes_ros.model import (
    Gains,
    SwarmCommand,
    motion_commands,
    robot_command,
    total_forces,
    unicycle_step,
)
from aes_ros.ros.conversions import arrays_to_poses, yaw_to_quaternion
from aes_ros.ros.qos import COMMAND, LATCHED, SENSOR

pytestmark = pytest.mark.ros

TIMEOUT = 20.0  # [s] generous: other tests may load the 2 cores


class Driver:
    """An rclpy node in the test process, spun in a background thread."""

    def __init__(self) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("test_driver", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        try:
            while self.context.ok():
                self.executor.spin_once(timeout_sec=0.05)
        except ExternalShutdownException:
            pass

    def record(self, msg_type: type, topic: str, qos: Any) -> list:
        """Messages received on ``topic``, appended as they arrive."""
        received: list = []
        self.node.create_subscription(msg_type, topic, received.append, qos)
        return received

    def publisher(self, msg_type: type, topic: str, qos: Any, wait: bool = True):
        pub = self.node.create_publisher(msg_type, topic, qos)
        if wait:
            assert wait_for(lambda: pub.get_subscription_count() > 0, TIMEOUT), topic
        return pub

    def call(self, srv_type: type, name: str, request: Any) -> Any:
        client = self.node.create_client(srv_type, name)
        assert client.wait_for_service(timeout_sec=TIMEOUT), name
        future = client.call_async(request)
        assert wait_for(future.done, TIMEOUT), name
        self.node.destroy_client(client)
        return future.result()

    def set_parameters(self, node: str, params: list[Parameter]) -> list:
        request = SetParameters.Request(parameters=[p.to_parameter_msg() for p in params])
        return self.call(SetParameters, f"{node}/set_parameters", request).results

    def get_parameters(self, node: str, names: list[str]) -> list:
        response = self.call(
            GetParameters, f"{node}/get_parameters", GetParameters.Request(names=names)
        )
        return [parameter_value_to_python(v) for v in response.values]

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.thread.join(timeout=5)


@pytest.fixture
def driver(ros_env):
    d = Driver()
    try:
        yield d
    finally:
        d.close()


def poses_msg(xy: np.ndarray, yaw: np.ndarray, t: float) -> PoseArray:
    msg = PoseArray()
    msg.header.frame_id = "odom"
    msg.header.stamp = stamp(t)
    msg.poses = arrays_to_poses(np.asarray(xy, dtype=float), np.asarray(yaw, dtype=float))
    return msg


def stamp(t: float):
    return rclpy.time.Time(nanoseconds=round(t * 1e9)).to_msg()


def odom_msg(x: float, y: float, yaw: float, t: float) -> Odometry:
    msg = Odometry()
    msg.header.frame_id = "odom"
    msg.header.stamp = stamp(t)
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation = yaw_to_quaternion(yaw)
    return msg


def exchange(send, received: list, timeout: float = TIMEOUT, resend: float = 0.5) -> Any:
    """Call ``send()`` (again every ``resend`` s: best-effort input) until a new message
    arrives in ``received``; return it."""
    count = len(received)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        send()
        if wait_for(lambda: len(received) > count, resend):
            return received[-1]
    raise AssertionError("no reply")


def until(send, check, timeout: float = TIMEOUT) -> None:
    """Call ``send()`` until ``check()`` is true (for inputs that may arrive late)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        send()
        if wait_for(check, 0.3):
            return
    assert check()


def expected(xy, yaw, i, neighbors, rest, gains, command, dt=0.05):
    xy = np.asarray(xy, dtype=float)
    return robot_command(xy[i], yaw[i], xy[neighbors], np.asarray(rest), gains, command, dt)


def assert_command(cmd: Twist, force: Vector3Stamped, want) -> None:
    assert cmd.linear.x == pytest.approx(want.linear, abs=1e-12)
    assert cmd.angular.z == pytest.approx(want.angular, abs=1e-12)
    assert (cmd.linear.y, cmd.linear.z, cmd.angular.x, cmd.angular.y) == (0, 0, 0, 0)
    assert (force.vector.x, force.vector.y) == pytest.approx(tuple(want.force), abs=1e-12)
    assert force.header.frame_id == "odom"


ROBOT_1 = ["-r", "__ns:=/mona_1", "-p", "robot_id:=1", "-p", "neighbors:=[0,2]"]
REST_1 = [0.2, 0.25]
NOISE_OFF = ["-p", "d_r:=0.0", "-p", "d_theta:=0.0", "-p", "clip:=false"]


def test_command_is_the_control_law(spawn, driver):
    """Noise off: cmd_vel and aes_force equal robot_command() for the same inputs,
    with the rotation centre from the poses, a fixed /swarm/rotation_center, or the
    live centroid recognised from the supervisor's message."""
    spawn.start(
        "aes-robot-node",
        "--ros-args",
        *ROBOT_1,
        "-p",
        "rest_lengths:=[0.2,0.25]",
        *NOISE_OFF,
        name="robot",
    )
    cmds = driver.record(Twist, "/mona_1/cmd_vel", COMMAND)
    forces = driver.record(Vector3Stamped, "/mona_1/aes_force", COMMAND)
    poses = driver.publisher(PoseArray, "/swarm/poses", SENSOR)
    center = driver.publisher(PointStamped, "/swarm/rotation_center", LATCHED)
    combined = scenario_mod.load("combined")
    gains = Gains.from_mapping({**combined.values, "d_r": 0.0, "d_theta": 0.0})
    rng = np.random.default_rng(1)

    # Before the supervisor speaks: the scenario's command about the centroid of the poses.
    for step in range(3):
        xy, yaw = rng.uniform(-0.3, 0.3, (3, 2)), rng.uniform(-np.pi, np.pi, 3)
        msg = poses_msg(xy, yaw, 1.0 + 0.05 * step)
        cmd = exchange(lambda msg=msg: poses.publish(msg), cmds)
        assert wait_for(lambda: len(forces) == len(cmds), TIMEOUT)
        command = SwarmCommand((-1.0, 0.0), -0.7, tuple(xy.mean(axis=0)))
        assert_command(cmd, forces[-1], expected(xy, yaw, 1, [0, 2], REST_1, gains, command))

    # A fixed rotation centre.
    fixed = PointStamped()
    fixed.point.x, fixed.point.y = 5.0, -2.0
    center.publish(fixed)
    command = SwarmCommand((-1.0, 0.0), -0.7, (5.0, -2.0))
    want = expected(xy, yaw, 1, [0, 2], REST_1, gains, command)
    until(lambda: poses.publish(msg), lambda: cmds[-1].angular.z == pytest.approx(want.angular))
    assert_command(cmds[-1], forces[-1], want)

    # The supervisor's live centroid (same stamp, same point): the robot then uses the
    # centroid of each new poses message itself, without waiting for the next one.
    live = PointStamped()
    live.header.stamp = msg.header.stamp
    live.point.x, live.point.y = (float(v) for v in xy.mean(axis=0))
    center.publish(live)
    time.sleep(0.5)
    xy2 = xy + np.array([0.3, 0.1])
    msg2 = poses_msg(xy2, yaw, 2.0)
    command = SwarmCommand((-1.0, 0.0), -0.7, tuple(xy2.mean(axis=0)))
    want = expected(xy2, yaw, 1, [0, 2], REST_1, gains, command, dt=1.0 - 0.05 * 2)
    until(lambda: poses.publish(msg2), lambda: cmds[-1].angular.z == pytest.approx(want.angular))
    assert_command(cmds[-1], forces[-1], want)


def test_stretched_springs_pull_toward_neighbours(spawn, driver):
    """A robot behind its neighbours drives and turns toward them; gains set at runtime
    apply to the next command; with noise on the command changes, the force does not."""
    spawn.start(
        "aes-robot-node",
        "--ros-args",
        *ROBOT_1,
        "-p",
        "rest_lengths:=[0.2,0.2]",
        *NOISE_OFF,
        name="robot",
    )
    cmds = driver.record(Twist, "/mona_1/cmd_vel", COMMAND)
    forces = driver.record(Vector3Stamped, "/mona_1/aes_force", COMMAND)
    poses = driver.publisher(PoseArray, "/swarm/poses", SENSOR)
    results = driver.set_parameters(
        "/mona_1/aes_robot",
        [Parameter("w_l", value=0.0), Parameter("w_r", value=0.0), Parameter("alpha", value=0.2)],
    )
    assert all(r.successful for r in results), results
    v0 = scenario_mod.load("combined").v0
    xy = [[0.5, 0.05], [0.0, 0.0], [0.5, -0.05]]  # neighbours 0.5 m east: stretched, symmetric

    def command_for(heading: float, t: float) -> Twist:
        msg = poses_msg(xy, [0.0, heading, 0.0], t)
        return exchange(lambda: poses.publish(msg), cmds)

    facing = command_for(0.0, 1.0)
    assert facing.linear.x > v0 + 0.05 and abs(facing.angular.z) < 1e-9
    assert forces[-1].vector.x > 0.5 and forces[-1].vector.y == pytest.approx(0.0, abs=1e-12)
    away = command_for(math.pi, 1.05)
    assert away.linear.x < v0 - 0.05  # backs up toward them
    north = command_for(math.pi / 2, 1.1)
    assert north.linear.x == pytest.approx(v0, abs=1e-9) and north.angular.z < -0.5  # turns right

    noise_free = forces[-1].vector.x
    assert driver.set_parameters("/mona_1/aes_robot", [Parameter("d_r", value=0.5)])[0].successful
    noisy = [command_for(math.pi / 2, 1.15 + 0.05 * k) for k in range(3)]
    assert any(abs(c.linear.x - v0) > 1e-6 for c in noisy)
    assert forces[-1].vector.x == pytest.approx(noise_free, abs=1e-12)


def test_enable_and_bad_poses(spawn, driver):
    """/swarm/enabled false -> zero cmd_vel; NaN or too short poses are dropped with a
    warning and the node keeps working."""
    proc = spawn.start(
        "aes-robot-node",
        "--ros-args",
        *ROBOT_1,
        "-p",
        "rest_lengths:=[0.2,0.25]",
        *NOISE_OFF,
        name="robot",
    )
    cmds = driver.record(Twist, "/mona_1/cmd_vel", COMMAND)
    poses = driver.publisher(PoseArray, "/swarm/poses", SENSOR)
    enabled = driver.publisher(Bool, "/swarm/enabled", LATCHED)
    xy, yaw = [[0.5, 0.05], [0.0, 0.0], [0.5, -0.05]], [0.0, 0.3, 0.0]
    good = poses_msg(xy, yaw, 1.0)
    assert exchange(lambda: poses.publish(good), cmds).linear.x > 0.1

    enabled.publish(Bool(data=False))
    until(lambda: poses.publish(good), lambda: cmds[-1] == Twist())
    enabled.publish(Bool(data=True))
    until(lambda: poses.publish(good), lambda: cmds[-1].linear.x > 0.1)

    nan = poses_msg(xy, yaw, 1.1)
    nan.poses[0].position.x = float("nan")
    short = poses_msg(xy[:1], yaw[:1], 1.2)  # no pose for robot 1
    count = len(cmds)
    for _ in range(5):
        poses.publish(nan)
        poses.publish(short)
        time.sleep(0.1)
    time.sleep(0.5)
    assert len(cmds) == count
    assert exchange(lambda: poses.publish(good), cmds).linear.x > 0.1
    assert proc.poll() is None
    log = spawn.procs[0][1].read_text()
    assert "dropped /swarm/poses" in log


def test_parameter_checks(spawn, driver):
    """Out-of-range or inconsistent parameter sets are rejected with a reason; the node
    keeps its old values and keeps running; valid sets apply."""
    proc = spawn.start(
        "aes-robot-node", "--ros-args", *ROBOT_1, "-p", "rest_lengths:=[0.2,0.25]", name="robot"
    )
    node = "/mona_1/aes_robot"
    cmds = driver.record(Twist, "/mona_1/cmd_vel", COMMAND)
    poses = driver.publisher(PoseArray, "/swarm/poses", SENSOR)
    defaults = scenario_mod.load("combined")
    assert driver.get_parameters(node, ["alpha", "robot_id", "neighbors", "clip"]) == [
        defaults.alpha,
        1,
        [0, 2],
        True,
    ]
    rejected = {
        "alpha": Parameter("alpha", value=50.0),
        "v0": Parameter("v0", value=float("nan")),
        "rest_lengths": Parameter("rest_lengths", value=[0.2]),
        "neighbors": Parameter("neighbors", value=[0, 1]),
        "neighbor_source": Parameter("neighbor_source", value="gps"),
        "scenario": Parameter("scenario", value="linear"),
    }
    for name, param in rejected.items():
        (result,) = driver.set_parameters(node, [param])
        assert not result.successful, name
        assert result.reason, name
    assert "rest_lengths" in driver.set_parameters(node, [rejected["rest_lengths"]])[0].reason
    assert driver.get_parameters(node, ["alpha", "v0", "rest_lengths", "neighbor_source"]) == [
        defaults.alpha,
        defaults.v0,
        [0.2, 0.25],
        "poses",
    ]
    msg = poses_msg([[0.5, 0.05], [0.0, 0.0], [0.5, -0.05]], [0.0, 0.3, 0.0], 1.0)
    exchange(lambda: poses.publish(msg), cmds)
    # Neighbours and their lengths change together atomically.
    request = SetParametersAtomically.Request(
        parameters=[
            Parameter("neighbors", value=[0]).to_parameter_msg(),
            Parameter("rest_lengths", value=[0.3]).to_parameter_msg(),
        ]
    )
    assert driver.call(
        SetParametersAtomically, f"{node}/set_parameters_atomically", request
    ).result.successful
    assert driver.get_parameters(node, ["neighbors", "rest_lengths"]) == [[0], [0.3]]
    results = driver.set_parameters(
        node, [Parameter("alpha", value=0.1), Parameter("max_linear_speed", value=0.01)]
    )
    assert all(r.successful for r in results)
    assert driver.get_parameters(node, ["alpha"]) == [0.1]
    until(lambda: poses.publish(msg), lambda: cmds[-1].linear.x == pytest.approx(0.01))
    assert proc.poll() is None
    # SIGTERM: clean shutdown.
    os.killpg(proc.pid, signal.SIGTERM)
    assert proc.wait(timeout=TIMEOUT) == 0
    assert "Traceback" not in spawn.procs[0][1].read_text()


def test_odom_source_and_neighbour_timeout(spawn, driver):
    """odom source (switched on at runtime): neighbours from their /mona_<j>/odom; one not
    heard from for longer than neighbor_timeout (by stamp) is left out of the sum."""
    spawn.start(
        "aes-robot-node",
        "--ros-args",
        *ROBOT_1,
        "-p",
        "rest_lengths:=[0.2,0.25]",
        "-p",
        "neighbor_timeout:=0.5",
        *NOISE_OFF,
        name="robot",
    )
    forces = driver.record(Vector3Stamped, "/mona_1/aes_force", COMMAND)
    # Switched at runtime: the node subscribes to its own and its neighbours' odom.
    params = [Parameter("neighbor_source", value="odom")]
    assert driver.set_parameters("/mona_1/aes_robot", params)[0].successful
    odom = [driver.publisher(Odometry, f"/mona_{j}/odom", SENSOR) for j in range(3)]
    gains = Gains.from_mapping({**scenario_mod.load("combined").values, "d_r": 0.0})
    xy = np.array([[0.4, 0.1], [0.0, 0.0], [0.1, -0.4]])
    command = SwarmCommand((-1.0, 0.0), -0.7, None)  # no centre known: no rotation term

    def force_is(neighbors: list[int]):
        rest = [REST_1[[0, 2].index(j)] for j in neighbors]
        want = expected(xy, [0.0, 0.0, 0.0], 1, neighbors, rest, gains, command).force
        return lambda: (
            bool(forces)
            and (
                (forces[-1].vector.x, forces[-1].vector.y) == pytest.approx(tuple(want), abs=1e-12)
            )
        )

    clock = [1.0]

    def round_(publish_to: list[int]) -> None:
        clock[0] += 0.05
        for j in publish_to:
            odom[j].publish(odom_msg(*xy[j], 0.0, clock[0]))
        time.sleep(0.05)
        odom[1].publish(odom_msg(*xy[1], 0.0, clock[0]))

    until(lambda: round_([0, 2]), force_is([0, 2]))
    clock[0] += 1.0  # neighbour 2 falls silent for longer than the timeout
    until(lambda: round_([0]), force_is([0]))
    clock[0] += 1.0
    until(lambda: round_([]), force_is([]))


@pytest.mark.parametrize("source", ["poses", "odom"])
def test_host_runs_every_robot(spawn, driver, source):
    """A host with 4 robots publishes every robot's command, equal to the control law
    with the process-wide -p overrides applied to every robot."""
    proc = spawn.start(
        "aes-robot-host",
        "--ros-args",
        "-p",
        "scenario:=linear",
        "-p",
        "num_robots:=4",
        "-p",
        f"neighbor_source:={source}",
        "-p",
        "alpha:=0.1",
        *NOISE_OFF,
        name="host",
    )
    scen = scenario_mod.load("linear").with_robots(4)
    xy, yaw = scen.initial_state(seed=3)
    _, table, rest_table = scen.sheet()
    gains = Gains.from_mapping({**scen.values, "alpha": 0.1, "d_r": 0.0, "d_theta": 0.0})
    command = SwarmCommand((-1.0, 0.0), 0.0, tuple(xy.mean(axis=0)))
    forces = [driver.record(Vector3Stamped, f"/mona_{i}/aes_force", COMMAND) for i in range(4)]
    cmds = [driver.record(Twist, f"/mona_{i}/cmd_vel", COMMAND) for i in range(4)]
    wants = []
    for i in range(4):
        keep = table[i] >= 0
        wants.append(expected(xy, yaw, i, table[i][keep], rest_table[i][keep], gains, command))

    def all_match() -> bool:
        return all(
            c and (c[-1].linear.x, c[-1].angular.z) == pytest.approx((w.linear, w.angular))
            for c, w in zip(cmds, wants, strict=True)
        )

    clock = [1.0]
    if source == "poses":
        poses = driver.publisher(PoseArray, "/swarm/poses", SENSOR)

        def send() -> None:
            clock[0] += 0.05
            poses.publish(poses_msg(xy, yaw, clock[0]))
    else:
        odom = [driver.publisher(Odometry, f"/mona_{i}/odom", SENSOR) for i in range(4)]

        def send() -> None:
            clock[0] += 0.05
            for i in range(4):
                odom[i].publish(odom_msg(*xy[i], yaw[i], clock[0]))

    until(send, all_match)
    for i in range(4):
        assert_command(cmds[i][-1], forces[i][-1], wants[i])
    assert driver.get_parameters("/mona_2/aes_robot", ["robot_id", "alpha", "neighbor_source"]) == [
        2,
        0.1,
        source,
    ]
    assert spawn.stop(proc) == 0  # SIGINT: clean shutdown
    assert "Traceback" not in spawn.procs[0][1].read_text()


def test_lockstep_with_supervisor_equals_offline_model(spawn, driver):
    """Supervisor + host, stepped in lockstep by the test (kinematic unicycle, noise and
    clipping off): the trajectory equals the offline model's, combined scenario with the
    live centroid as rotation centre."""
    common = ["-p", "scenario:=combined", "-p", "num_robots:=9"]
    spawn.start("aes-supervisor", "--ros-args", *common, name="supervisor")
    spawn.start("aes-robot-host", "--ros-args", *common, *NOISE_OFF, name="host")
    scen = scenario_mod.load("combined").with_robots(9)
    _, table, rest_table = scen.sheet()
    gains = Gains.from_mapping({**scen.values, "d_r": 0.0, "d_theta": 0.0})
    forces = [driver.record(Vector3Stamped, f"/mona_{i}/aes_force", COMMAND) for i in range(9)]
    cmds = [driver.record(Twist, f"/mona_{i}/cmd_vel", COMMAND) for i in range(9)]
    centers = driver.record(PointStamped, "/swarm/rotation_center", LATCHED)
    poses = driver.publisher(PoseArray, "/swarm/poses", SENSOR)
    assert wait_for(lambda: poses.get_subscription_count() >= 2, TIMEOUT)  # host + supervisor

    xy, yaw = scen.initial_state(seed=7)
    ref_xy, ref_yaw = xy.copy(), yaw.copy()
    dt = 0.05
    for step in range(40):
        msg = poses_msg(xy, yaw, 1.0 + step * dt)

        def replies(msg=msg) -> list | None:
            out = []
            for f, c in zip(forces, cmds, strict=True):
                hits = [k for k, m in enumerate(f) if m.header.stamp == msg.header.stamp]
                if not hits or len(c) <= hits[0]:
                    return None
                out.append(c[hits[0]])
            return out

        until(lambda msg=msg: poses.publish(msg), lambda: replies() is not None)
        got = replies()
        u = np.array([c.linear.x for c in got])
        w = np.array([c.angular.z for c in got])
        xy, yaw = unicycle_step(xy, yaw, u, w, dt)
        f = total_forces(ref_xy, table, rest_table, gains, SwarmCommand((-1.0, 0.0), -0.7))
        ref_u, ref_w = motion_commands(f, ref_yaw, gains, dt)
        ref_xy, ref_yaw = unicycle_step(ref_xy, ref_yaw, ref_u, ref_w, dt)
    assert len(centers) > 0  # the supervisor was publishing the live centroid
    assert np.max(np.abs(xy - ref_xy)) < 1e-9
    assert np.max(np.abs(yaw - ref_yaw)) < 1e-9


def test_host_evaluates_its_robots_at_once_exactly_as_one_by_one() -> None:
    """``aes-robot-host`` evaluates all its robots in one batched call: the commands and
    forces are bit for bit those of robot_command() per robot, with neighbour counts,
    gains, noise, limits and rotation centres differing from robot to robot."""
    from aes_ros.model import RobotInput, evaluate_robots

    rng = np.random.default_rng(3)

    def jobs() -> list[RobotInput]:
        out = []
        for r in range(7):
            k = [0, 1, 3, 6, 4, 2, 6][r]
            gains = Gains(alpha=0.01 * (r + 1), beta=0.5 + r / 10, k=1.0 + r, d_r=0.1 * (r % 3))
            gains = Gains(**{**gains.__dict__, "d_theta": 0.02 * (r % 2)})
            noisy = gains.d_r > 0 or gains.d_theta > 0
            center = None if r == 4 else (0.3 * r, -0.2)
            out.append(
                RobotInput(
                    positions[r],
                    headings[r],
                    neighbours[r][:k],
                    rests[r][:k],
                    gains,
                    SwarmCommand((-1.0, 0.2 * r), [0.0, 0.4, -0.7][r % 3], center),
                    0.02 + 0.01 * r,
                    np.random.default_rng(r) if noisy else None,
                    (0.05, 1.0) if r % 2 else None,
                )
            )
        return out

    positions = rng.normal(size=(7, 2))
    headings = rng.uniform(-np.pi, np.pi, 7)
    neighbours = rng.normal(size=(7, 6, 2))
    rests = rng.uniform(0.1, 0.5, (7, 6))
    rests[3, 2] = 0.0  # a rest length latched on top of its neighbour
    batch_jobs, single_jobs = jobs(), jobs()
    for _ in range(3):  # each robot's generator advances alike, step after step
        batch = evaluate_robots(batch_jobs)
        single = [robot_command(*job.arguments()) for job in single_jobs]
        for a, b in zip(batch, single, strict=True):
            assert (a.linear, a.angular) == (b.linear, b.angular)
            assert np.array_equal(a.force, b.force)
    assert len({round(c.force[0], 9) for c in batch}) == 7  # the inputs really differ

"""Robot nodes as real processes (``aes-robot-node``, ``aes-robot-host``), driven from
an rclpy node in the test process: the published command is the control law of
:func:`aes_ros.model.robot_command`, for both neighbour sources; parameters are
checked at runtime; bad input is dropped.
"""

from __future__ import annotations

import math
import os
import signal
import time

import numpy as np
import pytest
from geometry_msgs.msg import PointStamped, PoseArray, Twist, Vector3Stamped
from helpers.messages import odom_msg, poses_msg
from helpers.robot import (
    NODE_1,
    NOISE_OFF,
    REST_1,
    assert_command,
    expected,
    record_outputs,
    robot_1,
)
from helpers.ros_env import TIMEOUT
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from std_msgs.msg import Bool

from aes_ros import scenario as scenario_mod
from aes_ros.model import (
    Gains,
    SwarmCommand,
    motion_commands,
    total_forces,
    unicycle_step,
)
from aes_ros.ros import interface as names
from aes_ros.ros.interface import robot_topic
from aes_ros.ros.qos import COMMAND, LATCHED, SENSOR


def test_command_is_the_control_law(spawn, probe):
    """Noise off: cmd_vel and aes_force equal robot_command() for the same inputs,
    with the rotation centre from the poses, a fixed /swarm/rotation_center, or the
    live centroid recognised from the supervisor's message."""
    spawn.start(*robot_1(*NOISE_OFF), name="robot")
    cmds, forces = record_outputs(probe, 1)
    poses = probe.publisher(PoseArray, names.POSES, SENSOR)
    center = probe.publisher(PointStamped, names.ROTATION_CENTER, LATCHED)
    combined = scenario_mod.load("combined")
    gains = Gains.from_mapping({**combined.values, "d_r": 0.0, "d_theta": 0.0})
    rng = np.random.default_rng(1)

    # Before the supervisor speaks: the scenario's command about the centroid of the poses.
    for step in range(3):
        xy, yaw = rng.uniform(-0.3, 0.3, (3, 2)), rng.uniform(-np.pi, np.pi, 3)
        msg = poses_msg(xy, yaw, 1.0 + 0.05 * step)
        cmd = probe.exchange(lambda msg=msg: poses.publish(msg), cmds)
        probe.wait(lambda: len(forces) == len(cmds), TIMEOUT, "the force of that command")
        command = SwarmCommand((-1.0, 0.0), -0.7, tuple(xy.mean(axis=0)))
        assert_command(cmd, forces[-1], expected(xy, yaw, 1, [0, 2], REST_1, gains, command))

    # A fixed rotation centre.
    fixed = PointStamped()
    fixed.point.x, fixed.point.y = 5.0, -2.0
    center.publish(fixed)
    command = SwarmCommand((-1.0, 0.0), -0.7, (5.0, -2.0))
    want = expected(xy, yaw, 1, [0, 2], REST_1, gains, command)
    probe.until(
        lambda: poses.publish(msg), lambda: cmds[-1].angular.z == pytest.approx(want.angular)
    )
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
    probe.until(
        lambda: poses.publish(msg2), lambda: cmds[-1].angular.z == pytest.approx(want.angular)
    )
    assert_command(cmds[-1], forces[-1], want)


def test_stretched_springs_pull_toward_neighbours(spawn, probe):
    """A robot behind its neighbours drives and turns toward them; gains set at runtime
    apply to the next command; with noise on the command changes, the force does not."""
    spawn.start(*robot_1(*NOISE_OFF, rest_lengths="[0.2,0.2]"), name="robot")
    cmds, forces = record_outputs(probe, 1)
    poses = probe.publisher(PoseArray, names.POSES, SENSOR)
    results = probe.set_parameters(
        NODE_1,
        [Parameter("w_l", value=0.0), Parameter("w_r", value=0.0), Parameter("alpha", value=0.2)],
    )
    assert all(r.successful for r in results), results
    v0 = scenario_mod.load("combined").v0
    xy = [[0.5, 0.05], [0.0, 0.0], [0.5, -0.05]]  # neighbours 0.5 m east: stretched, symmetric

    def command_for(heading: float, t: float) -> Twist:
        msg = poses_msg(xy, [0.0, heading, 0.0], t)
        return probe.exchange(lambda: poses.publish(msg), cmds)

    facing = command_for(0.0, 1.0)
    assert facing.linear.x > v0 + 0.05 and abs(facing.angular.z) < 1e-9
    assert forces[-1].vector.x > 0.5 and forces[-1].vector.y == pytest.approx(0.0, abs=1e-12)
    away = command_for(math.pi, 1.05)
    assert away.linear.x < v0 - 0.05  # backs up toward them
    north = command_for(math.pi / 2, 1.1)
    assert north.linear.x == pytest.approx(v0, abs=1e-9) and north.angular.z < -0.5  # turns right

    noise_free = forces[-1].vector.x
    assert probe.set_parameters(NODE_1, [Parameter("d_r", value=0.5)])[0].successful
    noisy = [command_for(math.pi / 2, 1.15 + 0.05 * k) for k in range(3)]
    assert any(abs(c.linear.x - v0) > 1e-6 for c in noisy)
    assert forces[-1].vector.x == pytest.approx(noise_free, abs=1e-12)


def test_enable_and_bad_poses(spawn, probe):
    """/swarm/enabled false -> zero cmd_vel; NaN or too short poses are dropped with a
    warning and the node keeps working."""
    proc = spawn.start(*robot_1(*NOISE_OFF), name="robot")
    cmds = probe.record(Twist, robot_topic(1, names.CMD_VEL), COMMAND)
    poses = probe.publisher(PoseArray, names.POSES, SENSOR)
    enabled = probe.publisher(Bool, names.ENABLED, LATCHED)
    xy, yaw = [[0.5, 0.05], [0.0, 0.0], [0.5, -0.05]], [0.0, 0.3, 0.0]
    good = poses_msg(xy, yaw, 1.0)
    assert probe.exchange(lambda: poses.publish(good), cmds).linear.x > 0.1

    enabled.publish(Bool(data=False))
    probe.until(lambda: poses.publish(good), lambda: cmds[-1] == Twist())
    enabled.publish(Bool(data=True))
    probe.until(lambda: poses.publish(good), lambda: cmds[-1].linear.x > 0.1)

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
    assert probe.exchange(lambda: poses.publish(good), cmds).linear.x > 0.1
    assert proc.poll() is None
    log = spawn.log(proc).read_text()
    assert "dropped /swarm/poses" in log


def test_parameter_checks(spawn, probe):
    """Out-of-range or inconsistent parameter sets are rejected with a reason; the node
    keeps its old values and keeps running; valid sets apply."""
    proc = spawn.start(*robot_1(), name="robot")
    node = NODE_1
    cmds = probe.record(Twist, robot_topic(1, names.CMD_VEL), COMMAND)
    poses = probe.publisher(PoseArray, names.POSES, SENSOR)
    defaults = scenario_mod.load("combined")
    assert probe.get_parameters(node, ["alpha", "robot_id", "neighbors", "clip"]) == [
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
        (result,) = probe.set_parameters(node, [param])
        assert not result.successful, name
        assert result.reason, name
    assert "rest_lengths" in probe.set_parameters(node, [rejected["rest_lengths"]])[0].reason
    assert probe.get_parameters(node, ["alpha", "v0", "rest_lengths", "neighbor_source"]) == [
        defaults.alpha,
        defaults.v0,
        [0.2, 0.25],
        "poses",
    ]
    msg = poses_msg([[0.5, 0.05], [0.0, 0.0], [0.5, -0.05]], [0.0, 0.3, 0.0], 1.0)
    probe.exchange(lambda: poses.publish(msg), cmds)
    # Neighbours and their lengths change together atomically.
    assert probe.set_parameters_atomically(
        node, [Parameter("neighbors", value=[0]), Parameter("rest_lengths", value=[0.3])]
    ).successful
    assert probe.get_parameters(node, ["neighbors", "rest_lengths"]) == [[0], [0.3]]
    results = probe.set_parameters(
        node, [Parameter("alpha", value=0.1), Parameter("max_linear_speed", value=0.01)]
    )
    assert all(r.successful for r in results)
    assert probe.get_parameters(node, ["alpha"]) == [0.1]
    probe.until(lambda: poses.publish(msg), lambda: cmds[-1].linear.x == pytest.approx(0.01))
    assert proc.poll() is None
    # SIGTERM: clean shutdown.
    os.killpg(proc.pid, signal.SIGTERM)
    assert proc.wait(timeout=TIMEOUT) == 0
    assert "Traceback" not in spawn.log(proc).read_text()


def test_odom_source_and_neighbour_timeout(spawn, probe):
    """odom source (switched on at runtime): neighbours from their /mona_<j>/odom; one not
    heard from for longer than neighbor_timeout (by stamp) is left out of the sum."""
    spawn.start(*robot_1("-p", "neighbor_timeout:=0.5", *NOISE_OFF), name="robot")
    forces = probe.record(Vector3Stamped, robot_topic(1, names.AES_FORCE), COMMAND)
    # Switched at runtime: the node subscribes to its own and its neighbours' odom.
    params = [Parameter("neighbor_source", value="odom")]
    assert probe.set_parameters(NODE_1, params)[0].successful
    odom = [probe.publisher(Odometry, robot_topic(j, names.ODOM), SENSOR) for j in range(3)]
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

    probe.until(lambda: round_([0, 2]), force_is([0, 2]))
    clock[0] += 1.0  # neighbour 2 falls silent for longer than the timeout
    probe.until(lambda: round_([0]), force_is([0]))
    clock[0] += 1.0
    probe.until(lambda: round_([]), force_is([]))


@pytest.mark.parametrize(("source", "per_participant"), [("poses", 0), ("odom", 0), ("poses", 1)])
def test_host_runs_every_robot(spawn, probe, source, per_participant):
    """A host with 4 robots publishes every robot's command, equal to the control law
    with the process-wide -p overrides (use_sim_time among them) applied to every robot;
    also with each robot in a DDS participant of its own (``robots_per_participant``,
    what a host does under a discovery server), where each robot's parameters still
    answer and reject a bad value."""
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
        "-p",
        "use_sim_time:=true",
        "-p",
        f"robots_per_participant:={per_participant}",
        *NOISE_OFF,
        name="host",
    )
    scen = scenario_mod.load("linear").with_robots(4)
    xy, yaw = scen.initial_state(seed=3)
    _, table, rest_table = scen.sheet()
    gains = Gains.from_mapping({**scen.values, "alpha": 0.1, "d_r": 0.0, "d_theta": 0.0})
    command = SwarmCommand((-1.0, 0.0), 0.0, tuple(xy.mean(axis=0)))
    cmds, forces = zip(*[record_outputs(probe, i) for i in range(4)], strict=True)
    wants = []
    for i in range(4):
        keep = table[i] >= 0
        wants.append(expected(xy, yaw, i, table[i][keep], rest_table[i][keep], gains, command))

    def all_match() -> bool:
        # the force topic is matched on its own: wait for it too, not only the commands
        return all(forces) and all(
            c and (c[-1].linear.x, c[-1].angular.z) == pytest.approx((w.linear, w.angular))
            for c, w in zip(cmds, wants, strict=True)
        )

    clock = [1.0]
    if source == "poses":
        poses = probe.publisher(PoseArray, names.POSES, SENSOR)

        def send() -> None:
            clock[0] += 0.05
            poses.publish(poses_msg(xy, yaw, clock[0]))
    else:
        odom = [probe.publisher(Odometry, robot_topic(i, names.ODOM), SENSOR) for i in range(4)]

        def send() -> None:
            clock[0] += 0.05
            for i in range(4):
                odom[i].publish(odom_msg(*xy[i], yaw[i], clock[0]))

    probe.until(send, all_match)
    for i in range(4):
        assert_command(cmds[i][-1], forces[i][-1], wants[i])
    # use_sim_time: the host's clock drives the robots', and the parameter says so
    assert probe.get_parameters(
        "/mona_2/aes_robot", ["robot_id", "alpha", "neighbor_source", "use_sim_time"]
    ) == [2, 0.1, source, True]
    participants = 4 if per_participant == 1 else 1
    assert f"{participants} DDS participant(s)" in spawn.log(proc).read_text()
    for i in range(4):
        (result,) = probe.set_parameters(f"/mona_{i}/aes_robot", [Parameter("alpha", value=-1.0)])
        assert not result.successful and "alpha" in result.reason
    assert spawn.stop(proc) == 0  # SIGINT: clean shutdown
    assert "Traceback" not in spawn.log(proc).read_text()


def test_a_host_of_one_robot_drives_it_without_neighbours(spawn, probe):
    """A swarm of one: the lone robot has no springs (an empty sheet row, which rclpy
    once refused as a parameter override), and its command is the control law's."""
    proc = spawn.start(
        "aes-robot-host",
        "--ros-args",
        "-p",
        "scenario:=linear",
        "-p",
        "num_robots:=1",
        *NOISE_OFF,
        name="host",
    )
    scen = scenario_mod.load("linear").with_robots(1)
    xy, yaw = scen.initial_state(seed=3)
    gains = Gains.from_mapping({**scen.values, "d_r": 0.0, "d_theta": 0.0})
    command = SwarmCommand((-1.0, 0.0), 0.0, tuple(xy.mean(axis=0)))
    want = expected(xy, yaw, 0, np.array([], dtype=int), np.array([]), gains, command)
    cmds, forces = record_outputs(probe, 0)
    poses = probe.publisher(PoseArray, names.POSES, SENSOR)
    clock = [1.0]

    def send() -> None:
        clock[0] += 0.05
        poses.publish(poses_msg(xy, yaw, clock[0]))

    probe.until(send, lambda: bool(cmds) and bool(forces))
    assert_command(cmds[-1], forces[-1], want)
    assert probe.get_parameters("/mona_0/aes_robot", ["neighbors"]) == [[]]
    assert spawn.stop(proc) == 0
    assert "Traceback" not in spawn.log(proc).read_text()


def wakeups_per_second(pid: int, seconds: float = 1.0) -> float:
    """How often the threads of process ``pid`` went to sleep of their own accord (their
    voluntary context switches) per second, over ``seconds``."""

    def count() -> int:
        total = 0
        for task in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{task}/status") as fh:
                total += sum(
                    int(line.split()[1]) for line in fh if line.startswith("voluntary_ctxt")
                )
        return total

    before, start = count(), time.monotonic()
    time.sleep(seconds)
    return (count() - before) / (time.monotonic() - start)


def test_an_idle_odom_host_sleeps_and_a_batch_that_cannot_fill_still_goes_out(spawn, probe):
    """odom source: a host without odometry coming wakes about as rarely as one without
    robots to run (polling its batch every 4 ms was ~1000 wake-ups a second); a batch
    that cannot fill (one robot's odometry of four) goes out all the same, and the host
    is idle again afterwards."""
    proc = spawn.start(
        "aes-robot-host",
        "--ros-args",
        *("-p", "scenario:=linear", "-p", "num_robots:=4", "-p", "neighbor_source:=odom"),
        *NOISE_OFF,
        name="host",
    )
    cmds, _ = record_outputs(probe, 0)
    odom = probe.publisher(Odometry, robot_topic(0, names.ODOM), SENSOR)  # the host is up
    time.sleep(1.0)  # past its start
    assert wakeups_per_second(proc.pid) < 150
    clock = [1.0]

    def send() -> None:
        clock[0] += 0.05
        odom.publish(odom_msg(0.0, 0.0, 0.0, clock[0]))

    probe.until(send, lambda: cmds)
    time.sleep(0.5)
    assert wakeups_per_second(proc.pid) < 150


def test_lockstep_with_supervisor_equals_offline_model(spawn, probe):
    """Supervisor + host, stepped in lockstep by the test (kinematic unicycle, noise and
    clipping off): the trajectory equals the offline model's, combined scenario with the
    live centroid as rotation centre."""
    common = ["-p", "scenario:=combined", "-p", "num_robots:=9"]
    spawn.start("aes-supervisor", "--ros-args", *common, name="supervisor")
    spawn.start("aes-robot-host", "--ros-args", *common, *NOISE_OFF, name="host")
    scen = scenario_mod.load("combined").with_robots(9)
    _, table, rest_table = scen.sheet()
    gains = Gains.from_mapping({**scen.values, "d_r": 0.0, "d_theta": 0.0})
    cmds, forces = zip(*[record_outputs(probe, i) for i in range(9)], strict=True)
    centers = probe.record(PointStamped, names.ROTATION_CENTER, LATCHED)
    poses = probe.publisher(PoseArray, names.POSES, SENSOR, subscribers=2)  # host + supervisor

    xy, yaw = scen.initial_state(seed=7)
    ref_xy, ref_yaw = xy.copy(), yaw.copy()
    # Commands and forces are paired by their index below. A robot publishes
    # aes_force only once it sees a reader, cmd_vel always: so first wait until the
    # host has answered with both (every reader matched), then start counting.
    warmup = poses_msg(xy, yaw, 0.5)
    answered = lambda: all(f and c for f, c in zip(forces, cmds, strict=True))  # noqa: E731
    probe.until(lambda: poses.publish(warmup), answered)
    time.sleep(0.5)
    for received in (*cmds, *forces):
        received.clear()
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

        probe.until(lambda msg=msg: poses.publish(msg), lambda: replies() is not None)
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


@pytest.mark.alone  # 1000 robots in one host
def test_a_large_host_logs_every_robots_counts_before_it_tears_them_down(spawn, probe):
    """At SIGINT a host logs every robot's published counts (what a recording is checked
    against) before it destroys the robots one by one, which rmw makes slow in a large
    process (~80 ms a robot at 300): a host SIGKILLed at the launch's stop timeout keeps
    every count."""
    n = 300
    proc = spawn.start(
        "aes-robot-host", "--ros-args", "-p", "scenario:=combined", "-p", f"num_robots:={n}",
        name="host",
    )  # fmt: skip
    log = spawn.log(proc)
    deadline = time.monotonic() + 120.0
    while names.ROBOTS_READY not in log.read_text():
        assert proc.poll() is None and time.monotonic() < deadline, log.read_text()[-2000:]
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    counted: set[str] = set()
    deadline = time.monotonic() + 10.0
    while len(counted) < n and time.monotonic() < deadline:
        time.sleep(0.2)
        counted = {
            line.split("]: ", 1)[1].split(":", 1)[0]
            for line in log.read_text().splitlines()
            if "[published]: /mona_" in line
        }
    assert counted == {f"/mona_{i}" for i in range(n)}, f"{len(counted)} of {n} robots"
    proc.kill()  # what the launcher does at its stop timeout
    proc.wait(10)

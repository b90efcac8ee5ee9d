"""The arena keeper (issue #21) in real processes: the supervisor on its own, driven by
poses from the test's probe, and a whole ``aes-swarm launch`` driving at a wall.
"""

from __future__ import annotations

import subprocess
import time

import numpy as np
import pytest
from geometry_msgs.msg import PoseArray, Twist, TwistStamped
from helpers.messages import poses_msg, twist
from helpers.ros_env import TIMEOUT
from rclpy.parameter import Parameter
from std_msgs.msg import Bool

from aes_ros.arena import Arena
from aes_ros.ros import interface as names
from aes_ros.ros.launch.events import read_events
from aes_ros.ros.qos import COMMAND, LATCHED, SENSOR
from aes_ros.trajectory import load_trajectory

NODE = "/" + names.SUPERVISOR_NODE
SUPERVISOR = ["aes-supervisor", "--ros-args", "-p", "scenario:=linear", "-p", "num_robots:=4"]
TURNED = "arena keeper turned the swarm"
STOPPED = "arena keeper stopped the swarm"


def drive(msg: TwistStamped) -> tuple[float, float]:
    return (msg.twist.linear.x, msg.twist.linear.y)


def test_supervisor_keeper_turns_stops_and_is_off_without_an_arena(spawn, probe) -> None:
    """Four robots 0.05 m from x = -1, the command west. Without an arena the command is
    untouched; bad arena parameters are rejected with a reason; with the arena
    [-1, 3, -1, 1] the keeper turns v_d to the centre (|v_d| kept, the parameter agrees,
    the event logged); under ``stop`` a west command disables the robots instead;
    an empty arena switches the keeper off again."""
    proc = spawn.start(*SUPERVISOR, name="supervisor")
    velocity = probe.record(TwistStamped, names.DESIRED_VELOCITY, LATCHED)
    enabled = probe.record(Bool, names.ENABLED, LATCHED)
    probe.wait(lambda: velocity and enabled, TIMEOUT, "the latched command")
    assert drive(velocity[-1]) == (-1.0, 0.0) and enabled[-1].data is True
    assert probe.get_parameters(NODE, ["arena", "arena_policy", "arena_margin"]) == [
        [],
        "turn",
        pytest.approx(0.17),
    ]

    xy = np.array([[-0.95, -0.1], [-0.95, 0.1], [-0.75, -0.1], [-0.75, 0.1]])
    pose = poses_msg(xy, np.full(4, np.pi), 1.0)
    poses = probe.publisher(PoseArray, names.POSES, SENSOR)
    probe.every(0.05, lambda: poses.publish(pose))
    log = spawn.log(proc)
    probe.wait(lambda: names.SUPERVISOR_RECEIVING_POSES in log.read_text(), TIMEOUT, "poses")
    time.sleep(1.0)  # 20 poses: nothing changes without an arena
    assert [drive(m) for m in velocity] == [(-1.0, 0.0)] and len(enabled) == 1

    for bad in (
        Parameter("arena", value=[1.0, -1.0, -1.0, 1.0]),
        Parameter("arena", value=[-1.0, 1.0]),
        Parameter("arena", value=[-1.0, 1.0, -1.0, 1e9]),
        Parameter("arena", value="-1,1,-1,1"),
        Parameter("arena_policy", value="bounce"),
        Parameter("arena_margin", value=-0.1),
    ):
        (result,) = probe.set_parameters(NODE, [bad])
        assert not result.successful and bad.name in result.reason, (bad.value, result.reason)
    assert probe.get_parameters(NODE, ["arena"]) == [[]]

    # integers, as `ros2 param set /supervisor arena "[-1, 3, -1, 1]"` sends them
    (result,) = probe.set_parameters(NODE, [Parameter("arena", value=[-1, 3, -1, 1])])
    assert result.successful, result.reason
    probe.wait(lambda: drive(velocity[-1])[0] > 0.0, TIMEOUT, "the keeper's turn")
    new = np.array(drive(velocity[-1]))
    to_centre = Arena(-1.0, 3.0, -1.0, 1.0).centre - xy.mean(axis=0)
    np.testing.assert_allclose(new, to_centre / np.linalg.norm(to_centre), atol=1e-12)
    assert probe.get_parameters(NODE, ["desired_direction"]) == [list(new)]
    time.sleep(0.5)
    assert len(velocity) == 2, "the keeper acted more than once"
    probe.wait(lambda: f"{names.LOG_EVENT} {TURNED}" in log.read_text(), TIMEOUT, "the log line")

    (result,) = probe.set_parameters(NODE, [Parameter("arena_policy", value="stop")])
    assert result.successful
    cmd = probe.publisher(Twist, names.CMD, COMMAND)
    cmd.publish(twist(vx=-0.5))
    probe.wait(lambda: enabled[-1].data is False, TIMEOUT, "the keeper's stop")
    assert drive(velocity[-1]) == (-0.5, 0.0)  # the command stays; the robots stand
    probe.wait(lambda: f"{names.LOG_EVENT} {STOPPED}" in log.read_text(), TIMEOUT, "the log line")

    (result,) = probe.set_parameters(NODE, [Parameter("arena", value=[])])
    assert result.successful, result.reason
    (result,) = probe.set_parameters(NODE, [Parameter("enabled", value=True)])
    assert result.successful
    time.sleep(1.0)
    assert enabled[-1].data is True and drive(velocity[-1]) == (-0.5, 0.0)
    assert spawn.stop(proc) == 0
    assert "Traceback" not in log.read_text()


def test_launch_turns_the_swarm_before_the_wall(spawn, probe, tmp_path) -> None:
    """``aes-swarm launch --setup linear --robots 9`` (real time) with the arena's west
    wall 0.4 m ahead of the sheet: the keeper turns the swarm back east before the wall.
    No position on /swarm/poses (nor in the run's trajectory) is ever outside the arena,
    /swarm/desired_velocity turned from west to east, events.csv holds the turn, and the
    swarm comes back from the wall."""
    n = 9
    out = tmp_path / "run"
    arena = Arena(-0.6, 2.0, -1.0, 1.0)  # the sheet starts at x = -0.2 … 0.2
    probe.sample_poses(n)
    launcher = spawn.start(
        "aes-swarm", "launch", "--setup", "linear", "--robots", str(n), "--duration", "16",
        "--set", "arena=" + ",".join(str(v) for v in arena.bounds), "--out", str(out),
        name="launch",
    )  # fmt: skip
    try:
        assert launcher.wait(90) == 0, spawn.log(launcher).read_text()[-3000:]
    except subprocess.TimeoutExpired:
        pytest.fail(f"launch did not end:\n{spawn.log(launcher).read_text()[-3000:]}")

    positions = np.array(probe.positions)  # (T, N, 2)
    assert len(positions) > 200, len(positions)
    lowest = arena.clearances(positions).min()
    assert lowest > 0.0, f"a robot {-lowest:.3f} m outside the arena"
    trajectory = load_trajectory(out)
    assert arena.clearances(np.asarray(trajectory.positions)).min() > 0.0

    directions = [drive(m) for m in probe.desired]
    assert directions[0] == (-1.0, 0.0) and directions[-1][0] > 0.9, directions

    rows = [r for r in read_events(out / "events.csv") if r["event"] == TURNED]
    assert len(rows) == 1, read_events(out / "events.csv")
    assert rows[0]["process"] == names.SUPERVISOR_NODE and "west wall" in rows[0]["action"]
    assert float(rows[0]["sim_time"]) > 0.0

    x = positions[:, :, 0].mean(axis=1)
    assert x[-1] > x.min() + 0.3, "the swarm did not come back from the wall"
    print(f"closest any robot came to a wall: {lowest:.3f} m (margin 0.17 m)")


def test_arena_from_the_command_line_and_a_bad_one_fails_cleanly(spawn, probe) -> None:
    """``-p arena:=[…]`` sets the keeper's arena at start; an arena with x_min > x_max
    is reported by name and the process exits 1."""
    good = spawn.start(
        *SUPERVISOR, "-p", "arena:=[-1.5,1.5,-1.0,1.0]", "-p", "arena_policy:=stop",
        name="supervisor",
    )  # fmt: skip
    assert probe.get_parameters(NODE, ["arena", "arena_policy"]) == [
        [-1.5, 1.5, -1.0, 1.0],
        "stop",
    ]
    assert spawn.stop(good) == 0
    bad = spawn.start(*SUPERVISOR, "-p", "arena:=[1.5,-1.5,-1.0,1.0]", name="bad_supervisor")
    assert bad.wait(timeout=TIMEOUT) == 1
    log = spawn.log(bad).read_text()
    assert "arena" in log and "x_min < x_max" in log and "Traceback" not in log

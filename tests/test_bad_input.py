"""Bad input never crashes a node and never silently corrupts it.

Fills the gaps left by test_robot_node.py (NaN and short /swarm/poses, out-of-range
and mismatched parameters), test_supervisor.py (NaN and too large /swarm/cmd) and
test_cli.py (bad scenario files for ``simulate``): infinite and huge values on every
input topic, ``odom``, wrong-length arrays at the supervisor, parameters of the
wrong type, malformed parameter and scenario files for the nodes, warnings
throttled per kind. Property-based tests (hypothesis) for the ROS boundary
(:mod:`aes_ros.ros.conversions`) and the control law over every input that
boundary lets through; tests/test_properties.py covers the core on small scenes.
"""

from __future__ import annotations

import math
import re
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from aes_ros import model
from aes_ros.model import Gains, SwarmCommand
from aes_ros.params import PARAMS

rclpy = pytest.importorskip("rclpy")

from conftest import wait_for  # noqa: E402
from geometry_msgs.msg import (  # noqa: E402
    Point,
    PointStamped,
    Pose,
    PoseArray,
    Twist,
    TwistStamped,
    Vector3Stamped,
)
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402
from test_robot_node import (  # noqa: E402
    NOISE_OFF,
    REST_1,
    ROBOT_1,
    TIMEOUT,
    Driver,
    exchange,
    expected,
    odom_msg,
    poses_msg,
    until,
)

from aes_ros import scenario as scenario_mod  # noqa: E402
from aes_ros.ros.conversions import (  # noqa: E402
    MAX_COORDINATE,
    BadMessageError,
    arrays_to_poses,
    odom_to_pose,
    point_to_array,
    poses_to_arrays,
    twist_to_drive,
)
from aes_ros.ros.qos import COMMAND, LATCHED, SENSOR  # noqa: E402
from robot_node.controller import REST_LENGTH_RANGE  # noqa: E402

BAD_NUMBERS = [math.nan, math.inf, -math.inf, 1e300, -2.0 * MAX_COORDINATE]


@pytest.fixture
def driver(ros_env):
    d = Driver()
    try:
        yield d
    finally:
        d.close()


def quiet(received: list, send, seconds: float = 0.6) -> None:
    """``send()`` a few times; assert that nothing arrives in ``received``."""
    count = len(received)
    for _ in range(3):
        send()
        time.sleep(seconds / 3)
    assert len(received) == count


def same_force(msg: Vector3Stamped, want) -> bool:
    return (msg.vector.x, msg.vector.y) == pytest.approx(tuple(want), abs=1e-12)


def warnings_in(log: Path, kind: str) -> int:
    return len(re.findall(rf"\[WARN\].*{re.escape(kind)}", log.read_text()))


# ----------------------------------------------------------------------------- robot node


def test_robot_node_drops_bad_messages_and_parameters_keeps_last_good(spawn, driver):
    """NaN, ±inf, 1e300 and coordinates beyond ±1e6 m on /swarm/poses, odom, a
    neighbour's odom, /swarm/desired_velocity and /swarm/rotation_center; parameters
    of the wrong type or out of range: no command from a bad message, the next good
    one gives exactly the command of the last good values, one warning per kind
    (throttled), the node stays up."""
    proc = spawn.start(
        "aes-robot-node", "--ros-args", *ROBOT_1, "-p", "rest_lengths:=[0.2,0.25]",
        "-p", "neighbor_timeout:=1000.0", *NOISE_OFF, name="robot",
    )  # fmt: skip
    log = spawn.procs[-1][1]
    node = "/mona_1/aes_robot"
    forces = driver.record(Vector3Stamped, "/mona_1/aes_force", COMMAND)
    cmds = driver.record(Twist, "/mona_1/cmd_vel", COMMAND)
    poses = driver.publisher(PoseArray, "/swarm/poses", SENSOR)
    desired = driver.publisher(TwistStamped, "/swarm/desired_velocity", LATCHED)
    center = driver.publisher(PointStamped, "/swarm/rotation_center", LATCHED)
    gains = Gains.from_mapping({**scenario_mod.load("combined").values, "d_r": 0.0})
    xy, yaw = np.array([[0.5, 0.05], [0.0, 0.0], [0.5, -0.05]]), np.array([0.0, 0.3, 0.0])
    clock = [1.0]

    def good() -> PoseArray:
        clock[0] += 0.05
        return poses_msg(xy, yaw, clock[0])

    want = expected(
        xy, yaw, 1, [0, 2], REST_1, gains, SwarmCommand((-1.0, 0.0), -0.7, tuple(xy.mean(0)))
    )
    assert same_force(exchange(lambda: poses.publish(good()), forces), want.force)

    # /swarm/poses: non-finite or huge values anywhere, no pose for this robot.
    bad_poses = []
    for value in BAD_NUMBERS:
        for robot, field in ((0, "x"), (1, "y")):
            msg = good()
            setattr(msg.poses[robot].position, field, value)
            bad_poses.append(msg)
        msg = good()
        msg.poses[2].orientation.z = value
        bad_poses.append(msg)
    bad_poses += [poses_msg(xy[:1], yaw[:1], 9.0), PoseArray()]
    quiet(forces, lambda: [poses.publish(m) for m in bad_poses])

    # Swarm command and rotation centre: non-finite, huge or out of the allowed range.
    for vx, vy, w in [(math.nan, 0, 0), (math.inf, 0, 0), (0, -math.inf, 0), (1e300, 0, 0),
                      (0, 50.0, 0), (0, 1, math.nan), (0, 1, 1e3)]:  # fmt: skip
        msg = TwistStamped()
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.angular.z = (
            float(v) for v in (vx, vy, w)
        )
        desired.publish(msg)
    for value in BAD_NUMBERS:
        center.publish(PointStamped(point=Point(x=value, y=0.0)))
    time.sleep(0.5)
    assert same_force(exchange(lambda: poses.publish(good()), forces), want.force)

    # Parameters of the wrong type or out of range: rejected with a reason.
    rejected = [
        Parameter("alpha", value="fast"),
        Parameter("alpha", value=[0.1]),
        Parameter("robot_id", value=1.5),
        Parameter("neighbors", value=[0.5, 2.0]),
        Parameter("neighbors", value=[0, 2**40]),
        Parameter("rest_lengths", value=["0.2", "0.25"]),
        Parameter("rest_lengths", value=[1e-9, 0.25]),
        Parameter("rest_lengths", value=[math.inf, 0.25]),
        Parameter("rest_lengths", value=[0.2, 1e300]),
        Parameter("clip", value="yes"),
        Parameter("neighbor_timeout", value=-1.0),
        Parameter("seed", value=2**40),
        Parameter("k", value=math.inf),
    ]
    for param in rejected:
        (result,) = driver.set_parameters(node, [param])
        assert not result.successful and result.reason, (param.name, param.value)
    names = ["alpha", "robot_id", "neighbors", "rest_lengths", "clip", "k"]
    assert driver.get_parameters(node, names) == [
        gains.alpha, 1, [0, 2], REST_1, False, gains.k,
    ]  # fmt: skip
    assert same_force(exchange(lambda: poses.publish(good()), forces), want.force)

    # odom source: bad own odometry gives no command; a bad neighbour odometry is
    # dropped and the neighbour's last good position stays in use.
    assert driver.set_parameters(node, [Parameter("neighbor_source", value="odom")])[0].successful
    odom = [driver.publisher(Odometry, f"/mona_{j}/odom", SENSOR) for j in range(3)]
    want_odom = expected(xy, yaw, 1, [0, 2], REST_1, gains, SwarmCommand((-1.0, 0.0), -0.7, None))

    def odom_round(neighbour_0: Odometry | None = None) -> None:
        clock[0] += 0.05
        odom[0].publish(neighbour_0 or odom_msg(*xy[0], yaw[0], clock[0]))
        odom[2].publish(odom_msg(*xy[2], yaw[2], clock[0]))
        time.sleep(0.05)
        odom[1].publish(odom_msg(*xy[1], yaw[1], clock[0]))

    until(odom_round, lambda: forces and same_force(forces[-1], want_odom.force))
    for value in BAD_NUMBERS:
        own = odom_msg(*xy[1], yaw[1], clock[0] + 0.05)
        own.pose.pose.position.x = value
        quiet(forces, lambda own=own: odom[1].publish(own), 0.3)
    for value in BAD_NUMBERS:
        far = odom_msg(*xy[0], yaw[0], clock[0] + 0.05)
        far.pose.pose.position.y = value
        count = len(forces)
        until(lambda far=far: odom_round(far), lambda count=count: len(forces) > count)
        assert same_force(forces[-1], want_odom.force), value

    # A good swarm command still changes the command (the checks above are not vacuous).
    north = TwistStamped()
    north.twist.linear.y = 1.0
    desired.publish(north)
    new = expected(xy, yaw, 1, [0, 2], REST_1, gains, SwarmCommand((0.0, 1.0), 0.0, None))
    until(odom_round, lambda: same_force(forces[-1], new.force))
    assert not same_force(forces[-1], want_odom.force)

    assert proc.poll() is None
    assert all(math.isfinite(c.linear.x) and math.isfinite(c.angular.z) for c in cmds)
    assert all(math.isfinite(f.vector.x) and math.isfinite(f.vector.y) for f in forces)
    # One warning per kind of bad input (each kind throttled on its own, 5 s):
    # about 35 bad poses messages were sent within a few seconds.
    kinds = ["/swarm/poses", "/swarm/desired_velocity", "/swarm/rotation_center", "odom"]
    for kind in [f"dropped {k}" for k in [*kinds, "/mona_0/odom"]]:
        assert 1 <= warnings_in(log, kind) <= 3, kind
    assert "Traceback" not in log.read_text()


# ----------------------------------------------------------------------------- supervisor

SUPERVISOR = ["aes-supervisor", "--ros-args", "-p", "scenario:=linear", "-p", "num_robots:=4"]


def test_supervisor_drops_bad_messages_and_parameters(spawn, driver):
    """±inf and 1e300 on /swarm/cmd; NaN, huge and wrong-length /swarm/poses; parameters
    of the wrong type: the command and the parameters stay, no centre or metrics from a
    bad poses message, one warning per kind, the node stays up."""
    proc = spawn.start(*SUPERVISOR, "-p", "publish_rate:=20.0", name="supervisor")
    log = spawn.procs[-1][1]
    velocity = driver.record(TwistStamped, "/swarm/desired_velocity", LATCHED)
    centers = driver.record(PointStamped, "/swarm/rotation_center", LATCHED)
    alignment = driver.record(Float64, "/swarm/alignment", LATCHED)
    poses = driver.publisher(PoseArray, "/swarm/poses", SENSOR)
    cmd = driver.publisher(Twist, "/swarm/cmd", COMMAND)
    assert wait_for(lambda: velocity, TIMEOUT)
    xy, yaw = scenario_mod.load("linear").with_robots(4).initial_state(seed=2)
    good = poses_msg(xy, yaw, 1.0)
    exchange(lambda: poses.publish(good), centers)
    assert wait_for(lambda: alignment, TIMEOUT)

    for vx, vy, w in [(math.inf, 0, 0), (0, -math.inf, 0), (1e300, 0, 0), (0, 0, -math.inf),
                      (0, 0, 1e300)]:  # fmt: skip
        bad = Twist()
        bad.linear.x, bad.linear.y, bad.angular.z = (float(v) for v in (vx, vy, w))
        cmd.publish(bad)

    bad_poses = []
    for value in BAD_NUMBERS:
        msg = poses_msg(xy, yaw, 2.0)
        msg.poses[3].position.x = value
        bad_poses.append(msg)
    bad_poses += [poses_msg(xy[:3], yaw[:3], 2.0), PoseArray()]
    bad_poses.append(poses_msg(np.vstack([xy, [[9.0, 9.0]]]), np.append(yaw, 0.0), 2.0))
    n_centers, n_alignment = len(centers), len(alignment)
    for _ in range(3):
        for msg in bad_poses:
            poses.publish(msg)
        time.sleep(0.2)
    time.sleep(0.3)
    assert len(centers) == n_centers and len(alignment) == n_alignment

    for param in [
        Parameter("desired_direction", value="north"),
        Parameter("desired_direction", value=[math.nan, 0.0]),
        Parameter("rotation_rate", value=[1.0]),
        Parameter("rotation_rate", value=math.inf),
        Parameter("rotation_center", value=[1.0]),
        Parameter("rotation_center", value=[1e300, 0.0]),
        Parameter("rotation_center_mode", value=3),
        Parameter("publish_rate", value=0.0),
        Parameter("enabled", value="yes"),
    ]:
        (result,) = driver.set_parameters("/supervisor", [param])
        assert not result.successful and result.reason, (param.name, param.value)
    assert driver.get_parameters(
        "/supervisor", ["desired_direction", "rotation_rate", "rotation_center_mode", "enabled"]
    ) == [[-1.0, 0.0], 0.0, "centroid", True]
    assert [(v.twist.linear.x, v.twist.linear.y) for v in velocity] == [(-1.0, 0.0)]
    # Still working: a good message is used at once.
    center = exchange(lambda: poses.publish(poses_msg(xy + 1.0, yaw, 3.0)), centers)
    assert (center.point.x, center.point.y) == pytest.approx(tuple(xy.mean(0) + 1.0))
    assert proc.poll() is None
    for kind in ("dropped /swarm/cmd", "dropped /swarm/poses"):
        assert 1 <= warnings_in(log, kind) <= 2, kind
    assert "Traceback" not in log.read_text()


# ----------------------------------------------------------------------------- files

BAD_FILES = {
    "not_yaml.yaml": "/**:\n  ros__parameters: [1, 2\n",
    "wrong_type.yaml": "/**:\n  ros__parameters:\n    alpha: fast\n",
    "mismatch.yaml": "/**:\n  ros__parameters:\n    neighbors: [0, 2]\n    rest_lengths: [0.2]\n",
    "range.yaml": "/**:\n  ros__parameters:\n    k: -5.0\n",
    "scenario_bad.yaml": "alpha: [1, 2\n",
    "scenario_unknown.yaml": "speed_of_light: 3\n",
}


@pytest.mark.parametrize(
    ("exe", "args", "message"),
    [
        ("aes-robot-node", ["--params-file", "{d}/not_yaml.yaml"], "Couldn't parse params file"),
        ("aes-robot-node", ["--params-file", "{d}/missing.yaml"], "Error opening YAML file"),
        ("aes-robot-node", ["--params-file", "{d}/wrong_type.yaml"], "'alpha'"),
        ("aes-robot-node", ["-p", "neighbors:=[0,2]", "--params-file", "{d}/mismatch.yaml"],
         "rest_lengths: 1 values for 2 neighbors"),
        ("aes-robot-node", ["-p", "scenario:={d}/scenario_bad.yaml"], "not valid YAML"),
        ("aes-robot-host", ["--params-file", "{d}/not_yaml.yaml"], "Couldn't parse params file"),
        ("aes-robot-host", ["--params-file", "{d}/range.yaml"], "Parameter k out of range"),
        ("aes-supervisor", ["--params-file", "{d}/not_yaml.yaml"], "Couldn't parse params file"),
        ("aes-supervisor", ["--params-file", "{d}/range.yaml"], "Parameter k out of range"),
        ("aes-supervisor", ["-p", "scenario:={d}/scenario_unknown.yaml"], "speed_of_light"),
    ],
)  # fmt: skip
def test_malformed_parameter_and_scenario_files_fail_cleanly(spawn, tmp_path, exe, args, message):
    """A malformed, missing or inconsistent parameter or scenario file: the node does not
    start, says why (and which field) and exits 1, without a traceback."""
    for name, text in BAD_FILES.items():
        (tmp_path / name).write_text(text)
    args = [a.format(d=tmp_path) for a in args]
    proc = spawn.start(exe, "--ros-args", "-r", "__ns:=/mona_1", *args, name="node")
    assert proc.wait(timeout=TIMEOUT) == 1
    out = spawn.procs[-1][1].read_text()
    assert "cannot start" in out and message in out, out
    assert "Traceback" not in out, out


# ----------------------------------------------------------------------------- properties

any_float = st.floats(allow_nan=True, allow_infinity=True)
finite = st.floats(allow_nan=False, allow_infinity=False)
accepted = st.floats(-MAX_COORDINATE, MAX_COORDINATE)


def make_pose(x: float, y: float, q: tuple[float, float, float, float]) -> Pose:
    pose = Pose()
    pose.position.x, pose.position.y = x, y
    o = pose.orientation
    o.x, o.y, o.z, o.w = q
    return pose


@settings(max_examples=300, deadline=None)
@given(values=st.lists(st.tuples(any_float, any_float, st.tuples(*[any_float] * 4)), max_size=6))
def test_conversions_reject_or_return_finite_bounded_arrays(values) -> None:
    """Any PoseArray, Odometry or Point: either BadMessageError or finite positions
    within ±MAX_COORDINATE and headings in [-π, π] — never a NaN for the model."""
    with np.errstate(over="raise", invalid="raise", divide="raise"):  # overflow = a bug
        msg = PoseArray()
        msg.poses = [make_pose(x, y, q) for x, y, q in values]
        try:
            xy, yaw = poses_to_arrays(msg)
        except BadMessageError:
            pass
        else:
            assert xy.shape == (len(values), 2) and yaw.shape == (len(values),)
            assert np.all(np.abs(xy) <= MAX_COORDINATE) and np.all(np.abs(yaw) <= math.pi)
        for pose in msg.poses:
            odom = Odometry()
            odom.pose.pose = pose
            try:
                _, x, y, heading = odom_to_pose(odom)
            except BadMessageError:
                continue
            assert abs(x) <= MAX_COORDINATE and abs(y) <= MAX_COORDINATE
            assert abs(heading) <= math.pi
            assert point_to_array(pose.position) == pytest.approx([x, y])


@settings(max_examples=200, deadline=None)
@given(xy=arrays(float, st.tuples(st.integers(0, 6), st.just(2)), elements=accepted),
       yaw=st.floats(-math.pi, math.pi))  # fmt: skip
def test_poses_round_trip(xy, yaw) -> None:
    headings = np.full(len(xy), yaw)
    msg = PoseArray()
    msg.poses = arrays_to_poses(xy, headings)
    back, back_yaw = poses_to_arrays(msg, expected=len(xy))
    np.testing.assert_array_equal(back, xy)
    np.testing.assert_allclose(np.angle(np.exp(1j * (back_yaw - headings))), 0.0, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(values=st.tuples(any_float, any_float, any_float))
def test_twist_to_drive_is_finite_or_rejected(values) -> None:
    msg = Twist()
    msg.linear.x, msg.linear.y, msg.angular.z = values
    if all(math.isfinite(v) for v in values):
        (vx, vy), w = twist_to_drive(msg)
        assert (vx, vy, w) == values
    else:
        with pytest.raises(BadMessageError):
            twist_to_drive(msg)


direction_part = st.floats(PARAMS["direction"].low, PARAMS["direction"].high)


@settings(max_examples=300, deadline=None)
@given(
    own=st.tuples(accepted, accepted),
    heading=st.floats(-math.pi, math.pi),
    others=arrays(float, st.tuples(st.integers(0, 6), st.just(2)),
                  elements=st.sampled_from([0.0, MAX_COORDINATE, -MAX_COORDINATE]) | accepted),
    rest=st.floats(*REST_LENGTH_RANGE),
    direction=st.tuples(direction_part, direction_part),
    omega=st.floats(PARAMS["omega"].low, PARAMS["omega"].high),
    center=st.none() | st.tuples(accepted, accepted),
    coincident=st.booleans(),
    clip=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)  # fmt: skip
def test_control_law_is_finite_for_everything_the_boundary_accepts(
    own, heading, others, rest, direction, omega, center, coincident, clip, seed
) -> None:
    """Every input a robot node accepts (positions within ±MAX_COORDINATE, rest lengths
    and swarm command within their parameter ranges, neighbours possibly on top of the
    robot) gives a finite command and force: nothing non-finite reaches cmd_vel."""
    if coincident:
        others = np.vstack([others, [own]])
    out = model.robot_command(
        np.array(own), heading, others, np.full(len(others), rest), Gains(),
        SwarmCommand(direction, omega, center), 0.05, rng=np.random.default_rng(seed),
        limits=(0.13, 3.4) if clip else None,
    )  # fmt: skip
    assert math.isfinite(out.linear) and math.isfinite(out.angular)
    assert np.all(np.isfinite(out.force))

"""End-to-end tests of the ROS 2 system (SPEC §7): real processes over Fast DDS.

Every test gets its own ROS_DOMAIN_ID (``ros_env``/``spawn`` fixtures) and
starts the system as a user would: ``aes-swarm launch`` (which starts
aes-sim-bridge, aes-supervisor and the robot hosts/nodes as separate
processes), ``scripts/start_swarm.sh`` or ``aes-swarm steer``. An observer node
in the test process watches ``/swarm/poses`` and calls the services. Runs use
16 robots or fewer and lockstep at full speed where the test allows, so that
the sim-time spans the checks need cost little wall time.

Coverage of the layouts and neighbour sources: single + poses (linear/bag),
per-core + poses (offline equality, enable/parameters), per-core + odom
(steering), per-robot + poses (rotation), hand-started hosts (script).
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from aes_ros import metrics, scenario, simulator
from aes_ros.report import load_trajectory

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip("rclpy")

from geometry_msgs.msg import PoseArray, TwistStamped  # noqa: E402
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue  # noqa: E402
from rcl_interfaces.srv import GetParameters, SetParameters  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

from aes_ros.ros.bag import read_bag  # noqa: E402
from aes_ros.ros.conversions import poses_to_arrays  # noqa: E402
from aes_ros.ros.qos import LATCHED  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
#: Fast, deterministic stepping: each control step waits for every robot's command.
FAST = ("--lockstep", "--real-time-factor", "0")


# ----------------------------------------------------------------------------- helpers


def launch_cmd(*args: str) -> list[str]:
    return ["aes-swarm", "launch", *args]


def run_launch(spawn, *args: str, timeout: float = 120.0) -> tuple[int, str]:
    """Run ``aes-swarm launch`` to completion; returns (exit code, its output)."""
    proc = spawn.start(*launch_cmd(*args), name="launch")
    log = spawn.procs[-1][1]
    try:
        rc = proc.wait(timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f"aes-swarm launch did not finish in {timeout} s:\n{log.read_text()[-3000:]}")
    return rc, log.read_text()


def processes_in_domain(domain: str) -> list[str]:
    """Command lines of live processes (other than this one) with this ROS_DOMAIN_ID."""
    found = []
    needle = f"ROS_DOMAIN_ID={domain}".encode()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if needle not in (entry / "environ").read_bytes().split(b"\0"):
                continue
            stat = (entry / "stat").read_text()
            if stat.rsplit(")", 1)[1].split()[0] == "Z":
                continue
            found.append((entry / "cmdline").read_bytes().replace(b"\0", b" ").decode())
        except OSError:
            continue
    return found


def assert_no_orphans(ros_env: dict[str, str], timeout: float = 15.0) -> None:
    domain = ros_env["ROS_DOMAIN_ID"]
    deadline = time.monotonic() + timeout
    while processes_in_domain(domain) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert processes_in_domain(domain) == []


def direction_deg(v: np.ndarray) -> float:
    return math.degrees(math.atan2(v[1], v[0]))


class Observer:
    """A node in the test process: samples /swarm/poses, calls services."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context)
        self.node = rclpy.create_node("test_observer", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.times: list[float] = []
        self.positions: list[np.ndarray] = []
        self.headings: list[np.ndarray] = []
        self.desired: list[TwistStamped] = []
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.node.create_subscription(PoseArray, "/swarm/poses", self.on_poses, qos)
        self.node.create_subscription(
            TwistStamped, "/swarm/desired_velocity", self.desired.append, LATCHED
        )

    def on_poses(self, msg: PoseArray) -> None:
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if len(msg.poses) != self.n or (self.times and t <= self.times[-1]):
            return
        pos, head = poses_to_arrays(msg)
        self.times.append(t)
        self.positions.append(pos)
        self.headings.append(head)

    @property
    def now(self) -> float:
        return self.times[-1] if self.times else -1.0

    def spin_until(self, predicate, timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                pytest.fail(f"timed out after {timeout} s waiting for {what} (sim t={self.now})")
            self.executor.spin_once(timeout_sec=0.05)

    def wait_sim(self, t: float, timeout: float = 60.0) -> None:
        self.spin_until(lambda: self.now >= t, timeout, f"sim time {t}")

    def wait_all_moving(self, timeout: float = 120.0) -> float:
        """Wait until every robot has moved from its first sampled position; returns
        that sim time (robots start a few seconds after the bridge's clock in real time)."""

        def moving() -> bool:
            return len(self.times) > 1 and bool(
                np.all(np.linalg.norm(self.positions[-1] - self.positions[0], axis=-1) > 1e-4)
            )

        self.spin_until(moving, timeout, "every robot moving")
        return self.now

    def index_at(self, t: float) -> int:
        """The first sample at or after sim time t (else the last one)."""
        k = int(np.searchsorted(np.asarray(self.times), t - 1e-9))
        return min(k, len(self.times) - 1)

    def position_at(self, t: float) -> np.ndarray:
        """Positions (N, 2) of the first sample at or after sim time t."""
        return self.positions[self.index_at(t)]

    def motion(self, t0: float, t1: float) -> np.ndarray:
        """Per robot, the larger of its displacement [m] and its turn [rad] from t0 to t1."""
        a, b = self.index_at(t0), self.index_at(t1)
        moved = np.linalg.norm(self.positions[b] - self.positions[a], axis=-1)
        turned = np.abs(np.angle(np.exp(1j * (self.headings[b] - self.headings[a]))))
        return np.maximum(moved, turned)

    def call(self, srv_type, name: str, request, timeout: float = 20.0):
        client = self.node.create_client(srv_type, name)
        try:
            self.spin_until(lambda: client.service_is_ready(), timeout, f"service {name}")
            future = client.call_async(request)
            self.spin_until(future.done, timeout, f"answer of {name}")
            return future.result()
        finally:
            self.node.destroy_client(client)

    def set_double(self, node: str, name: str, value: float):
        param = Parameter(
            name=name,
            value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value),
        )
        return self.call(
            SetParameters, f"{node}/set_parameters", SetParameters.Request(parameters=[param])
        ).results[0]

    def get_double(self, node: str, name: str) -> float:
        reply = self.call(
            GetParameters, f"{node}/get_parameters", GetParameters.Request(names=[name])
        )
        return reply.values[0].double_value

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.fixture
def observer_factory():
    made: list[Observer] = []

    def make(n: int) -> Observer:
        obs = Observer(n)
        made.append(obs)
        return obs

    yield make
    for obs in made:
        obs.close()


# ----------------------------------------------------------------------------- CLI checks


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["launch", "--layout", "ring"], "--layout"),
        (["launch", "--robots", "0"], "--robots"),
        (["launch", "--neighbor-source", "wifi"], "--neighbor-source"),
        (["launch", "--real-time-factor", "-1"], "--real-time-factor"),
        (["launch", "--set", "alpha=-1"], "alpha"),
        (["launch", "--setup", "spiral"], "--setup"),
        (["steer"], "--direction"),
        (["steer", "--omega", "nan"], "--omega"),
    ],
)
def test_bad_arguments_exit_2_naming_the_option(args: list[str], option: str) -> None:
    out = subprocess.run(
        [str(BIN / "aes-swarm"), *args], capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 2, out
    assert option in out.stderr


def test_bag_schemas_are_complete_ros2msg_definitions() -> None:
    """A schema holds the type's .msg text and every type it uses (rosbag2 layout)."""
    from aes_ros.ros.bag import message_definition

    text = message_definition("geometry_msgs/msg/PoseArray")
    assert text.startswith("# An array of poses")
    for dep in ("std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/Pose",
                "geometry_msgs/Point", "geometry_msgs/Quaternion"):  # fmt: skip
        assert f"MSG: {dep}\n" in text
        assert text.count(f"MSG: {dep}\n") == 1


def test_layouts_split_robots_and_name_hosts(tmp_path) -> None:
    from aes_ros.ros.launch.plan import LaunchConfig, node_commands, split_robots

    assert split_robots(10, 2) == [[0, 1, 2, 3, 4], [5, 6, 7, 8, 9]]
    assert split_robots(3, 8) == [[0], [1], [2]]
    sc = scenario.load("linear").with_robots(6)
    files = (tmp_path / "s.yaml", tmp_path / "r.yaml")
    per_core = node_commands(LaunchConfig(sc, layout="per-core", cores=2), *files)
    assert [name for name, _ in per_core] == [
        "sim_bridge", "supervisor", "robot_host_0", "robot_host_1"
    ]  # fmt: skip
    assert "robot_ids:=[3,4,5]" in per_core[3][1]
    assert "robot_host:__node:=robot_host_1" in per_core[3][1]
    per_robot = node_commands(LaunchConfig(sc, layout="per-robot"), *files)
    assert len(per_robot) == 2 + 6 and "__ns:=/mona_5" in per_robot[-1][1]
    single = node_commands(LaunchConfig(sc, layout="single"), *files)
    assert len(single) == 3 and not any("robot_ids" in a for a in single[2][1])


# ----------------------------------------------------------------------------- whole runs


def test_linear_moves_west_orders_and_records_a_bag(spawn, ros_env, tmp_path) -> None:
    """16 robots, linear setup, layout single, neighbours from /swarm/poses: the
    centroid moves west, heading order > 0.9; the outputs of ``simulate`` are
    written; the MCAP bag reads back with every recorded topic."""
    out, bag = tmp_path / "out", tmp_path / "run.mcap"
    rc, log = run_launch(
        spawn, "--setup", "linear", "--robots", "16", "--layout", "single", *FAST,
        "--duration", "15", "--set", "clip=true", "--out", str(out), "--record", str(bag),
    )  # fmt: skip
    assert rc == 0, log
    assert "all 16 robots moving" in log
    assert "processes stopped cleanly" in log, log  # every node exited 0 on SIGINT
    for name in ("trajectory.npz", "metrics.csv", "snapshots.png", "metrics.png"):
        assert (out / name).stat().st_size > 0, name
    traj = load_trajectory(out / "trajectory.npz")
    times, pos, head = traj.times, traj.positions[0], traj.headings[0]
    assert pos.shape[1:] == (16, 2) and times[-1] - times[0] >= 15.0 - 1e-6
    moved = pos[-1].mean(axis=0) - pos[0].mean(axis=0)
    assert moved[0] < -0.5, f"centroid moved {moved}, expected west"
    assert abs(direction_deg(moved)) > 150.0
    tail = times >= times[-1] - 2.0
    assert metrics.heading_order(head[tail]).mean() > 0.9

    counts = Counter()
    cmd = None
    for topic, _, msg in read_bag(bag):
        counts[topic] += 1
        if topic == "/mona_3/cmd_vel" and cmd is None:
            cmd = msg
    expected = {
        "/clock", "/swarm/poses", "/swarm/desired_velocity", "/swarm/rotation_center",
        "/swarm/alignment", "/swarm/heading_order", "/swarm/total_force",
        *(f"/mona_{i}/cmd_vel" for i in range(16)),
    }  # fmt: skip
    missing = expected - set(counts)
    assert not missing, f"bag lacks {missing}; has {counts}"
    assert counts["/mona_0/cmd_vel"] > 100 and counts["/swarm/poses"] > 100
    assert cmd is not None and math.isfinite(cmd.linear.x) and cmd.linear.y == 0.0
    assert_no_orphans(ros_env)


def test_ros_system_equals_offline_simulator(spawn, ros_env, tmp_path) -> None:
    """THE ROS SYSTEM EQUALS THE OFFLINE SIMULATOR.

    Lockstep, kinematic mode, clipping off, noise off (d_r = d_theta = 0), the
    same seed and so the same initial state: after 10 s of sim time (200 steps)
    every robot is within 1 mm of the offline simulator's run. Layout per-core
    (two robot hosts), neighbours from /swarm/poses. The linear setup (ω = 0)
    is used because with a live-centroid rotation centre the supervisor's
    centroid reaches the robots one step late, which the offline model does
    not have. The neighbour source is ``poses``: with ``odom`` a robot acts on its
    own odometry before all of its neighbours' odometry of the same step has
    arrived, so it sees some neighbours one step late (about 2 cm apart after
    10 s); that source is covered by the steering test.
    """
    seed = 7
    out = tmp_path / "out"
    rc, log = run_launch(
        spawn, "--setup", "linear", "--robots", "16", "--layout", "per-core", *FAST,
        "--mode", "kinematic", "--duration", "10", "--seed", str(seed),
        "--set", "d_r=0", "--set", "d_theta=0", "--set", "clip=false", "--out", str(out),
    )  # fmt: skip
    assert rc == 0, log
    traj = load_trajectory(out / "trajectory.npz")
    times, pos, head = traj.times, traj.positions[0], traj.headings[0]

    sc = scenario.load("linear", {"d_r": 0.0, "d_theta": 0.0, "duration": 10.0}).with_robots(16)
    ref = simulator.simulate(sc, [seed], noise=False)
    start_pos, start_head = sc.initial_state(seed)
    np.testing.assert_allclose(pos[0], start_pos, atol=1e-9)
    np.testing.assert_allclose(head[0], start_head, atol=1e-9)
    assert times[0] == 0.0  # lockstep: the bridge waits at t = 0 for every robot
    k_end = int(np.argmin(np.abs(times - 10.0)))
    assert abs(times[k_end] - 10.0) < 1e-6, times[-5:]
    err = np.linalg.norm(pos[k_end] - ref.positions[0, -1], axis=-1)
    assert err.max() < 1e-3, f"max deviation {err.max() * 1e3:.3f} mm"
    # Every sampled step agrees, not only the last one.
    steps = np.round((times - times[0]) / sc.dt).astype(int)
    dev = np.linalg.norm(pos - ref.positions[0, steps], axis=-1)
    assert dev.max() < 1e-3
    # The run actually went somewhere (not a trivially equal standstill).
    assert np.linalg.norm(ref.positions[0, -1] - start_pos, axis=-1).min() > 0.1


def test_rotation_turns_counter_clockwise_about_the_centroid(spawn, ros_env, tmp_path) -> None:
    """rotation setup with ω = +0.7 rad/s (counter-clockwise, REP-103): the swarm
    turns counter-clockwise about its centroid. 9 robots, one ``aes-robot-node``
    process per robot (layout per-robot), neighbours from /swarm/poses."""
    out = tmp_path / "out"
    rc, log = run_launch(
        spawn, "--setup", "rotation", "--set", "omega=0.7", "--robots", "9",
        "--layout", "per-robot", *FAST, "--duration", "12", "--out", str(out),
        timeout=180.0,
    )  # fmt: skip
    assert rc == 0, log
    traj = load_trajectory(out / "trajectory.npz")
    times, pos = traj.times, traj.positions[0]
    later = times >= times[0] + 4.0
    omega = metrics.rotation_angle(pos[later][:-1], pos[later][1:]) / np.diff(times[later])
    assert omega.mean() > 0.03, f"mean angular velocity {omega.mean():+.3f} rad/s"
    # Total turn about the centroid over the last 8 s, counter-clockwise.
    turned = metrics.rotation_angle(pos[later][0], pos[later][-1])
    assert turned > 0.2, turned
    drift = np.linalg.norm(pos[-1].mean(axis=0) - pos[0].mean(axis=0))
    assert drift < 0.5, f"centroid drifted {drift:.2f} m: not a rotation about it"


def test_steer_north_mid_run(spawn, ros_env, observer_factory) -> None:
    """Linear setup driving west; a mid-run ``aes-swarm steer --direction 0 1``
    (one /swarm/cmd Twist) turns the centroid's direction north within 10 s of
    sim time. 16 robots, layout per-core, neighbours from their odom topics."""
    n = 16
    launcher = spawn.start(
        *launch_cmd("--setup", "linear", "--robots", str(n), "--layout", "per-core",
                    "--neighbor-source", "odom", *FAST, "--duration", "0",
                    "--set", "clip=true"),
        name="launch",
    )  # fmt: skip
    obs = observer_factory(n)
    t0 = obs.wait_all_moving()
    obs.wait_sim(t0 + 6.0, timeout=90.0)
    west = obs.position_at(t0 + 6.0).mean(axis=0) - obs.position_at(t0 + 3.0).mean(axis=0)
    assert abs(direction_deg(west)) > 135.0, f"not moving west before steering: {west}"

    # Keep sampling while `aes-swarm steer` runs: the sim goes on at full speed.
    steer = subprocess.Popen(
        [str(BIN / "aes-swarm"), "steer", "--direction", "0", "1"],
        env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    try:
        obs.spin_until(lambda: steer.poll() is not None, 60.0, "aes-swarm steer")
    finally:
        if steer.poll() is None:
            steer.kill()
    output = steer.communicate()[0]
    assert steer.returncode == 0, output
    assert "direction (0, 1)" in output
    obs.spin_until(
        lambda: obs.desired and obs.desired[-1].twist.linear.y == 1.0, 20.0, "desired_velocity"
    )
    north = obs.desired[-1]
    assert north.twist.linear.x == 0.0
    # The supervisor stamps the new command with its (sim) time of arrival.
    t_cmd = north.header.stamp.sec + north.header.stamp.nanosec * 1e-9
    assert t_cmd > t0 + 6.0
    obs.wait_sim(t_cmd + 10.0, timeout=90.0)
    times = np.asarray(obs.times)
    a, b = np.searchsorted(times, [t_cmd + 7.0, t_cmd + 10.0 - 1e-9])
    assert times[b] - times[a] > 1.0, "too few samples to measure the direction"
    heading = obs.positions[b].mean(axis=0) - obs.positions[a].mean(axis=0)
    assert abs(direction_deg(heading) - 90.0) < 30.0, f"centroid moves toward {heading}"
    assert spawn.stop(launcher) == 0
    assert_no_orphans(ros_env)


def test_enable_stops_and_restarts_and_bad_parameters_are_rejected(
    spawn, ros_env, observer_factory, tmp_path
) -> None:
    """/swarm/enable false: every robot stops; true: every robot moves again.
    Out-of-range parameter sets on a robot node and on the supervisor are
    rejected with a reason, the old value stays and the nodes keep running.
    The launcher is ended by SIGTERM: every process stops and the bag is closed
    and readable. 16 robots, layout per-core, neighbours from /swarm/poses,
    real time (no lockstep)."""
    n = 16
    bag = tmp_path / "run.mcap"
    launcher = spawn.start(
        *launch_cmd("--setup", "combined", "--robots", str(n), "--layout", "per-core",
                    "--real-time-factor", "1", "--duration", "0", "--record", str(bag)),
        name="launch",
    )  # fmt: skip
    obs = observer_factory(n)
    t0 = obs.wait_all_moving()
    obs.wait_sim(t0 + 1.0)
    assert obs.motion(t0, obs.now).min() > 1e-4

    # Parameters out of range: rejected with a reason, old value kept, node alive.
    robot = "/mona_0/aes_robot"
    alpha = obs.get_double(robot, "alpha")
    result = obs.set_double(robot, "alpha", -1.0)
    assert not result.successful and result.reason
    assert obs.get_double(robot, "alpha") == alpha
    assert obs.set_double(robot, "alpha", alpha * 1.01).successful
    assert obs.get_double(robot, "alpha") == pytest.approx(alpha * 1.01)
    result = obs.set_double("/supervisor", "publish_rate", -5.0)
    assert not result.successful and result.reason
    assert launcher.poll() is None

    # Disable: every robot stops.
    reply = obs.call(SetBool, "/swarm/enable", SetBool.Request(data=False))
    assert reply.success
    obs.wait_sim(obs.now + 1.5)  # in-flight commands and cmd_timeout pass
    t1 = obs.now
    obs.wait_sim(t1 + 2.0)
    still = obs.motion(t1, obs.now)
    assert still.max() < 1e-6, f"robots still moving while disabled: {still.max():.2e}"

    # Enable again: every robot moves.
    reply = obs.call(SetBool, "/swarm/enable", SetBool.Request(data=True))
    assert reply.success
    t2 = obs.now
    obs.wait_sim(t2 + 2.5)
    moved = obs.motion(t2, obs.now)
    assert moved.min() > 1e-3, f"robots not moving after re-enable: {moved.min():.2e}"

    # SIGTERM to the launcher stops everything and closes the bag.
    os.killpg(launcher.pid, signal.SIGTERM)
    assert launcher.wait(60) == 0
    assert_no_orphans(ros_env)
    enabled = [msg.data for _, _, msg in read_bag(bag, topics=["/swarm/enabled"])]
    topics = {topic for topic, _, _ in read_bag(bag)}
    assert {"/clock", "/swarm/poses", "/mona_15/cmd_vel", "/swarm/alignment"} <= topics
    assert False in enabled and enabled[-1] is True, enabled


def test_start_swarm_script_runs_and_stops_cleanly(spawn, ros_env, observer_factory) -> None:
    """scripts/start_swarm.sh starts bridge, supervisor and two robot hosts from the
    console scripts; the robots move; Ctrl-C (SIGINT) stops every process."""
    n = 4
    env_path = f"{BIN}{os.pathsep}{ros_env.get('PATH', '')}"
    spawn.env = {**spawn.env, "PATH": env_path}
    script = spawn.start(
        "bash", str(REPO / "scripts" / "start_swarm.sh"), "-s", "linear", "-n", str(n), "-k", "2",
        name="start_swarm",
    )  # fmt: skip
    obs = observer_factory(n)
    t0 = obs.wait_all_moving()
    obs.wait_sim(t0 + 3.0, timeout=60.0)
    moved = obs.motion(t0, obs.now)
    assert moved.min() > 1e-3, moved
    os.killpg(script.pid, signal.SIGINT)
    assert script.wait(30) == 0
    assert_no_orphans(ros_env)

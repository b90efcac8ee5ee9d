"""The ``aes-sim-bridge`` process seen from another ROS node (real processes, own domain)."""

from __future__ import annotations

import dataclasses
import json
import math
import signal
import time
from importlib import resources

import numpy as np
import pytest
import yaml
from geometry_msgs.msg import Twist
from helpers.probe import STREAM, Probe
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

from aes_ros.model import robot_command, unicycle_step
from aes_ros.ros import interface as names
from aes_ros.ros.conversions import quaternion_to_yaw, stamp_to_ns, unicycle_twist
from aes_ros.ros.interface import robot_topic
from aes_ros.ros.qos import COMMAND, DISPLAY, SENSOR
from aes_ros.scenario import load
from aes_ros.simulator import simulate

BRIDGE = "/" + names.SIM_BRIDGE_NODE
#: Wait [s] for a service of the bridge and its answer.
SERVICE_TIMEOUT = 10.0


@dataclasses.dataclass
class Bridge:
    """What the probe sees of the bridge beside the poses: ``/clock`` [s], robot 1's
    odometry, and a ``cmd_vel`` publisher per robot."""

    clock: list[float]
    odom: list[Odometry]
    cmd: list

    def send(self, robot: int, linear: float, angular: float = 0.0) -> None:
        self.cmd[robot].publish(unicycle_twist(linear, angular))


def start_bridge(spawn, probe: Probe, n: int, *params: str):
    """Start ``aes-sim-bridge`` for ``n`` robots with ``-p`` ``params``; returns the
    process and the probe's view of it (the caller starts sampling the poses)."""
    args = ["aes-sim-bridge", "--ros-args"]
    for p in params:
        args += ["-p", p]
    proc = spawn.start(*args, name="sim_bridge")
    bridge = Bridge(
        clock=probe.record(Clock, names.CLOCK, STREAM, lambda m: stamp_to_ns(m.clock) * 1e-9),
        odom=probe.record(Odometry, robot_topic(1, names.ODOM), SENSOR),
        cmd=[probe.publisher(Twist, robot_topic(i, names.CMD_VEL), COMMAND) for i in range(n)],
    )
    return proc, bridge


def set_bridge_parameter(probe: Probe, name: str, value) -> tuple[bool, str]:
    (result,) = probe.set_parameters(BRIDGE, [Parameter(name, value=value)])
    return result.successful, result.reason


def test_bridge_publishes_the_scenario_and_follows_cmd_vel(spawn, probe):
    scenario = load("linear").with_robots(4)
    start_pos, start_head = scenario.initial_state(3)
    proc, bridge = start_bridge(
        spawn, probe, 4, "scenario:=linear", "num_robots:=4", "seed:=3", "cmd_timeout:=0.5"
    )
    probe.sample_poses(4)
    probe.wait(
        lambda: len(probe.times) >= 3 and len(bridge.odom) >= 2,
        20.0,
        "/swarm/poses and odom from the bridge",
    )

    # /clock advances with the poses' stamps; N poses = the seeded initial state
    probe.wait(lambda: len(bridge.clock) >= 3, 5.0, "/clock")
    assert bridge.clock[-1] > bridge.clock[0]
    stamp, pos, head = probe.sample()
    assert stamp > 0.0
    np.testing.assert_allclose(pos, start_pos, atol=1e-12)
    np.testing.assert_allclose(np.cos(head - start_head), 1.0, atol=1e-12)
    odom = bridge.odom[-1]
    assert odom.header.frame_id == "odom" and odom.child_frame_id == "mona_1/base_link"
    assert odom.pose.pose.position.x == pytest.approx(start_pos[1, 0], abs=1e-12)
    assert quaternion_to_yaw(odom.pose.pose.orientation) == pytest.approx(start_head[1])

    # a non-finite command is dropped; a valid one drives robot 1 forward
    bridge.send(1, math.nan, 0.0)
    time.sleep(0.3)
    t_end = time.monotonic() + 1.5
    while time.monotonic() < t_end:
        bridge.send(1, 0.1, 0.0)
        time.sleep(0.05)
    _, pos, head = probe.sample()
    moved = pos - start_pos
    heading = np.array([np.cos(start_head[1]), np.sin(start_head[1])])
    assert moved[1] @ heading > 0.05  # forward, ~0.1 m/s for ~1.5 s
    assert abs(moved[1] @ [-heading[1], heading[0]]) < 1e-9  # never sideways
    assert head[1] == pytest.approx(start_head[1], abs=1e-9)
    np.testing.assert_allclose(moved[[0, 2, 3]], 0.0, atol=1e-12)
    assert bridge.odom[-1].twist.twist.linear.x == pytest.approx(0.1)

    # silence: after cmd_timeout (0.5 s of sim time) robot 1 stops
    time.sleep(1.5)
    (t1, p1, _), (t2, p2, _) = probe.sample(-5), probe.sample(-1)
    assert t2 > t1
    np.testing.assert_array_equal(p1, p2)
    assert bridge.odom[-1].twist.twist.linear.x == 0.0

    assert spawn.stop(proc) == 0  # SIGINT: clean exit
    assert "Traceback" not in spawn.logs()


#: What the probe answers for each robot in the lockstep tests: (linear [m/s], angular [rad/s]).
LOCKSTEP_COMMANDS = {0: (0.1, 0.5), 1: (-0.05, -1.0)}


def lockstep_pair(spawn, probe: Probe, timeout: float):
    """A lockstep bridge of 2 robots (seed 5, full speed, no clipping, ``lockstep_timeout``
    ``timeout`` [s]) whose robots the probe plays: it answers each new state with
    :data:`LOCKSTEP_COMMANDS` of the robots in ``answer["robots"]``. Returns the process,
    the bridge, the sim times [s] answered and ``answer``."""
    proc, bridge = start_bridge(
        spawn, probe, 2,
        "num_robots:=2", "seed:=5", "lockstep:=true", "real_time_factor:=0.0", "clip:=false",
        f"lockstep_timeout:={timeout}",
    )  # fmt: skip
    answered: set[float] = set()
    answer = {"robots": [0, 1]}

    def reply(t: float, _pos: np.ndarray, _head: np.ndarray) -> None:
        if t not in answered:
            answered.add(t)
            for i in answer["robots"]:
                bridge.send(i, *LOCKSTEP_COMMANDS[i])

    probe.on_poses = reply
    probe.sample_poses(2)
    return proc, bridge, answered, answer


def assert_offline_model(probe: Probe, t: float) -> None:
    """The poses the probe got at sim time ``t`` [s] are exactly those of the offline
    unicycle model driven by :data:`LOCKSTEP_COMMANDS` from the bridge's initial state."""
    pos, head = load("combined").with_robots(2).initial_state(5)
    u, turn = (np.array(v) for v in zip(*LOCKSTEP_COMMANDS.values(), strict=True))
    target = round(t / 0.05)
    for _ in range(target):
        pos, head = unicycle_step(pos, head, u, turn, 0.05)
    k = next(k for k in reversed(range(len(probe.times))) if round(probe.times[k] / 0.05) == target)
    _, got_pos, got_head = probe.sample(k)
    np.testing.assert_allclose(got_pos, pos, atol=1e-9)
    np.testing.assert_allclose(np.cos(got_head - head), 1.0, atol=1e-12)


def test_lockstep_steps_once_per_round_of_commands(spawn, probe):
    proc, bridge, answered, answer = lockstep_pair(spawn, probe, 2.0)
    probe.wait(lambda: len(answered) >= 41, 30.0, "lockstep advancing 40 steps")
    stamps = sorted(answered)
    np.testing.assert_allclose(np.diff(stamps[:41]), 0.05, atol=1e-9)  # no step skipped
    assert_offline_model(probe, stamps[-1])  # the bridge integrated exactly these commands

    # robot 1 falls silent: the bridge waits lockstep_timeout (2 s of wall time since its
    # last answer), then goes on without it and stops its body
    answer["robots"] = [0]
    silent_since = time.monotonic()
    stuck = max(answered)
    left = round(stuck / 0.05)

    def later() -> list[int]:  # samples well after robot 1 left (the probe may miss some)
        return [k for k in range(len(probe.times)) if round(probe.times[k] / 0.05) > left + 12]

    probe.wait(lambda: len(later()) >= 5, 20.0, "lockstep going on without robot 1")
    assert time.monotonic() - silent_since > 1.8  # it was waited for first
    later = later()
    _, pos_a, _ = probe.sample(later[0])
    _, pos_b, _ = probe.sample(later[-1])
    assert np.linalg.norm(pos_b[1] - pos_a[1]) < 1e-12  # robot 1 stands still
    assert np.linalg.norm(pos_b[0] - pos_a[0]) > 1e-3  # robot 0 goes on
    assert "robot 1 silent for 2 s" in spawn.log(proc).read_text()
    # robot 1 answers again: back in the barrier, so the bridge waits for it again
    bridge.send(1, *LOCKSTEP_COMMANDS[1])
    answer["robots"] = [0, 1]
    resumed = max(answered)
    probe.wait(lambda: max(answered) >= resumed + 0.5, 10.0, "lockstep with robot 1 again")
    # A timeout set at runtime: with 6 s the bridge waits for robot 1 again.
    (result,) = probe.set_parameters("/sim_bridge", [Parameter("lockstep_timeout", value=6.0)])
    assert result.successful, result.reason
    answer["robots"] = [0]
    time.sleep(0.3)
    waiting = max(answered)
    time.sleep(2.5)  # longer than the first timeout, shorter than the new one
    assert max(answered) == waiting
    assert "robot 1 answered again: back in the barrier" in spawn.log(proc).read_text()


def test_a_slow_step_of_the_bridge_is_not_taken_for_the_robots_silence(spawn, probe, tmp_path):
    """The bridge's first step compiles its contact code (its numba cache is empty here)
    and takes far longer than lockstep_timeout; the robots cannot answer that step before
    its state is out, so they stay in the barrier: the run equals the offline model and no
    robot is stopped. (Their silence was counted from the start of the step: both left
    the barrier right after a slow step, as in a CI run on a busy machine.)"""
    spawn.env = {**spawn.env, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    proc, _, answered, _ = lockstep_pair(spawn, probe, 1.5)
    probe.wait(lambda: len(answered) >= 6, 120.0, "lockstep advancing 5 steps")
    assert "left the barrier" not in spawn.log(proc).read_text()
    assert_offline_model(probe, max(answered))


def test_reset_and_pause_services(spawn, probe):
    proc, bridge = start_bridge(spawn, probe, 2, "num_robots:=2", "seed:=1", "cmd_timeout:=10.0")
    probe.sample_poses(2)
    start_pos, _ = load("combined").with_robots(2).initial_state(1)
    probe.wait(lambda: len(probe.times) >= 2, 20.0, "/swarm/poses")
    # a command may arrive before the bridge's subscription has matched: sent until it moves
    probe.until(
        lambda: bridge.send(0, 0.1, 0.3),
        lambda: np.linalg.norm(probe.sample()[1][0] - start_pos[0]) > 0.05,
    )

    # pause: the clock and the robots stop; resume: both go on
    result = probe.call(SetBool, names.SIM_PAUSE, SetBool.Request(data=True), SERVICE_TIMEOUT)
    assert result.success and result.message == "paused"
    time.sleep(0.3)
    clock, moved = bridge.clock[-1], probe.sample()[1]
    time.sleep(1.0)
    assert bridge.clock[-1] == clock
    np.testing.assert_array_equal(probe.sample()[1], moved)
    result = probe.call(SetBool, names.SIM_PAUSE, SetBool.Request(data=False), SERVICE_TIMEOUT)
    assert result.success and result.message == "running"
    probe.wait(lambda: bridge.clock[-1] > clock + 0.2, 5.0, "the clock going on")

    # reset: back to the initial poses, every robot stopped, the clock goes on
    t_before = bridge.clock[-1]
    result = probe.call(Trigger, names.SIM_RESET, Trigger.Request(), SERVICE_TIMEOUT)
    assert result.success
    time.sleep(1.0)
    stamp, pos, _ = probe.sample()
    assert stamp > t_before
    np.testing.assert_allclose(pos, start_pos, atol=1e-12)

    proc.send_signal(signal.SIGTERM)  # also a clean exit
    assert proc.wait(10.0) == 0


def test_runtime_parameters_and_dynamic_mode(spawn, probe):
    _, bridge = start_bridge(
        spawn, probe, 2, "num_robots:=2", "seed:=2", "mode:=dynamic", "cmd_timeout:=10.0"
    )
    probe.sample_poses(2)
    start_pos, start_head = load("combined").with_robots(2).initial_state(2)
    probe.wait(lambda: len(probe.times) >= 2 and bridge.odom, 20.0, "/swarm/poses and odom")

    # out of range: rejected with a reason, the bridge keeps its value and runs on
    ok, reason = set_bridge_parameter(probe, "real_time_factor", -1.0)
    assert not ok and "real_time_factor" in reason
    ok, _ = set_bridge_parameter(probe, "mode", "kinematic")  # read-only
    assert not ok
    # twice real time: sim time runs ahead of the wall clock
    assert set_bridge_parameter(probe, "real_time_factor", 2.0)[0]
    wall, sim = time.monotonic(), bridge.clock[-1]
    time.sleep(2.0)
    assert bridge.clock[-1] - sim > 1.3 * (time.monotonic() - wall)

    # dynamic mode: wheel motors drive robot 1 forward, robot 0 turns on the spot (CCW)
    t_end = time.monotonic() + 1.0
    while time.monotonic() < t_end:
        bridge.send(0, 0.0, 1.0)
        bridge.send(1, 0.1, 0.0)
        time.sleep(0.05)
    # Robot 0 stopped before the look: with cmd_timeout 10 s its turn would go on until
    # the sample comes in, and on a busy machine (seen in CI) past the angle whose sine
    # the check reads (the loop's 2 s of sim time at 1 rad/s are 2 rad; the limit 2.84).
    bridge.send(0, 0.0, 0.0)
    bridge.send(1, 0.1, 0.0)
    time.sleep(0.2)
    _, pos, head = probe.sample()
    heading = np.array([np.cos(start_head[1]), np.sin(start_head[1])])
    assert (pos[1] - start_pos[1]) @ heading > 0.05
    assert np.linalg.norm(pos[0] - start_pos[0]) < 0.01
    assert np.sin(head[0] - start_head[0]) > 0.3
    assert bridge.odom[-1].twist.twist.linear.x == pytest.approx(0.1, abs=0.02)


def test_pause_at_holds_the_world_there_until_it_is_set_later(spawn, probe):
    """A launch sets ``pause_at`` to the run's end once the run has started: the bridge
    waits there, its clock too, rather than run on past it, and goes on once
    ``pause_at`` is moved on. (Set at runtime, as the launcher does: a held clock is
    not published again, so the probe must be listening before the hold.)"""
    _, bridge = start_bridge(spawn, probe, 2, "num_robots:=2", "pause_at:=600.0")
    probe.wait(lambda: bridge.clock and bridge.clock[-1] >= 0.1, 20.0, "/clock")
    hold = math.ceil(bridge.clock[-1]) + 1.0
    half_step = 0.025  # at 20 Hz: the first step at or past pause_at is the one at `hold`
    assert set_bridge_parameter(probe, "pause_at", hold - half_step)[0]
    probe.wait(lambda: bridge.clock[-1] >= hold - 1e-6, 20.0, f"/clock at {hold:g} s")
    time.sleep(1.0)  # real time: running on, the clock would be 1 s further
    assert bridge.clock[-1] == pytest.approx(hold)
    ok, reason = set_bridge_parameter(probe, "pause_at", -1.0)  # out of range: refused
    assert not ok and "pause_at" in reason
    assert set_bridge_parameter(probe, "pause_at", hold + 0.5 - half_step)[0]
    probe.wait(lambda: bridge.clock[-1] >= hold + 0.5 - 1e-6, 20.0, "/clock moved on")
    time.sleep(0.5)
    assert bridge.clock[-1] == pytest.approx(hold + 0.5)


def colliding_scenario(path) -> str:
    """A 2 x 2 combined sheet whose bodies overlap from the start (spacing 0.07 m < 2r),
    driven into a wall, with a post beside its path and contacts on; written to ``path``."""
    data = yaml.safe_load(
        resources.files("aes_ros").joinpath("scenarios/combined.yaml").read_text()
    )
    data.update(rows=2, cols=2, spacing=0.07, contacts=True, duration=10.0)
    data.update(walls=[-0.28, 0.5, -0.5, 0.5], obstacles=[{"circle": [-0.13, -0.2, 0.03]}])
    path.write_text(yaml.safe_dump(data))
    return str(path)


def test_lockstep_bridge_with_the_control_law_equals_the_offline_simulator(spawn, probe, tmp_path):
    """The test plays 4 noise-free robots with aes_ros.model.robot_command: 10 s in lockstep
    end where the offline simulator ends from the same seed, with bodies that collide
    with each other and a wall (contacts on); /sim/stats counts the contacts, and the
    dashboard's /swarm/markers shows the wall and the post."""
    path = colliding_scenario(tmp_path / "colliding.yaml")
    scenario = load(path).with_robots(4)
    spawn.start(
        "aes-dashboard", "--ros-args", "-p", f"scenario:={path}", "-p", "num_robots:=4",
        "-p", "port:=0", name="dashboard",
    )  # fmt: skip
    markers: list[MarkerArray] = []
    probe.node.create_subscription(MarkerArray, names.MARKERS, markers.append, DISPLAY)
    _, bridge = start_bridge(
        spawn, probe, 4,
        f"scenario:={path}", "num_robots:=4", "seed:=7", "lockstep:=true",
        "real_time_factor:=0.0", "clip:=false", "lockstep_timeout:=30.0",
    )  # fmt: skip
    _, neighbors, rest = scenario.sheet()
    states: dict[int, np.ndarray] = {}

    def control(t: float, pos: np.ndarray, head: np.ndarray) -> None:
        step = round(t / scenario.dt)
        if step in states:
            return  # a re-published state was answered already
        states[step] = pos
        if step >= scenario.n_steps:
            return  # the run is over: the bridge waits (and counts no contact)
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
            bridge.send(i, out.linear, out.angular)

    probe.on_poses = control
    probe.sample_poses(4)
    probe.wait(lambda: scenario.n_steps in states, 60.0, f"step {scenario.n_steps}")
    # (the bridge now waits for commands that do not come: its figures stay those of the run)
    stats = json.loads(
        probe.call(Trigger, names.SIM_STATS, Trigger.Request(), SERVICE_TIMEOUT).message
    )
    # the numpy backend: the bridge's very Euler step and contact resolution (the numba
    # kernel's own arithmetic rounds differently, and contacts carry that on)
    offline = simulate(scenario, 7, noise=False, backend="numpy")
    assert np.linalg.norm(offline.positions[0, -1] - offline.positions[0, 0], axis=-1).min() > 0.1
    # The contract is < 1 mm; the bridge does the same Euler step and contact resolution,
    # so (as measured) the positions agree to rounding.
    np.testing.assert_allclose(states[scenario.n_steps], offline.positions[0, -1], atol=1e-12)
    np.testing.assert_allclose(states[100], offline.positions[0, 100], atol=1e-12)

    # /sim/stats: the contacts of these steps, the closest bodies no closer than 2r - 1 mm
    assert offline.contacts[0].sum() > scenario.n_steps  # they touched all along
    assert stats["contacts"] == offline.contacts[0].sum()
    assert stats["contacts_per_s"] == pytest.approx(stats["contacts"] / stats["sim_s"])
    assert stats["min_centre_distance_m"] == pytest.approx(np.nanmin(offline.min_distance[0, 1:]))
    assert stats["min_centre_distance_m"] > 0.08 - 0.001

    # the dashboard draws the wall and the post in /swarm/markers
    probe.wait(
        lambda: any(m.ns == "obstacles" for a in markers for m in a.markers), 30.0, "markers"
    )
    drawn = markers[-1].markers
    (wall,) = [m for m in drawn if m.ns == "walls"]
    assert {(p.x, p.y) for p in wall.points} == {
        (-0.28, -0.5),
        (0.5, -0.5),
        (0.5, 0.5),
        (-0.28, 0.5),
    }
    (post,) = [m for m in drawn if m.ns == "obstacles"]
    assert (post.pose.position.x, post.pose.position.y) == (-0.13, -0.2)
    assert post.scale.x == pytest.approx(0.06)

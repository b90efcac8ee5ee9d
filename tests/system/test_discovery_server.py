"""``aes-swarm launch --discovery server``: the swarm behind a Fast DDS discovery server.

- the ROS tools work with the environment the launch prints (read from ``OUT/ros_env.sh``
  and set in this process before its rclpy contexts are made, as a user's shell would
  before ``ros2``): topic and node lists, echo of ``/swarm/poses``, parameter get and set
  (an out-of-range set rejected with its reason), a service call, steering by
  ``/swarm/cmd``; the recorder, a super client, finds every topic to record; a plain
  client (what the launcher's monitor and the dashboard are) sees every node, though of
  the topics only those it uses;
- ``scripts/start_swarm.sh -d server``: its server first, its printed lines work;
- the server SIGKILLed mid-run: the launcher respawns it on its port, the swarm keeps
  moving meanwhile (matched endpoints keep talking); then a robot host SIGKILLed: the
  respawned host's new endpoints match through the respawned server and its robots move
  again.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import rclpy
from geometry_msgs.msg import PoseArray, Twist
from helpers.messages import poses_msg
from helpers.probe import Probe
from helpers.ros_env import assert_no_orphans, find_process, shell_environment, wait_for
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import SetBool

from aes_ros import scenario
from aes_ros.ros import discovery as dds
from aes_ros.ros import interface as names
from aes_ros.ros.bag import read_bag
from aes_ros.ros.launch.events import read_events
from aes_ros.ros.qos import COMMAND, SENSOR

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
N = 9
ROBOT_NODES = [f"{names.robot_namespace(i)}/{names.ROBOT_NODE}" for i in range(N)]
#: The one robot host of layout single (its node is /robot_host).
HOST = f"{names.ROBOT_HOST_NODE}_0"


def launch_cmd(out: Path, *extra: str) -> list[str]:
    return [
        "aes-swarm", "launch", "--setup", "linear", "--robots", str(N), "--layout", "single",
        "--duration", "0", "--discovery", "server", "--out", str(out), *extra,
    ]  # fmt: skip


@pytest.fixture
def launch(spawn, ros_env, tmp_path: Path) -> Iterator[Callable[..., tuple]]:
    """``launch(*options)`` starts a server mode launch and returns it, its output
    directory and a started probe made with the environment the launch printed (the
    probe is closed and the environment restored at the end of the test)."""
    stack = contextlib.ExitStack()

    def start(*extra: str) -> tuple[subprocess.Popen, Path, Probe]:
        out = tmp_path / "out"
        launcher = spawn.start(*launch_cmd(out, *extra), name="launch")
        script = out / "ros_env.sh"
        assert wait_for(script.exists, 60.0), spawn.log(launcher).read_text()[-3000:]
        log = spawn.log(launcher).read_text()
        printed = [line.strip() for line in log.splitlines() if line.startswith("  export ")]
        assert printed == [line for line in script.read_text().splitlines() if line[:1] != "#"]
        variables = stack.enter_context(shell_environment(script))
        assert variables["ROS_DISCOVERY_SERVER"].startswith("127.0.0.1:")
        assert variables["ROS_SUPER_CLIENT"] == "true"
        assert variables["ROS_DOMAIN_ID"] == ros_env["ROS_DOMAIN_ID"]
        probe = Probe(keep_clients=True)
        stack.callback(probe.close)
        # faults are the launcher's to handle once it runs (before, any death ends the launch)
        moving = "robots moving at sim time"
        probe.wait(lambda: moving in spawn.log(launcher).read_text(), 60.0, "the launch to run")
        return launcher, out, probe.sample_poses(N)

    with stack:
        yield start


def plain_client_graph(nodes_wanted: set[str], timeout: float = 20.0) -> tuple[set[str], set[str]]:
    """Node and topic names a plain client (no ROS_SUPER_CLIENT) learns, once it sees
    ``nodes_wanted`` (or after ``timeout`` s)."""
    super_client = os.environ.pop(dds.SUPER_CLIENT_VARIABLE)
    context = rclpy.Context()
    try:
        rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node("plain_client", context=context)
    finally:
        os.environ[dds.SUPER_CLIENT_VARIABLE] = super_client

    def nodes() -> set[str]:
        return {f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces()}

    try:
        wait_for(lambda: nodes_wanted <= nodes(), timeout)
        return nodes(), {t for t, _ in node.get_topic_names_and_types()}
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def check_graph(probe: Probe) -> None:
    """A super client lists every node and topic of the swarm; a plain client every node
    (what the monitor and the dashboard ask for) but not the topics it does not use."""
    node = probe.node

    def nodes() -> set[str]:
        return {f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces()}

    swarm = {"/sim_bridge", "/supervisor", "/robot_host", *ROBOT_NODES}
    probe.wait(lambda: swarm <= nodes(), 20.0, "every node of the swarm in the node list")
    topics = {names.POSES, names.ALIGNMENT, names.CLOCK, names.robot_topic(N - 1, names.CMD_VEL)}
    probe.wait(
        lambda: topics <= {t for t, _ in node.get_topic_names_and_types()}, 20.0, "topic list"
    )
    plain_nodes, plain_topics = plain_client_graph(swarm)
    assert swarm <= plain_nodes
    assert names.ALIGNMENT not in plain_topics  # hence ROS_SUPER_CLIENT for ros2 and the recorder


def check_parameters(probe: Probe) -> None:
    """Get and set the supervisor's rotation_rate (the command follows); an out-of-range
    publish_rate is rejected with the reason and the old value stays."""
    supervisor = "/" + names.SUPERVISOR_NODE
    (result,) = probe.set_parameters(supervisor, [Parameter("rotation_rate", value=0.2)])
    assert result.successful, result.reason
    assert probe.get_parameters(supervisor, ["rotation_rate"]) == [pytest.approx(0.2)]
    probe.wait(
        lambda: probe.desired and probe.desired[-1].twist.angular.z == pytest.approx(0.2),
        20.0,
        "the supervisor's command with the new rotation rate",
    )
    (rate,) = probe.get_parameters(supervisor, ["publish_rate"])
    (result,) = probe.set_parameters(supervisor, [Parameter("publish_rate", value=-5.0)])
    assert not result.successful and result.reason
    assert probe.get_parameters(supervisor, ["publish_rate"]) == [rate]


def check_service_and_steering(probe: Probe) -> None:
    """/swarm/enable answers; a /swarm/cmd Twist north becomes the swarm's command."""
    for enabled in (False, True):
        assert probe.call(SetBool, names.ENABLE, SetBool.Request(data=enabled)).success
    cmd = probe.publisher(Twist, names.CMD, COMMAND)
    north = Twist()
    north.linear.y = 1.0
    probe.until(
        lambda: cmd.publish(north),
        lambda: probe.desired and probe.desired[-1].twist.linear.y == 1.0,
    )
    assert probe.desired[-1].twist.linear.x == 0.0


def test_ros_tools_work_with_the_printed_environment(launch, spawn, ros_env, tmp_path) -> None:
    bag = tmp_path / "run.mcap"
    launcher, _, probe = launch("--record", str(bag))
    t0 = probe.wait_all_moving(60.0)
    check_graph(probe)
    check_parameters(probe)
    check_service_and_steering(probe)
    probe.wait_sim(probe.now + 0.5)
    assert probe.motion(t0, probe.now).min() > 1e-3
    assert spawn.stop(launcher) == 0, spawn.log(launcher).read_text()[-3000:]
    # the recorder, a super client, found the topics through the server
    topics = {topic for topic, _, _ in read_bag(bag)}
    assert {names.POSES, names.ALIGNMENT, names.CMD, names.robot_topic(0, names.CMD_VEL)} <= topics
    assert_no_orphans(ros_env)


def events_of(out: Path, process: str) -> list[str]:
    path = out / "events.csv"
    return (
        [r["event"] for r in read_events(path) if r["process"] == process] if path.exists() else []
    )


def kill(ros_env: dict[str, str], needle: str) -> float:
    """SIGKILL the one process of the test's domain whose command line holds ``needle``."""
    os.kill(find_process(ros_env["ROS_DOMAIN_ID"], needle), signal.SIGKILL)
    return time.monotonic()


@pytest.mark.alone  # judges recovery times
def test_a_killed_server_is_respawned_and_new_endpoints_match_through_it(
    launch, spawn, ros_env
) -> None:
    launcher, out, probe = launch()
    probe.wait_all_moving(60.0)
    cmd_vel = probe.record(
        Twist, names.robot_topic(0, names.CMD_VEL), COMMAND, lambda _m: time.monotonic()
    )
    # the server: the swarm keeps moving while it is gone and after
    t_kill = probe.now
    kill(ros_env, dds.SERVER_PROGRAM)
    recovered = ["died", "restarted", "recovered"]
    probe.wait(lambda: events_of(out, dds.SERVER_PROCESS) == recovered, 20.0, "the server back")
    probe.wait_sim(probe.now + 1.0)
    moved = probe.motion(t_kill, probe.now)
    assert moved.min() > 1e-3, f"robots stopped with the server gone: {moved.min():.2e}"
    # a robot host: its new endpoints match the bridge's and the probe's through the new server
    killed = kill(ros_env, "aes-robot-host")
    probe.wait(lambda: events_of(out, HOST) == recovered, 30.0, "the robot host back")
    probe.wait(lambda: any(t > killed + 0.3 for t in cmd_vel), 20.0, "cmd_vel of the new host")
    t1 = probe.now
    probe.wait_sim(t1 + 1.5)
    moved = probe.motion(t1, probe.now)
    assert moved.min() > 1e-3, f"robots not moving after the host's restart: {moved.min():.2e}"
    assert spawn.stop(launcher) == 0, spawn.log(launcher).read_text()[-3000:]
    log = spawn.log(launcher).read_text()
    assert "2 faults" in log and "2 recovered" in log, log[-2000:]
    assert events_of(out, dds.SERVER_PROCESS)[:2] == ["died", "restarted"]
    assert_no_orphans(ros_env)


def test_start_swarm_script_runs_through_a_server_it_starts(spawn, ros_env, tmp_path) -> None:
    """scripts/start_swarm.sh -d server: the server first, the lines for a shell printed;
    with them a probe sees every node and the robots move; Ctrl-C stops all of it."""
    n = 4
    spawn.env = {**spawn.env, "PATH": f"{BIN}{os.pathsep}{ros_env.get('PATH', '')}"}
    script = spawn.start(
        "bash", str(REPO / "scripts" / "start_swarm.sh"), "-s", "linear", "-n", str(n),
        "-d", "server", name="start_swarm",
    )  # fmt: skip
    log = spawn.log(script)
    assert wait_for(lambda: "swarm running" in log.read_text(), 30.0), log.read_text()
    starts = [line for line in log.read_text().splitlines() if line.startswith("starting ")]
    assert starts[0].startswith("starting discovery_server:"), starts
    lines = [line.strip() for line in log.read_text().splitlines() if "export ROS_" in line]
    (tmp_path / "ros_env.sh").write_text("\n".join(lines) + "\n")
    with shell_environment(tmp_path / "ros_env.sh") as variables:
        assert variables["ROS_DISCOVERY_SERVER"].startswith("127.0.0.1:")
        probe = Probe()
        try:
            probe.sample_poses(n)
            t0 = probe.wait_all_moving(60.0)
            probe.wait_sim(t0 + 1.0)
            assert probe.motion(t0, probe.now).min() > 1e-3
            assert {"sim_bridge", "supervisor", "robot_host_0"} <= set(probe.node.get_node_names())
        finally:
            probe.close()
    os.killpg(script.pid, signal.SIGINT)
    assert script.wait(30) == 0
    assert_no_orphans(ros_env)


def test_a_host_behind_a_server_serves_every_robot_from_its_participants(
    spawn, ros_env, tmp_path
) -> None:
    """A robot host that is a client of a server makes its robots in several DDS
    participants (here one robot each): through the server every robot is in the node
    list, answers parameter get and set (a bad value rejected with its reason) and
    commands its robot from the poses; Ctrl-C stops the host cleanly."""
    n = 4
    port = dds.free_udp_port()
    server = spawn.start(*dds.server_argv(port, "127.0.0.1"), name=dds.SERVER_PROCESS)
    assert wait_for(lambda: dds.SERVER_READY in spawn.log(server).read_text(), 30.0)
    found = dds.Discovery("server", f"127.0.0.1:{port}")
    spawn.env = found.client_environment(spawn.env)
    host = spawn.start(
        "aes-robot-host", "--ros-args", "-p", "scenario:=linear", "-p", f"num_robots:={n}",
        "-p", "robots_per_participant:=1", name="host",
    )  # fmt: skip
    (tmp_path / "ros_env.sh").write_text(found.script(ros_env))
    with shell_environment(tmp_path / "ros_env.sh"):
        probe = Probe(keep_clients=True)
        try:
            robots = [f"/mona_{i}/{names.ROBOT_NODE}" for i in range(n)]
            probe.wait(
                lambda: set(robots) <= {f"{ns}/{name}" for name, ns in
                                        probe.node.get_node_names_and_namespaces()},
                30.0, "every robot in the node list",
            )  # fmt: skip
            assert f"{n} DDS participant(s)" in spawn.log(host).read_text()
            for i, robot in enumerate(robots):
                (result,) = probe.set_parameters(robot, [Parameter("alpha", value=0.01 * (i + 1))])
                assert result.successful, result.reason
                (result,) = probe.set_parameters(robot, [Parameter("alpha", value=-1.0)])
                assert not result.successful and "alpha" in result.reason
                assert probe.get_parameters(robot, ["alpha"]) == [pytest.approx(0.01 * (i + 1))]
            cmds = [
                probe.record(Twist, names.robot_topic(i, names.CMD_VEL), COMMAND) for i in range(n)
            ]
            scen = scenario.load("linear").with_robots(n)
            xy, yaw = scen.initial_state(seed=1)
            poses = probe.publisher(PoseArray, names.POSES, SENSOR)
            clock = [1.0]

            def send() -> None:
                clock[0] += 0.05
                poses.publish(poses_msg(xy, yaw, clock[0]))

            probe.until(send, lambda: all(cmds))
        finally:
            probe.close()
    assert spawn.stop(host) == 0
    assert "Traceback" not in spawn.log(host).read_text()

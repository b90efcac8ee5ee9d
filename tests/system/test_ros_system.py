"""End-to-end tests of the ROS 2 system: real processes over Fast DDS.

See docs/design.md#ros-interface.

Every test gets its own ROS_DOMAIN_ID (``ros_env``/``spawn`` fixtures) and
starts the system as a user would: ``aes-swarm launch`` (which starts
aes-sim-bridge, aes-supervisor and the robot hosts/nodes as separate
processes), ``scripts/start_swarm.sh`` or ``aes-swarm steer``. The test's probe
(:class:`helpers.probe.Probe`) samples ``/swarm/poses`` and calls the services. Runs use
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
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from helpers.probe import Probe
from helpers.ros_env import assert_no_orphans, processes_in_domain
from rclpy.parameter import Parameter
from std_srvs.srv import SetBool

from aes_ros import metrics, scenario, simulator
from aes_ros.previous_run import LAUNCH_OUTPUTS
from aes_ros.ros import interface as names
from aes_ros.ros.bag import read_bag
from aes_ros.ros.interface import robot_namespace
from aes_ros.trajectory import load_trajectory

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
#: Fast, deterministic stepping: each control step waits for every robot's command.
FAST = ("--lockstep", "--real-time-factor", "0")


# ----------------------------------------------------------------------------- helpers


def launch_cmd(*args: str) -> list[str]:
    return ["aes-swarm", "launch", *args]


def run_launch(spawn, *args: str, timeout: float = 120.0) -> tuple[int, str]:
    """Run ``aes-swarm launch`` to completion; returns (exit code, its output)."""
    proc = spawn.start(*launch_cmd(*args), name="launch")
    log = spawn.log(proc)
    try:
        rc = proc.wait(timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f"aes-swarm launch did not finish in {timeout} s:\n{log.read_text()[-3000:]}")
    return rc, log.read_text()


def direction_deg(v: np.ndarray) -> float:
    return math.degrees(math.atan2(v[1], v[0]))


# ----------------------------------------------------------------------------- whole runs


def test_linear_moves_west_orders_and_records_a_bag(spawn, ros_env, tmp_path) -> None:
    """16 robots, linear setup, layout single, neighbours from /swarm/poses: the
    centroid moves west, heading order > 0.9; the outputs of ``simulate`` are
    written; the MCAP bag reads back with every recorded topic; the same launch again is
    refused, the run's files intact."""
    out, bag = tmp_path / "out", tmp_path / "run.mcap"
    rc, log = run_launch(
        spawn, "--setup", "linear", "--robots", "16", "--layout", "single", *FAST,
        "--duration", "15", "--set", "clip=true", "--out", str(out), "--record", str(bag),
    )  # fmt: skip
    assert rc == 0, log
    assert "all 16 robots moving" in log
    assert "processes stopped cleanly" in log, log  # every node exited 0 on SIGINT
    for name in ("trajectory.h5", "metrics.csv", "snapshots.png", "metrics.png"):
        assert (out / name).stat().st_size > 0, name
    traj = load_trajectory(out / "trajectory.h5")
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
    check_a_second_launch_is_refused(spawn, out, bag)


def check_a_second_launch_is_refused(spawn, out: Path, bag: Path) -> None:
    """The same command again: refused before it starts anything (exit code 2, the
    directory and ``--overwrite`` named), the first run's files as they were; every
    file the launch wrote into ``out`` is one the check looks for."""
    written = {p.name for p in out.iterdir()}
    assert written <= set(LAUNCH_OUTPUTS) | {bag.name}, written - set(LAUNCH_OUTPUTS)
    files = [bag, *sorted(p for p in out.rglob("*") if p.is_file())]
    before = {p: p.read_bytes() for p in files}
    again = spawn.start(
        *launch_cmd("--setup", "linear", "--robots", "16", "--out", str(out), "--record", str(bag)),
        name="second_launch",
    )  # fmt: skip
    assert again.wait(60) == 2
    log = spawn.log(again).read_text()
    assert f"--out {out} holds an earlier run (run.json," in log and "--overwrite" in log, log
    assert not any(line.startswith("launch:") for line in log.splitlines()), log
    assert {p: p.read_bytes() for p in files} == before


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
        "--set", "d_r=0", "--set", "d_theta=0", "--set", "clip=false",
        "--set", "contacts=false", "--out", str(out),
    )  # fmt: skip
    assert rc == 0, log
    traj = load_trajectory(out / "trajectory.h5")
    times, pos, head = traj.times, traj.positions[0], traj.headings[0]

    # contacts off: a contact is a discontinuity that grows the numba kernel's 1e-9 m
    # rounding apart from the bridge's into millimetres; the lockstep bridge with bodies
    # is compared with the offline simulator in tests/system/test_sim_bridge.py
    values = {"d_r": 0.0, "d_theta": 0.0, "duration": 10.0, "contacts": False}
    sc = scenario.load("linear", values).with_robots(16)
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
    traj = load_trajectory(out / "trajectory.h5")
    times, pos = traj.times, traj.positions[0]
    later = times >= times[0] + 4.0
    omega = metrics.rotation_angle(pos[later][:-1], pos[later][1:]) / np.diff(times[later])
    assert omega.mean() > 0.03, f"mean angular velocity {omega.mean():+.3f} rad/s"
    # Total turn about the centroid over the last 8 s, counter-clockwise.
    turned = metrics.rotation_angle(pos[later][0], pos[later][-1])
    assert turned > 0.2, turned
    drift = np.linalg.norm(pos[-1].mean(axis=0) - pos[0].mean(axis=0))
    assert drift < 0.5, f"centroid drifted {drift:.2f} m: not a rotation about it"


def check_moving_west(probe: Probe) -> float:
    """Every robot moves and, from 3 to 6 s later, the centroid heads west; returns the
    sim time at which every robot moved."""
    t0 = probe.wait_all_moving()
    probe.wait_sim(t0 + 6.0, timeout=90.0)
    west = probe.position_at(t0 + 6.0).mean(axis=0) - probe.position_at(t0 + 3.0).mean(axis=0)
    assert abs(direction_deg(west)) > 135.0, f"not moving west before steering: {west}"
    return t0


def steer_north(spawn, probe: Probe, t0: float) -> float:
    """``aes-swarm steer --direction 0 1`` while the sim goes on at full speed: it says
    so and exits 0, and the supervisor echoes north, stamped with its (sim) time of
    arrival, later than ``t0 + 6``; returns that time."""
    steer = spawn.start("aes-swarm", "steer", "--direction", "0", "1", name="steer")
    try:
        probe.wait(lambda: steer.poll() is not None, 60.0, "aes-swarm steer")
    finally:
        if steer.poll() is None:
            steer.kill()
    output = spawn.log(steer).read_text()
    assert steer.returncode == 0, output
    assert "direction (0, 1)" in output
    probe.wait(
        lambda: probe.desired and probe.desired[-1].twist.linear.y == 1.0, 20.0, "desired_velocity"
    )
    north = probe.desired[-1]
    assert north.twist.linear.x == 0.0
    t_cmd = north.header.stamp.sec + north.header.stamp.nanosec * 1e-9
    assert t_cmd > t0 + 6.0
    return t_cmd


def check_heading_north_within_10_s(probe: Probe, t_cmd: float) -> None:
    """From 7 to 10 s of sim time after the command, the centroid moves north (±30°)."""
    probe.wait_sim(t_cmd + 10.0, timeout=90.0)
    times = np.asarray(probe.times)
    a, b = np.searchsorted(times, [t_cmd + 7.0, t_cmd + 10.0 - 1e-9])
    assert times[b] - times[a] > 1.0, "too few samples to measure the direction"
    heading = probe.positions[b].mean(axis=0) - probe.positions[a].mean(axis=0)
    assert abs(direction_deg(heading) - 90.0) < 30.0, f"centroid moves toward {heading}"


def test_steer_north_mid_run(spawn, ros_env, probe) -> None:
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
    probe.sample_poses(n)
    t0 = check_moving_west(probe)
    t_cmd = steer_north(spawn, probe, t0)
    check_heading_north_within_10_s(probe, t_cmd)
    assert spawn.stop(launcher) == 0
    assert_no_orphans(ros_env)


def check_every_robot_moving(probe: Probe) -> None:
    """Every robot has moved within 1 s of sim time after the last one started."""
    t0 = probe.wait_all_moving()
    probe.wait_sim(t0 + 1.0)
    assert probe.motion(t0, probe.now).min() > 1e-4


def check_bad_parameters_are_rejected(probe: Probe, launcher: subprocess.Popen) -> None:
    """Parameters out of range on a robot node and on the supervisor: rejected with a
    reason, the old value kept, the node alive; a good value applies."""
    robot = f"{robot_namespace(0)}/{names.ROBOT_NODE}"

    def set_alpha(value: float):
        return probe.set_parameters(robot, [Parameter("alpha", value=value)])[0]

    (alpha,) = probe.get_parameters(robot, ["alpha"])
    result = set_alpha(-1.0)
    assert not result.successful and result.reason
    assert probe.get_parameters(robot, ["alpha"]) == [alpha]
    assert set_alpha(alpha * 1.01).successful
    assert probe.get_parameters(robot, ["alpha"]) == [pytest.approx(alpha * 1.01)]
    supervisor = "/" + names.SUPERVISOR_NODE
    (result,) = probe.set_parameters(supervisor, [Parameter("publish_rate", value=-5.0)])
    assert not result.successful and result.reason
    assert launcher.poll() is None


def disable_and_check_every_robot_stops(probe: Probe) -> None:
    """/swarm/enable false: once in-flight commands and cmd_timeout have passed (1.5 s),
    no robot moves for 2 s."""
    reply = probe.call(SetBool, names.ENABLE, SetBool.Request(data=False))
    assert reply.success
    probe.wait_sim(probe.now + 1.5)  # in-flight commands and cmd_timeout pass
    t1 = probe.now
    probe.wait_sim(t1 + 2.0)
    still = probe.motion(t1, probe.now)
    assert still.max() < 1e-6, f"robots still moving while disabled: {still.max():.2e}"


def enable_and_check_every_robot_moves(probe: Probe) -> None:
    """/swarm/enable true: every robot moves within 2.5 s."""
    reply = probe.call(SetBool, names.ENABLE, SetBool.Request(data=True))
    assert reply.success
    t2 = probe.now
    probe.wait_sim(t2 + 2.5)
    moved = probe.motion(t2, probe.now)
    assert moved.min() > 1e-3, f"robots not moving after re-enable: {moved.min():.2e}"


def sigterm_and_check_the_bag(launcher: subprocess.Popen, ros_env, bag: Path) -> None:
    """SIGTERM to the launcher stops everything and closes the bag, which holds the
    swarm's topics and the enable sequence (false, then true last)."""
    os.killpg(launcher.pid, signal.SIGTERM)
    assert launcher.wait(60) == 0
    assert_no_orphans(ros_env)
    enabled = [msg.data for _, _, msg in read_bag(bag, topics=[names.ENABLED])]
    topics = {topic for topic, _, _ in read_bag(bag)}
    assert {"/clock", "/swarm/poses", "/mona_15/cmd_vel", "/swarm/alignment"} <= topics
    assert False in enabled and enabled[-1] is True, enabled


def test_enable_stops_and_restarts_and_bad_parameters_are_rejected(
    spawn, ros_env, probe, tmp_path
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
    probe.sample_poses(n)
    check_every_robot_moving(probe)
    check_bad_parameters_are_rejected(probe, launcher)
    disable_and_check_every_robot_stops(probe)
    enable_and_check_every_robot_moves(probe)
    sigterm_and_check_the_bag(launcher, ros_env, bag)


def test_start_swarm_script_runs_and_stops_cleanly(spawn, ros_env, probe) -> None:
    """scripts/start_swarm.sh starts bridge, supervisor and two robot hosts from the
    console scripts; the robots move; Ctrl-C (SIGINT) stops every process."""
    n = 4
    env_path = f"{BIN}{os.pathsep}{ros_env.get('PATH', '')}"
    spawn.env = {**spawn.env, "PATH": env_path}
    script = spawn.start(
        "bash", str(REPO / "scripts" / "start_swarm.sh"), "-s", "linear", "-n", str(n), "-k", "2",
        name="start_swarm",
    )  # fmt: skip
    probe.sample_poses(n)
    t0 = probe.wait_all_moving()
    probe.wait_sim(t0 + 3.0, timeout=60.0)
    moved = probe.motion(t0, probe.now)
    assert moved.min() > 1e-3, moved
    os.killpg(script.pid, signal.SIGINT)
    assert script.wait(30) == 0
    assert_no_orphans(ros_env)


def test_start_swarm_script_runs_no_code_given_as_a_setup_name(spawn, ros_env, tmp_path) -> None:
    """A setup name holding quotes, Python and ``$(...)`` is only a name: the script
    refuses it (exit 2, naming it) before it starts any process, and none of it runs."""
    spawn.env = {**spawn.env, "PATH": f"{BIN}{os.pathsep}{ros_env.get('PATH', '')}"}
    python, shell = tmp_path / "python_ran", tmp_path / "shell_ran"
    setup = f"x'+__import__('pathlib').Path('{python}').touch().__str__()+'$(touch {shell})"
    script = spawn.start(
        "bash", str(REPO / "scripts" / "start_swarm.sh"), "-s", setup, "-n", "4",
        name="start_swarm",
    )  # fmt: skip
    assert script.wait(60) == 2
    log = spawn.log(script).read_text()
    assert "start_swarm.sh: -s: " in log and setup in log, log
    assert "starting" not in log and "Traceback" not in log, log
    assert not python.exists() and not shell.exists()


def test_start_swarm_script_picks_the_launchers_host_count(spawn, ros_env, probe) -> None:
    """Without -k the script runs as many robot hosts as `aes-swarm launch`'s layout
    auto would: 16 robots at 20 Hz are one host, whatever the number of cores."""
    n = 16
    spawn.env = {**spawn.env, "PATH": f"{BIN}{os.pathsep}{ros_env.get('PATH', '')}"}
    script = spawn.start(
        "bash", str(REPO / "scripts" / "start_swarm.sh"), "-s", "combined", "-n", str(n),
        name="start_swarm",
    )  # fmt: skip
    probe.sample_poses(n)
    probe.wait_all_moving()  # every robot answers, so every host is up
    hosts = [c for c in processes_in_domain(ros_env["ROS_DOMAIN_ID"]) if "aes-robot-host" in c]
    assert len(hosts) == 1, hosts
    os.killpg(script.pid, signal.SIGINT)
    assert script.wait(30) == 0
    assert_no_orphans(ros_env)

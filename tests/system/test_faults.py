"""Runs that survive faults: processes killed with SIGKILL under ``aes-swarm launch``.

- a robot host, the supervisor, the bridge and the recorder, one after the other in
  one real-time run (``--on-failure respawn``, the default): each is restarted and
  works again (its first message after the kill arrives; how fast is measured by
  ``bench/bench_faults.py`` against the targets, not asserted here), the run
  completes with exit code 0, ``metrics.csv`` has no gap, the swarm goes on west
  after every recovery, the bag's segments read back in order, and nothing is left
  running or in shared memory;
- the launcher itself: its outputs on disk hold everything up to at most 2 s before
  the kill and load with the usual readers, ``aes-swarm report`` writes the rest, and
  no process or shared-memory file is left behind;
- in lockstep, a robot host killed: its robots leave the barrier and the run goes
  on, then rejoin; the recorder killed: its next segment counts what was lost;
- ``--on-failure stop``: the first death ends the run early, outputs written, exit 1.
"""

from __future__ import annotations

import csv
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import Twist
from helpers.probe import Probe
from helpers.ros_env import abandoned_shm, assert_no_orphans, find_process, shm_files, wait_for
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

from aes_ros.metrics_csv import CSV_COLUMNS
from aes_ros.ros import interface as names
from aes_ros.ros.bag import bag_segments, read_bags, recording_summary
from aes_ros.ros.conversions import stamp_to_ns
from aes_ros.ros.launch import reaper
from aes_ros.ros.launch.events import read_events
from aes_ros.ros.launch.processes import FASTDDS_PROFILE
from aes_ros.ros.qos import COMMAND, LATCHED, STREAM_WRITER
from aes_ros.trajectory import load_trajectory
from aes_ros.trajectory_file import is_sealed

N = 16
#: Robots of robot_host_1 (two hosts, robots split evenly).
HOST_1 = list(range(8, 16))
#: Wall seconds after a kill before a message counts as the restarted process's (the
#: first restart waits 0.5 s, so nothing sooner can come from it).
AFTER_KILL = 0.3


def launch_cmd(out: Path, *extra: str) -> list[str]:
    return [
        "aes-swarm", "launch", "--setup", "linear", "--robots", str(N), "--layout", "per-core",
        "--out", str(out), *extra,
    ]  # fmt: skip


def heading_deg(v: np.ndarray) -> float:
    return math.degrees(math.atan2(v[1], v[0]))


def metrics_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


class Arrivals:
    """Wall times at which messages of some topics arrive at the probe."""

    def __init__(self, probe: Probe) -> None:
        self.probe = probe
        self.times: dict[str, list[float]] = {}

    def watch(self, msg_type: type, topic: str, qos) -> None:
        self.times[topic] = self.probe.record(msg_type, topic, qos, lambda _m: time.monotonic())

    def first_after(self, topic: str, t: float) -> float | None:
        return next((a for a in list(self.times[topic]) if a > t), None)


def kill(ros_env: dict[str, str], needle: str) -> float:
    """SIGKILL the process whose command line holds ``needle``; the wall time of the kill."""
    pid = find_process(ros_env["ROS_DOMAIN_ID"], needle)
    os.kill(pid, signal.SIGKILL)
    return time.monotonic()


def recovered(probe: Probe, arrivals: Arrivals, topics: list[str], killed: float, what: str):
    """Wait until every topic has a message from after the kill; the recovery time [s]."""
    probe.wait(
        lambda: all(arrivals.first_after(t, killed + AFTER_KILL) for t in topics),
        30.0,
        f"{what} to recover",
    )
    return max(arrivals.first_after(t, killed + AFTER_KILL) for t in topics) - killed


def check_heading_west(probe: Probe, seconds: float, what: str) -> None:
    """Over the next ``seconds`` of sim time the centroid moves west."""
    t0 = probe.now
    probe.wait_sim(t0 + seconds)
    step = probe.position_at(t0 + seconds).mean(axis=0) - probe.position_at(t0).mean(axis=0)
    assert np.linalg.norm(step) > 0.02 and abs(heading_deg(step)) > 150.0, (what, step)


# ----------------------------------------------------------------------------- phases


def kill_robot_host(probe, arrivals, ros_env) -> float:
    killed = kill(ros_env, "robot_host:__node:=robot_host_1")
    topics = [names.robot_topic(i, names.CMD_VEL) for i in HOST_1]
    took = recovered(probe, arrivals, topics, killed, "robot_host_1's robots")
    check_heading_west(probe, 3.0, "after the robot host")
    return took


def kill_supervisor(probe, arrivals, ros_env) -> float:
    killed = kill(ros_env, "aes-supervisor")
    took = recovered(probe, arrivals, [names.ALIGNMENT], killed, "the supervisor")
    check_heading_west(probe, 3.0, "after the supervisor")
    return took


def kill_bridge(probe, arrivals, ros_env, logs: Path) -> float:
    t_before = probe.now
    killed = kill(ros_env, "aes-sim-bridge")
    topics = [names.CLOCK, *(names.robot_topic(i, names.CMD_VEL) for i in (0, 15))]
    took = recovered(probe, arrivals, topics, killed, "the bridge")

    # It carries on where it was: its clock did not start over (its ready line says
    # from when; metrics.csv, checked at the end, has no gap).
    def ready() -> list[str]:
        text = (logs / "sim_bridge.log").read_text()
        return [line for line in text.splitlines() if names.BRIDGE_READY in line]

    assert wait_for(lambda: len(ready()) == 2, 10.0), ready()
    resumed = float(ready()[-1].rsplit("t=", 1)[1].split()[0])
    assert t_before - 0.5 <= resumed <= t_before + 0.5, (t_before, ready()[-1])
    check_heading_west(probe, 3.0, "after the bridge")
    return took


def kill_recorder(probe, ros_env, out: Path) -> None:
    kill(ros_env, "aes_ros.ros.recorder")
    assert wait_for(lambda: (out.parent / "run_1.mcap").exists(), 15.0), "no new segment"
    check_heading_west(probe, 2.0, "after the recorder")


def check_events(out: Path) -> dict[str, list[dict[str, str]]]:
    by_process: dict[str, list[dict[str, str]]] = {}
    for row in read_events(out / "events.csv"):
        by_process.setdefault(row["process"], []).append(row)
    for process in ("robot_host_1", "supervisor", "sim_bridge", "recorder"):
        events = [r["event"] for r in by_process[process]]
        assert events == ["died", "restarted", "recovered"], (process, events)
        assert by_process[process][0]["exit"] == "SIGKILL"
    return by_process


def check_metrics_without_gaps(out: Path, duration: float, recovery: float) -> float:
    """metrics.csv covers the run; its largest gap (in sim time, which at a real-time
    factor of 1 is wall time) is shorter than the slowest recovery. Returns the gap."""
    rows = metrics_rows(out / "metrics.csv")
    t = np.array([float(r["t"]) for r in rows])
    assert t[-1] - t[0] >= duration - 1e-6
    gap = float(np.diff(t).max())
    assert gap <= recovery, f"a gap of {gap:.2f} s sim time, recovery {recovery:.2f} s"
    traj = load_trajectory(out / "trajectory.h5")
    np.testing.assert_allclose(traj.times, t, atol=1e-5)
    return gap


def check_segments(bag: Path) -> None:
    segments = bag_segments(bag)
    assert [s.name for s in segments] == ["run.mcap", "run_1.mcap"]
    stamps = [stamp_to_ns(msg.header.stamp) for _, _, msg in read_bags(segments, [names.POSES])]
    assert len(stamps) > 100 and np.all(np.diff(stamps) >= 0), "segments out of order"
    summary = recording_summary(segments[-1])
    assert summary and int(summary["lost_total"]) >= 0  # the last segment was closed


# ----------------------------------------------------------------------------- tests


@pytest.mark.alone  # judges recovery times
def test_killed_processes_are_restarted_and_the_run_completes(spawn, probe, ros_env, tmp_path):
    out, bag = tmp_path / "out", tmp_path / "run.mcap"
    arrivals = Arrivals(probe)
    for i in [*HOST_1, 0]:
        arrivals.watch(Twist, names.robot_topic(i, names.CMD_VEL), COMMAND)
    arrivals.watch(Float64, names.ALIGNMENT, LATCHED)
    arrivals.watch(Clock, names.CLOCK, STREAM_WRITER)
    duration = 30.0
    launcher = spawn.start(
        *launch_cmd(out, "--duration", str(duration), "--record", str(bag)), name="launch"
    )
    probe.sample_poses(N)
    probe.wait_all_moving()
    check_heading_west(probe, 2.0, "before any fault")
    took = {
        "robot host": kill_robot_host(probe, arrivals, ros_env),
        "supervisor": kill_supervisor(probe, arrivals, ros_env),
        "bridge": kill_bridge(probe, arrivals, ros_env, out / "logs"),
    }
    kill_recorder(probe, ros_env, bag)
    assert launcher.wait(120) == 0, spawn.log(launcher).read_text()[-3000:]
    log = spawn.log(launcher).read_text()
    assert "4 faults" in log and "4 recovered" in log, log[-2000:]
    events = check_events(out)
    gap = check_metrics_without_gaps(out, duration, max(took.values()))
    check_segments(bag)
    assert_no_orphans(ros_env)
    recovery = {p: rows[-1]["action"] for p, rows in events.items()}
    print(f"\nrecovery (probe): {', '.join(f'{k} {v:.2f} s' for k, v in took.items())}; "
          f"launcher's events: {recovery}; largest gap in metrics.csv {gap:.2f} s")  # fmt: skip


def test_a_killed_launcher_leaves_its_outputs_and_no_process(spawn, probe, ros_env, tmp_path):
    out = tmp_path / "out"
    domain = int(ros_env["ROS_DOMAIN_ID"])
    shm_before = shm_files(domain)
    launcher = spawn.start(
        *launch_cmd(out, "--duration", "60", "--record", str(tmp_path / "run.mcap")),
        name="launch",
    )
    probe.sample_poses(N)
    t0 = probe.wait_all_moving()
    probe.wait_sim(t0 + 6.0)
    os.kill(launcher.pid, signal.SIGKILL)  # the launcher alone, not its children
    t_kill = probe.now
    launcher.wait(10)
    # the reaper cleans for a lease and more (reaper.LINGER): until the killed launcher's
    # lease runs out the probe still sends to it and makes its port again
    assert_no_orphans(ros_env, timeout=reaper.SETTLE + 20.0)
    assert abandoned_shm(shm_before, domain) == set(), "shared memory left behind"

    rows = metrics_rows(out / "metrics.csv")  # complete rows, the usual reader
    assert all(len(r) == len(CSV_COLUMNS) and None not in r.values() for r in rows)
    t_last = float(rows[-1]["t"])
    assert t_kill - 2.0 <= t_last <= t_kill, (t_kill, t_last)  # real time: 2 s of sim time
    partial = load_trajectory(out)  # trajectory.h5 as the killed launcher left it
    assert len(partial.times) >= len(rows) and partial.positions.shape[2] == N
    report = subprocess.run(
        [str(Path(sys.executable).parent / "aes-swarm"), "report", "--out", str(out)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert report.returncode == 0, report.stderr
    assert report.stdout.startswith("linear (ROS): N=16")
    for name in ("trajectory.h5", "snapshots.png", "metrics.png"):
        assert (out / name).stat().st_size > 0
    assert is_sealed(out / "trajectory.h5")  # rewritten closed: any HDF5 reader opens it
    assert list(read_bags(bag_segments(tmp_path / "run.mcap"), [names.CLOCK]))  # readable
    print(f"\nlauncher killed at sim time {t_kill:.2f} s: metrics.csv holds up to "
          f"{t_last:.2f} s ({t_kill - t_last:.2f} s lost), "
          f"{len(partial.times)} samples on disk")  # fmt: skip


@pytest.mark.alone  # judges recovery times
def test_lockstep_goes_on_without_a_dead_robot_host_and_counts_recording_losses(
    spawn, probe, ros_env, tmp_path
):
    """Lockstep at full speed, recording: robot_host_1 hangs (SIGSTOP), its robots
    leave the barrier after lockstep_timeout and the world steps on; it is killed, and
    its robots are back in once the launcher has restarted it; the recorder killed: the
    next segment says what it missed.

    The host hangs first so that its robots surely stay silent past the timeout: a
    host killed outright may be back within the 2 s (0.9 s measured), and the barrier
    only waited (seen in CI)."""
    out, bag = tmp_path / "out", tmp_path / "run.mcap"
    launcher = spawn.start(
        *launch_cmd(out, "--lockstep", "--real-time-factor", "0", "--duration", "0",
                    "--record", str(bag)),
        name="launch",
    )  # fmt: skip
    probe.sample_poses(N)
    t0 = probe.wait_all_moving()
    probe.wait_sim(t0 + 2.0)
    host = find_process(ros_env["ROS_DOMAIN_ID"], "robot_host:__node:=robot_host_1")
    os.kill(host, signal.SIGSTOP)
    t_kill = probe.now
    # Without lockstep dropouts the bridge would stall here forever.
    probe.wait(lambda: probe.now > t_kill + 5.0, 30.0, "lockstep stepping on")
    bridge_log = out / "logs" / "sim_bridge.log"

    def said_by_all(what: str) -> bool:
        text = bridge_log.read_text()
        return all(f"lockstep: robot {i} {what}" in text for i in HOST_1)

    assert wait_for(lambda: said_by_all("silent for 2 s"), 20), bridge_log.read_text()[-3000:]
    assert "left the barrier, stopped" in bridge_log.read_text()
    os.kill(host, signal.SIGKILL)
    launcher_log = spawn.log(launcher)
    assert wait_for(lambda: "robot_host_1 recovered" in launcher_log.read_text(), 30.0)
    assert wait_for(lambda: said_by_all("answered again: back in the barrier"), 20)
    kill(ros_env, "aes_ros.ros.recorder")
    assert wait_for(lambda: (tmp_path / "run_1.mcap").exists(), 15.0)
    # At full speed 3 s of sim time can pass before the new recorder's subscriptions
    # match (seen in CI: an empty run_1.mcap, so no outage to count): wait until it
    # receives the poses, which the launcher reports as the recorder's recovery.
    assert wait_for(lambda: "recorder recovered" in launcher_log.read_text(), 30.0), (
        launcher_log.read_text()[-3000:]
    )
    t_back = probe.now
    probe.wait(lambda: probe.now > t_back + 3.0, 30.0, "stepping after the recorder")
    os.killpg(launcher.pid, signal.SIGINT)
    assert launcher.wait(60) == 0, launcher_log.read_text()[-3000:]
    summary = recording_summary(tmp_path / "run_1.mcap")
    assert int(summary["lost_total"]) > 0, summary  # the recorder's outage, counted
    assert "recorded" in summary[names.POSES]
    print(f"\nlockstep: stepped on from sim time {t_kill:.2f} s without robot_host_1; "
          f"recorder outage: {summary['lost_total']} messages counted lost ({summary[names.POSES]}"
          " on /swarm/poses)")  # fmt: skip


def test_on_failure_stop_ends_the_run_with_its_outputs(spawn, probe, ros_env, tmp_path):
    out = tmp_path / "out"
    launcher = spawn.start(
        *launch_cmd(out, "--duration", "60", "--on-failure", "stop"), name="launch"
    )
    probe.sample_poses(N)
    t0 = probe.wait_all_moving()
    probe.wait_sim(t0 + 3.0)
    kill(ros_env, "aes-supervisor")
    assert launcher.wait(60) == 1
    log = spawn.log(launcher).read_text()
    assert "supervisor died (SIGKILL); --on-failure stop" in log, log[-2000:]
    assert len(metrics_rows(out / "metrics.csv")) > 40
    assert (out / "trajectory.h5").exists() and (out / "metrics.png").exists()
    assert_no_orphans(ros_env)


@pytest.fixture
def small_disk(tmp_path: Path):
    """A 256 KB file system (tmpfs) for the outputs; skipped where mounting is not allowed."""
    mount = tmp_path / "small"
    mount.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mount)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


def test_a_full_disk_stops_the_writers_not_the_swarm(spawn, probe, ros_env, small_disk):
    out, bag = small_disk / "out", small_disk / "run.mcap"
    launcher = spawn.start(
        *launch_cmd(out, "--duration", "20", "--record", str(bag)), name="launch"
    )
    probe.sample_poses(N)
    assert launcher.wait(120) == 1
    log = spawn.log(launcher).read_text()
    assert "warning:" in log and "the run may need about" in log  # said before it started
    assert "recorder cannot write the bag" in log and "cannot write the outputs" in log, log
    assert "ran 20.0 s of sim time" in log  # the swarm ran to the end
    assert "error: the outputs are incomplete" in log
    rows = metrics_rows(out / "metrics.csv")
    # every row whole but perhaps the last, cut where the disk filled up
    complete = [r for r in rows if None not in r.values()]
    assert (
        len(complete) > 20 and complete == rows[: len(complete)] and len(rows) - len(complete) <= 1
    )
    assert len(load_trajectory(out).times) >= len(rows)
    assert list(read_bags([bag], [names.CLOCK]))  # what was written reads back


def test_another_swarm_in_the_domain_is_refused_before_anything_starts(
    spawn, probe, ros_env, tmp_path
):
    """The other swarm's bridge runs with the Fast DDS profile that aes-swarm launch and
    scripts/start_swarm.sh give their processes (announcements every 0.5 s)."""
    spawn.env = {**spawn.env, "FASTRTPS_DEFAULT_PROFILES_FILE": str(FASTDDS_PROFILE)}
    spawn.start("aes-sim-bridge", "--ros-args", "-p", "num_robots:=4", name="other")
    probe.sample_poses(4).wait(lambda: probe.times, 30.0, "the other swarm's poses")
    out = tmp_path / "out"
    launcher = spawn.start(*launch_cmd(out, "--duration", "5"), name="launch")
    assert launcher.wait(60) == 1
    log = spawn.log(launcher).read_text()
    domain = ros_env["ROS_DOMAIN_ID"]
    assert f"another swarm is active in ROS_DOMAIN_ID={domain}: /sim_bridge" in log, log
    assert not (out / "logs" / "sim_bridge.log").exists()  # refused before starting anything

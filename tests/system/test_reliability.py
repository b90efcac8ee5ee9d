"""Reliability of the running ROS system (real processes over Fast DDS, own domain).

- Robot dropout: robots whose host is killed with SIGKILL are stopped by the bridge
  within ``cmd_timeout``, their neighbours leave them out after ``neighbor_timeout``,
  the rest keeps moving aligned; restarted, they rejoin and move with the swarm.
- Supervisor and bridge restarts: robots keep the last swarm command while the
  supervisor is gone, and keep running while the bridge is gone; both resume.

The processes are started by hand (as ``scripts/start_swarm.sh`` does) rather than
by ``aes-swarm launch``, which treats a dying child as a failed run.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import time
from dataclasses import dataclass

import numpy as np
import pytest
from geometry_msgs.msg import Vector3Stamped
from helpers.messages import seconds
from helpers.probe import Probe
from helpers.ros_env import Processes, assert_no_orphans
from std_msgs.msg import Float64

from aes_ros import metrics, scenario
from aes_ros.model import Gains, SwarmCommand, total_forces
from aes_ros.ros import interface as names
from aes_ros.ros.interface import robot_topic
from aes_ros.ros.qos import COMMAND, LATCHED

N = 20
#: Robots 18 and 19 (10 %): the trailing east edge of the 4 x 5 grid moving west.
DEAD = [18, 19]
LIVE = [i for i in range(N) if i not in DEAD]
#: A robot with robot 18 as a neighbour (robot 17 is another).
WATCHED = 13
CMD_TIMEOUT = 0.5
NEIGHBOR_TIMEOUT = 1.0
DT = 0.05


# ----------------------------------------------------------------------------- dropout


def sheet_without(table: np.ndarray, dead: list[int]) -> np.ndarray:
    """The neighbour table with the dead robots' entries marked -1 (left out)."""
    out = table.copy()
    out[np.isin(out, dead)] = -1
    return out


@dataclass(frozen=True)
class Sheet:
    """The linear setup's sheet of N robots and its noise-free force (E4)."""

    table: np.ndarray
    rest: np.ndarray
    gains: Gains
    command: SwarmCommand

    @classmethod
    def linear(cls) -> Sheet:
        sc = scenario.load("linear").with_robots(N)
        _, table, rest = sc.sheet()
        return cls(table, rest, sc.gains, SwarmCommand((-1.0, 0.0), 0.0, None))

    def forces(self, positions: np.ndarray, dead: list[int]) -> np.ndarray:
        """E4 at ``positions`` with ``dead`` left out of the sheet: (N, 2)."""
        table = sheet_without(self.table, dead)
        return total_forces(positions, table, self.rest, self.gains, self.command)


def has_sample(probe: Probe, msg) -> bool:
    """The probe sampled the poses of the stamp of ``msg``."""
    k = probe.index_at(seconds(msg))
    return abs(probe.times[k] - seconds(msg)) <= 1e-6


def force_matches(probe: Probe, sheet: Sheet, msg: Vector3Stamped, dead: list[int]) -> bool:
    """Robot WATCHED's published force equals E4 on the poses of its stamp, with
    ``dead`` left out of the sheet."""
    if not has_sample(probe, msg):
        return False  # no poses sample with that stamp
    f = sheet.forces(probe.positions[probe.index_at(seconds(msg))], dead)[WATCHED]
    return bool(np.allclose([msg.vector.x, msg.vector.y], f, atol=1e-9))


def e4_report(probe: Probe, sheet: Sheet, msgs: list) -> str:
    """Why no force in ``msgs`` matched E4: per message, its stamp, whether the probe
    has the poses of that stamp, and the distance to E4 on them (all and none dead)."""
    lines = [f"E4 check is off: {len(msgs)} forces of robot {WATCHED}, {len(probe.times)} samples"]
    for m in msgs:
        t = seconds(m)
        if not has_sample(probe, m):
            nearest = probe.times[probe.index_at(t)]
            lines.append(f"  t={t:.3f}: no poses sample (nearest {nearest:.3f})")
            continue
        positions = probe.positions[probe.index_at(t)]
        got = np.array([m.vector.x, m.vector.y])
        off = [np.abs(got - sheet.forces(positions, d)[WATCHED]).max() for d in ([], DEAD)]
        lines.append(f"  t={t:.3f}: |f - E4| = {off[0]:.2e} (18, 19 left out: {off[1]:.2e})")
    return "\n".join(lines)


def host(spawn: Processes, ids: list[int], name: str, *extra: str) -> subprocess.Popen:
    return spawn.start(
        "aes-robot-host", "--ros-args", "-p", "scenario:=linear", "-p", f"num_robots:={N}",
        "-p", f"robot_ids:={ids}".replace(" ", ""), "-p", "use_sim_time:=true",
        "-p", f"neighbor_timeout:={NEIGHBOR_TIMEOUT}", *extra,
        "-r", f"robot_host:__node:={name}", name=name,
    )  # fmt: skip


def start_twenty_robots(spawn: Processes) -> subprocess.Popen:
    """Bridge (real time), supervisor, the live robots in one host and DEAD in another
    (returned)."""
    spawn.start(
        "aes-sim-bridge", "--ros-args", "-p", "scenario:=linear", "-p", f"num_robots:={N}",
        "-p", f"cmd_timeout:={CMD_TIMEOUT}", "-p", "real_time_factor:=1.0", name="bridge",
    )  # fmt: skip
    spawn.start(
        "aes-supervisor", "--ros-args", "-p", "scenario:=linear", "-p", f"num_robots:={N}",
        "-p", "use_sim_time:=true", name="supervisor",
    )  # fmt: skip
    host(spawn, LIVE, "robot_host_0")
    return host(spawn, DEAD, "robot_host_1")


def kill_host(probe: Probe, victim: subprocess.Popen, forces: dict[int, list]) -> float:
    """SIGKILL the host of DEAD; after NEIGHBOR_TIMEOUT + 3 s of sim time, returns the
    stamp of their last command, which is no later than the kill."""
    os.killpg(victim.pid, signal.SIGKILL)
    victim.wait(10)
    t_kill = probe.now
    probe.wait_sim(t_kill + NEIGHBOR_TIMEOUT + 3.0)
    t_last = max(seconds(forces[i][-1]) for i in DEAD)  # their last command
    assert t_last <= t_kill + 0.5
    return t_last


def check_stopped_within_cmd_timeout(probe: Probe, t_last: float) -> float:
    """The bridge stopped DEAD within cmd_timeout of their last command (and they stayed
    still for 2 s); returns when."""
    k_last = probe.index_at(t_last)
    k_end = len(probe.times) - 1
    ends = np.asarray(probe.positions[k_end])[DEAD]
    moving = [
        k for k in range(k_last, k_end + 1)
        if np.abs(probe.positions[k][DEAD] - ends).max() > 1e-9
    ]  # fmt: skip
    t_stopped = probe.times[moving[-1] + 1] if moving else probe.times[k_last]
    # Steps of granularity: the timeout is checked once per control step, the stop
    # shows one step later, and the bridge may have had one more cmd_vel than the
    # last aes_force seen here (a host killed between the two publishes).
    assert t_stopped - t_last <= CMD_TIMEOUT + 3 * DT + 1e-9, (t_last, t_stopped)
    assert probe.times[k_end] - t_stopped > 2.0
    return t_stopped


def check_left_out_after_neighbor_timeout(
    probe: Probe, sheet: Sheet, watched: list, t_last: float
) -> float:
    """WATCHED leaves DEAD out of its force once neighbor_timeout has passed, and from
    then on; returns when."""
    after = [m for m in watched if seconds(m) > t_last and has_sample(probe, m)]
    out = [seconds(m) for m in after if force_matches(probe, sheet, m, DEAD)]
    assert out, "robot 13 never left 18 out"
    t_out = out[0]
    assert t_out - t_last <= NEIGHBOR_TIMEOUT + 2 * DT, (t_last, t_out)
    later = [m for m in after if seconds(m) >= t_out]
    assert len(later) > 5 and all(force_matches(probe, sheet, m, DEAD) for m in later)
    return t_out


def check_the_rest_moves_west_aligned(probe: Probe, sheet: Sheet) -> float:
    """The other 18 moved over the last 2 s, west, with alignment ψ > 0.8 over the last
    1 s; returns the lowest ψ."""
    t1 = probe.now
    moved = probe.motion(t1 - 2.0, t1)[LIVE]
    assert moved.min() > 0.05, f"survivors barely moved: {moved.min():.3f} m in 2 s"
    psi = [
        metrics.alignment_order(
            sheet.forces(probe.positions[k], DEAD)[LIVE], probe.headings[k][LIVE]
        )
        for k in range(probe.index_at(t1 - 1.0), probe.index_at(t1) + 1)
    ]
    assert min(psi) > 0.8, f"alignment of the other 18: min ψ = {min(psi):.3f}"
    step = probe.position_at(t1)[LIVE].mean(0) - probe.position_at(t1 - 2.0)[LIVE].mean(0)
    assert step[0] < -0.05 and abs(step[1]) < abs(step[0])
    return min(psi)


def restart_and_check_rejoined(
    spawn: Processes, probe: Probe, sheet: Sheet, forces: dict[int, list]
) -> tuple[float, float, float]:
    """The host of DEAD restarted: within 3 s of sim time of their first command, they
    are back in WATCHED's sum and move along with the swarm. Returns (first command,
    back in the sum, moving with the swarm) [s]."""
    n_before = {i: len(forces[i]) for i in DEAD}
    host(spawn, DEAD, "robot_host_1")
    probe.wait(lambda: all(len(forces[i]) > n_before[i] for i in DEAD), 60.0, "restarted robots")
    t_back = max(seconds(forces[i][n_before[i]]) for i in DEAD)
    probe.wait_sim(t_back + 3.0)
    # Back in the neighbours' sum ...
    back = [m for m in forces[WATCHED] if seconds(m) >= t_back and has_sample(probe, m)]
    taken = [seconds(m) for m in back if force_matches(probe, sheet, m, [])]
    assert taken, "robot 13 did not take 18 back"
    t_in = taken[0]
    # ... and moving with the swarm: over the last 0.5 s each moved along the
    # swarm's direction by at least half as much as the swarm's centroid.
    t_move = None
    for k in range(probe.index_at(t_back + 0.5), len(probe.times)):
        t = probe.times[k]
        v_dead = probe.positions[k][DEAD] - probe.position_at(t - 0.5)[DEAD]
        v_swarm = probe.positions[k][LIVE].mean(0) - probe.position_at(t - 0.5)[LIVE].mean(0)
        along = v_dead @ v_swarm / np.linalg.norm(v_swarm) ** 2
        if along.min() > 0.5:
            t_move = t
            break
    assert t_move is not None and t_move - t_back <= 3.0, (t_back, t_move)
    return t_back, t_in, t_move


@pytest.mark.alone  # judges recovery times
def test_killed_robots_stop_are_left_out_and_rejoin(spawn, ros_env, probe) -> None:
    """20 robots (linear setup, real time); the host of robots 18 and 19 (10 %) is
    killed with SIGKILL. The bridge stops them within cmd_timeout; their neighbours'
    noise-free force leaves them out after neighbor_timeout; the other 18 keep moving
    west with alignment ψ > 0.8. The host is restarted: within 3 s of sim time the two
    robots are back in their neighbours' sum and move with the swarm."""
    victim = start_twenty_robots(spawn)
    sheet = Sheet.linear()
    assert 18 in sheet.table[WATCHED]
    forces = {
        i: probe.record(Vector3Stamped, robot_topic(i, names.AES_FORCE), COMMAND)
        for i in [WATCHED, *DEAD]
    }
    probe.sample_poses(N)
    t0 = probe.wait_all_moving()
    probe.wait_sim(t0 + 3.0)

    # The check itself: robot 13's force is E4 on the sampled poses. Waited for (a fresh
    # clone's CI once found none of the last 20 matching, not seen again in 8 loaded
    # runs here): if it never matches, the report says whether poses were missing or
    # how far off the force was.
    def recent() -> list:
        return forces[WATCHED][-20:]

    try:
        probe.wait(lambda: any(force_matches(probe, sheet, m, []) for m in recent()), 10.0, "E4")
    except pytest.fail.Exception:
        pytest.fail(e4_report(probe, sheet, recent()))

    t_last = kill_host(probe, victim, forces)
    t_stopped = check_stopped_within_cmd_timeout(probe, t_last)
    t_out = check_left_out_after_neighbor_timeout(probe, sheet, forces[WATCHED], t_last)
    psi = check_the_rest_moves_west_aligned(probe, sheet)
    t_back, t_in, t_move = restart_and_check_rejoined(spawn, probe, sheet, forces)
    print(
        f"\nkilled {len(DEAD)}/{N} robots: stopped {t_stopped - t_last:.2f} s after their "
        f"last command, left out after {t_out - t_last:.2f} s, min ψ of the rest "
        f"{psi:.3f}; restarted: back in the sum after {t_in - t_back:.2f} s, "
        f"moving with the swarm after {t_move - t_back:.2f} s (sim time)"
    )
    for proc in spawn.procs:
        if proc is not victim:
            assert spawn.stop(proc) == 0
    assert_no_orphans(ros_env)


# ----------------------------------------------------------------------------- restarts

#: 10 robots of the linear setup (which drives west), the supervisor told north.
WORLD = ("-p", "scenario:=linear", "-p", "num_robots:=10")
BRIDGE_CMD = ("aes-sim-bridge", "--ros-args", *WORLD, "-p", "real_time_factor:=1.0")
SUPERVISOR_CMD = (
    "aes-supervisor", "--ros-args", *WORLD, "-p", "use_sim_time:=true",
    "-p", "desired_direction:=[0.0,1.0]",
)  # fmt: skip


def heading_deg(v: np.ndarray) -> float:
    return math.degrees(math.atan2(v[1], v[0]))


def direction(probe: Probe, t0: float, t1: float) -> float:
    """Direction [deg] in which the centroid moved from sim time t0 to t1."""
    return heading_deg(probe.position_at(t1).mean(0) - probe.position_at(t0).mean(0))


def check_driving_north(probe: Probe, what: str) -> None:
    """Every robot moves, and from 2 to 4 s later the centroid heads north (±30°)."""
    t0 = probe.wait_all_moving()
    probe.wait_sim(t0 + 4.0)
    assert abs(direction(probe, t0 + 2.0, t0 + 4.0) - 90.0) < 30.0, what


def kill_supervisor_and_check_robots_keep_north(probe: Probe, supervisor) -> None:
    """Without a supervisor the robots keep its last command: north, still moving."""
    os.killpg(supervisor.pid, signal.SIGKILL)
    supervisor.wait(10)
    t_kill = probe.now
    probe.wait_sim(t_kill + 4.0)
    assert abs(direction(probe, t_kill + 1.0, t_kill + 4.0) - 90.0) < 30.0, "lost the command"
    assert probe.motion(t_kill + 3.0, t_kill + 4.0).min() > 1e-3


def restart_supervisor_and_check_it_publishes(
    spawn: Processes, probe: Probe, alignment: list
) -> subprocess.Popen:
    """A new supervisor publishes the metrics and its latched command (north), and the
    swarm goes on north."""
    count = len(alignment)
    probe.desired.clear()
    supervisor = spawn.start(*SUPERVISOR_CMD, name="supervisor")
    probe.wait(lambda: len(alignment) > count + 5, 60.0, "metrics after restart")
    assert probe.desired and probe.desired[-1].twist.linear.y == 1.0
    t_back = probe.now
    probe.wait_sim(t_back + 2.0)
    assert abs(direction(probe, t_back, t_back + 2.0) - 90.0) < 30.0
    return supervisor


def kill_bridge_and_check_robots_wait(probe: Probe, bridge, robots, supervisor) -> None:
    """Without a bridge the robot host and the supervisor keep running, and no poses
    come for 3 s of wall time."""
    os.killpg(bridge.pid, signal.SIGKILL)
    bridge.wait(10)
    deadline = probe.now
    time.sleep(3.0)
    assert robots.poll() is None and supervisor.poll() is None
    assert probe.now == deadline  # nothing new without a bridge


def restart_bridge_and_check_north_again(
    spawn: Processes, probe: Probe, alignment: list
) -> subprocess.Popen:
    """A new bridge starts the world at t = 0: the robots move north again and the
    metrics resume."""
    probe.forget_poses()  # the new bridge's clock starts at 0 again
    count = len(alignment)
    bridge = spawn.start(*BRIDGE_CMD, name="bridge")
    check_driving_north(probe, "not north after restart")
    probe.wait(lambda: len(alignment) > count + 5, 30.0, "metrics after new bridge")
    return bridge


@pytest.mark.alone  # judges recovery times
def test_supervisor_and_bridge_restarts(spawn, ros_env, probe) -> None:
    """10 robots (linear setup, which drives west), the supervisor told to drive north.
    Supervisor killed with SIGKILL: the robots keep the last desired velocity and go
    on north; restarted, it publishes again (latched command, metrics). Bridge killed
    with SIGKILL: the robot host keeps running without errors; a new bridge starts
    the world again at t = 0 and the robots move north again, the metrics resume."""
    bridge = spawn.start(*BRIDGE_CMD, name="bridge")
    supervisor = spawn.start(*SUPERVISOR_CMD, name="supervisor")
    robots = spawn.start(
        "aes-robot-host", "--ros-args", *WORLD, "-p", "use_sim_time:=true", name="robot_host"
    )
    alignment = probe.record(Float64, names.ALIGNMENT, LATCHED)
    probe.sample_poses(10)
    check_driving_north(probe, "not driving north")

    kill_supervisor_and_check_robots_keep_north(probe, supervisor)
    supervisor = restart_supervisor_and_check_it_publishes(spawn, probe, alignment)
    kill_bridge_and_check_robots_wait(probe, bridge, robots, supervisor)
    bridge = restart_bridge_and_check_north_again(spawn, probe, alignment)

    assert robots.poll() is None
    log = spawn.log(robots).read_text()
    assert "Traceback" not in log and "[ERROR]" not in log, log[-3000:]
    for proc in (robots, supervisor, bridge):
        assert spawn.stop(proc) == 0
    assert_no_orphans(ros_env)

"""The straightforward design's row of ``bench_ros``: the same bridge and supervisor with
``bench/naive_swarm.py``'s robots (a node per robot, 10 robots per process) instead of
``aes-robot-host``, measured as ``bench_ros.measure`` measures this design's."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

from aes_ros import scenario as scenario_mod

sys.path.insert(0, str(Path(__file__).resolve().parent))
from process_stats import cpu_seconds, pss_mb  # sibling scripts, not a package
from ros_rows import Row, per_robot_step

#: Wall seconds the straightforward design gets until every robot moves (~10 s at 100 robots).
NAIVE_START_TIMEOUT = 120.0


def measure_naive(robots: int, rate: float, warmup: float, window: float) -> Row:
    """The same bridge and supervisor with the straightforward design's robots
    (:mod:`naive_swarm`: a node per robot, Odometry objects, SingleThreadedExecutor,
    10 robots per process) instead of ``aes-robot-host``."""
    import tempfile

    from aes_ros.ros.launch.commands import bridge_command, supervisor_command
    from aes_ros.ros.launch.config import LaunchConfig
    from aes_ros.ros.launch.layout import split_robots
    from aes_ros.ros.launch.monitor import Monitor
    from aes_ros.ros.launch.param_files import write_scenario
    from aes_ros.ros.launch.preflight import refuse_other_swarm
    from aes_ros.ros.launch.processes import ProcessSet, fastdds_environment

    sc = scenario_mod.load("combined", {"dt": 1.0 / rate}).with_robots(robots)
    config = LaunchConfig(sc, neighbor_source="odom", mode="kinematic", duration=0.0)
    work = Path(tempfile.mkdtemp(prefix="aes-bench-naive-"))
    scenario_file = write_scenario(sc, work / "scenario.yaml")
    procs = ProcessSet(work / "logs", fastdds_environment(dict(os.environ)))
    monitor = Monitor(robots)
    naive = Path(__file__).with_name("naive_swarm.py")
    t0 = time.monotonic()
    try:
        refuse_other_swarm(monitor.other_swarm(1.0))  # as a launch does: it would take commands
        children = [procs.start(*bridge_command(config, scenario_file)),
                    procs.start(*supervisor_command(config, scenario_file))]  # fmt: skip
        for k, ids in enumerate(split_robots(robots, -(-robots // 10))):
            cmd = [sys.executable, str(naive), "--scenario", str(scenario_file),
                   "--ids", f"{ids[0]}:{ids[-1] + 1}"]  # fmt: skip
            children.append(procs.start(f"robot_naive_{k}", cmd))
        deadline = time.monotonic() + NAIVE_START_TIMEOUT
        moved = np.zeros(robots, dtype=bool)
        checked = 0.0
        while not moved.all():
            monitor.spin_once(0.05)
            if time.monotonic() - checked > 0.5:
                checked = time.monotonic()
                refuse_other_swarm(monitor.second_swarm())
            if len(monitor.times) > 1:
                moved |= (
                    np.linalg.norm(monitor.positions[-1] - monitor.positions[0], axis=-1) > 1e-4
                )
            if time.monotonic() > deadline or any(c.proc.poll() is not None for c in children):
                still = np.flatnonzero(~moved)
                raise RuntimeError(
                    f"the naive swarm did not start within {time.monotonic() - t0:.0f} s: "
                    f"{len(still)} of {robots} robots never moved (first: {still[:10].tolist()}), "
                    f"{len(monitor.times)} pose samples; logs in {work / 'logs'}"
                )
        start_s = time.monotonic() - t0
        monitor.spin_for(warmup)
        monitor.bridge_stats()
        pids = {c.name: c.proc.pid for c in children}
        cpu0 = {name: cpu_seconds(pid) for name, pid in pids.items()}
        w0 = time.monotonic()
        monitor.spin_for(window)
        stats = monitor.bridge_stats()
        wall = time.monotonic() - w0
        cpu = {name: 100.0 * (cpu_seconds(pid) - cpu0[name]) / wall for name, pid in pids.items()}
        memory = sum(pss_mb(pid) for pid in pids.values())
    finally:
        procs.stop_all(10.0)
        monitor.close()
    robot_cpu = sum(v for k, v in cpu.items() if k.startswith("robot"))
    return Row(
        robots, rate, "odom", "naive", start_s, stats["real_time_factor"],
        stats["rate_min_hz"], stats["rate_median_hz"],
        stats["latency_p50_ms"] or float("nan"), stats["latency_p99_ms"] or float("nan"),
        cpu["sim_bridge"], cpu["supervisor"], robot_cpu, 0.0, memory, len(pids),
        per_robot_step(cpu["sim_bridge"] + cpu["supervisor"] + robot_cpu, stats, robots),
        "naive",
    )  # fmt: skip

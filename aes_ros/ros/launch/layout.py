"""How a launch spreads its robots over processes: the layout ``auto`` stands for and
the robots of each robot process."""

from __future__ import annotations

import os

import numpy as np

from aes_ros.ros.launch.config import LaunchConfig


def split_robots(n: int, parts: int) -> list[list[int]]:
    """Robot ids 0..n-1 in ``parts`` contiguous, nearly equal blocks (no empty block)."""
    parts = max(1, min(parts, n))
    return [list(map(int, block)) for block in np.array_split(np.arange(n), parts)]


#: ``auto`` runs all robots in one host process up to this many robot-steps per second
#: (robots × control rate), and beyond it too on a machine of two cores or fewer.
AUTO_SINGLE_STEPS = 20000.0


def resolved_layout(config: LaunchConfig) -> str:
    """The layout ``auto`` stands for (:func:`auto_layout`); any other layout as it is."""
    if config.layout != "auto":
        return config.layout
    return auto_layout(config.num_robots, config.scenario.dt, config.cores)


def robot_process_count(config: LaunchConfig) -> int:
    """How many processes run the robots (:func:`robot_commands`)."""
    layout, n = resolved_layout(config), config.num_robots
    if layout == "per-robot":
        return n
    return 1 if layout == "single" else min(n, config.cores or os.cpu_count() or 1)


def auto_layout(num_robots: int, dt: float, cores: int | None = None) -> str:
    """``single`` or ``per-core``: what ``auto`` means for ``num_robots`` robots at a
    control period of ``dt`` [s] on ``cores`` cores (None: this machine's)
    (``scripts/start_swarm.sh`` uses it for its default host count too).

    ``single`` up to AUTO_SINGLE_STEPS robot-steps per second, and always with two
    cores or fewer; ``per-core`` above it on a bigger machine. Why: every extra robot
    process reads every swarm message, runs its own executor, and must discover the
    other processes' robots endpoint by endpoint. Two cores, same code, same hour
    (bench/bench_ros.py, docs/performance.md), one host against two, answered rate
    and CPU per robot-step: 400 robots at 50 Hz 49.9 Hz / 64 µs against 44.7 Hz /
    100 µs; 1000 at 20 Hz 19.8 Hz / 72 µs against 12.3-12.9 Hz / 151-158 µs, and every
    robot moving after 32 s against 62-80 s; 1000 at 50 Hz, more than either carries,
    13.0 against 11.9 Hz. One host's Python runs on one core, which is about 20000
    robot-steps per second here (400 at 50 Hz, 1000 at 20 Hz): beyond that, more cores
    than two give the other hosts cores of their own (not measured here).
    """
    steps = num_robots / dt
    cores = os.cpu_count() if cores is None else cores
    return "single" if steps <= AUTO_SINGLE_STEPS or (cores or 1) <= 2 else "per-core"

"""Checks before a launch starts anything: would it write over an earlier run, can its
outputs be written, and is there room for them (pure: files and disk space; the
domain check is the monitor's)."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from aes_ros.previous_run import LAUNCH_OUTPUTS, check_out_dir, refuse, refuse_foreign
from aes_ros.ros.bag import parse_split, recording_files
from aes_ros.ros.launch.config import LaunchConfig
from aes_ros.ros.programs import LaunchError

#: Bytes per sample per robot of the trajectory: 3 float64 in trajectory.h5, written
#: once (uncompressed; its partly filled last chunks are within the 2 MB below).
TRAJECTORY_BYTES = 3 * 8
#: Bytes per metrics.csv row.
METRICS_ROW_BYTES = 90
#: Bag bytes per control step: per robot its pose in /swarm/poses (56) and a
#: cmd_vel record (about 100 with the MCAP record and index); plus /clock and the
#: supervisor's topics. An upper bound: the chunks are zstd-compressed.
BAG_BYTES_PER_ROBOT = 160
BAG_BYTES_PER_STEP = 600
#: Sim seconds assumed for a run without a set duration (``--duration 0``).
OPEN_ENDED_S = 600.0


def earlier_run(config: LaunchConfig) -> list[Path]:
    """The files of an earlier run where this launch would write: its outputs in
    ``out_dir`` (:data:`~aes_ros.previous_run.LAUNCH_OUTPUTS`) and the files of an
    earlier recording at ``record`` (:func:`~aes_ros.ros.bag.recording_files`).
    :class:`~aes_ros.previous_run.EarlierRunError` naming them unless
    ``config.overwrite``, when they are returned for the launcher to remove."""
    found = check_out_dir(config.out_dir, LAUNCH_OUTPUTS, overwrite=config.overwrite)
    if config.record is not None:
        refuse_foreign(Path(config.record).parent, "--record")
        bag = recording_files(config.record)
        found += refuse(bag, f"--record {config.record}", config.overwrite, "an earlier recording")
    return found


def check_writable(directory: Path, what: str) -> None:
    """Create ``directory`` and a file in it; LaunchError naming ``what`` if it cannot."""
    try:
        Path(directory).mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=directory, prefix=".aes-write-test-"):
            pass
    except OSError as exc:
        raise LaunchError(f"{what}: cannot write to {directory} ({exc.strerror or exc})") from None


def expected_bytes(config: LaunchConfig) -> dict[str, int]:
    """Rough upper bounds of the bytes a launch writes: ``outputs`` (into out_dir) and
    ``bag`` (the recording), for its duration (10 minutes when open-ended); a recording
    that keeps K segments (``bag_keep``) needs room for K + 1 of them at most."""
    seconds = config.run_time if config.run_time > 0 else OPEN_ENDED_S
    steps = seconds / float(config.scenario.dt)
    n = config.num_robots
    outputs = steps * (n * TRAJECTORY_BYTES + METRICS_ROW_BYTES) + 2_000_000  # + plots, logs
    per_step = n * BAG_BYTES_PER_ROBOT + BAG_BYTES_PER_STEP
    bag = steps * per_step if config.record else 0
    split = parse_split(config.bag_split) if config.record and config.bag_split else None
    if split is not None and config.bag_keep:
        # a segment of wall seconds spans real_time_factor times as much sim time
        # (unknown at 0, as fast as possible)
        sim_seconds = (split.seconds or 0.0) * config.real_time_factor
        segment = split.size or sim_seconds / float(config.scenario.dt) * per_step
        if segment:
            bag = min(bag, (config.bag_keep + 1) * segment)
    return {"outputs": int(outputs), "bag": int(bag)}


def room_warnings(config: LaunchConfig) -> list[str]:
    """Warnings for file systems with less free space than the run is expected to need."""
    need = expected_bytes(config)
    places: dict[int, list] = {}  # device -> [free bytes, needed bytes, paths]
    targets = []
    if config.out_dir is not None:
        targets.append(("outputs", Path(config.out_dir)))
    if config.record is not None:
        targets.append(("bag", Path(config.record).parent))
    for kind, path in targets:
        device = os.stat(path).st_dev
        entry = places.setdefault(device, [shutil.disk_usage(path).free, 0, []])
        entry[1] += need[kind]
        entry[2].append(str(path))
    horizon = "" if config.run_time > 0 else f" per {OPEN_ENDED_S / 60:g} minutes"
    return [
        f"{' and '.join(paths)}: {free / 1e6:.0f} MB free, the run may need about "
        f"{needed / 1e6:.0f} MB{horizon}; outputs stop with an error when the disk is full"
        for free, needed, paths in places.values()
        if free < needed
    ]


def check_outputs(config: LaunchConfig) -> list[str]:
    """LaunchError if the output directory or the bag's directory cannot be written;
    warnings where the free space looks short."""
    if config.out_dir is not None:
        check_writable(Path(config.out_dir), "--out")
    if config.record is not None:
        check_writable(Path(config.record).resolve().parent, "--record")
    return room_warnings(config)


def refuse_other_swarm(others: list[str]) -> None:
    """LaunchError naming the nodes of another swarm in this ROS domain, if any."""
    if others:
        domain = os.environ.get("ROS_DOMAIN_ID", "0")
        raise LaunchError(
            f"another swarm is active in ROS_DOMAIN_ID={domain}: {', '.join(others[:6])}"
            f"{' …' if len(others) > 6 else ''}; stop it, or start this one with another "
            "ROS_DOMAIN_ID"
        )

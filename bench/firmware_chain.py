"""The full chain of ``aes-swarm launch --firmware sil`` measured beside the same launch
without firmware (bench/bench_firmware.py's ``--robots``; docs/firmware.md).

One :func:`run` is one ``aes-swarm launch --setup linear --mode dynamic`` (the wheels of
both runs are pybullet's, saturated alike): its real-time factor (sim seconds of the
bridge's clock over wall seconds, between the launcher's first and last progress lines),
ψ̄ and ψ̄_heading (the means of metrics.csv's ``alignment`` and ``heading_order`` over
the run) and, sampled mid-run, the CPU of each kind of process [% of one core].
"""

from __future__ import annotations

import csv
import os
import re
import statistics
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import psutil

from aes_ros.ros.programs import executable

PROGRESS = re.compile(r"t =\s*([\d.]+) s .*\[wall ([\d.]+) s\]")
#: Which process a command line is, for the CPU profile.
KINDS = (
    ("mona-sil", "mona-sil"),
    ("aes-mona-driver", "mona_driver"),
    ("firmware_loop", "firmware_loop"),
    ("aes-sim-bridge", "sim_bridge"),
    ("aes-robot-host", "robot_host"),
    ("aes-supervisor", "supervisor"),
    ("aes-swarm", "launcher"),
)


def kind(cmdline: list[str]) -> str:
    text = " ".join(cmdline)
    return next((name for key, name in KINDS if key in text), "other")


def cpu_profile(root: psutil.Process, window_s: float) -> dict[str, float]:
    """CPU of ``root`` and its descendants over ``window_s`` [% of one core], summed by
    kind (``mona-sil``: all the MCUs together)."""
    procs = [root, *root.children(recursive=True)]
    before = {}
    for p in procs:
        try:
            before[p] = (kind(p.cmdline()), sum(p.cpu_times()[:2]))
        except psutil.Error:
            pass
    time.sleep(window_s)
    out: dict[str, float] = {}
    for p, (name, cpu0) in before.items():
        try:
            used = sum(p.cpu_times()[:2]) - cpu0
        except psutil.Error:
            continue
        out[name] = out.get(name, 0.0) + 100.0 * used / window_s
    return out


def ros_environment() -> dict[str, str]:
    """The environment of the benchmark's ROS processes: this host only, a domain of its
    own unless ``ROS_DOMAIN_ID`` is set."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.setdefault("ROS_DOMAIN_ID", str(140 + os.getpid() % 40))
    return env


def run(robots: int, duration: float, firmware: bool, seed: int = 0) -> dict[str, object]:
    """One launch; its real-time factor, ψ̄, ψ̄_heading and CPU profile."""
    env = ros_environment()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [executable("aes-swarm"), "launch", "--setup", "linear", "--robots", str(robots),
               "--mode", "dynamic", "--seed", str(seed), "--duration", str(duration),
               "--out", str(out), *(["--firmware", "sil"] if firmware else [])]  # fmt: skip
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True)
        lines: list[str] = []
        reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
        reader.start()
        profile: dict[str, float] = {}
        deadline = time.monotonic() + 120.0
        while not any("moving at sim time" in line for line in lines):
            if proc.poll() is not None or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        if proc.poll() is None:
            time.sleep(min(3.0, duration / 4))
            try:
                profile = cpu_profile(psutil.Process(proc.pid), min(5.0, duration / 3))
            except psutil.Error:
                pass
        if proc.wait(timeout=180) != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed:\n{''.join(lines)[-2000:]}")
        reader.join(5.0)
        with open(out / "metrics.csv") as fh:
            rows = list(csv.DictReader(fh))
    marks = [(float(m[1]), float(m[2])) for m in map(PROGRESS.search, lines) if m]
    rtf = float("nan")
    if len(marks) >= 2 and marks[-1][1] > marks[0][1]:
        rtf = (marks[-1][0] - marks[0][0]) / (marks[-1][1] - marks[0][1])
    return {
        "robots": robots,
        "firmware": "sil" if firmware else "none",
        "rtf": rtf,
        "psi": statistics.fmean(float(r["alignment"]) for r in rows),
        "psi_heading": statistics.fmean(float(r["heading_order"]) for r in rows),
        "cpu": profile,
    }

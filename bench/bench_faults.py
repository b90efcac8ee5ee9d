"""Recovery times of a launched swarm whose processes are killed with SIGKILL.

Starts ``aes-swarm launch`` (linear setup, real time, ``--on-failure respawn``,
recording) in a ROS domain of its own and, once every robot moves, kills in turn
a robot host, the supervisor, the bridge and the recorder, waiting for each to
recover before the next. A recovery is timed from the kill to the first message
of the restarted process arriving at an observer node in this process (with the
Fast DDS profile of the launched processes, as any node of the system): every
robot of the killed host's ``cmd_vel``, the supervisor's ``/swarm/alignment``,
the bridge's ``/clock`` (the swarm's ``cmd_vel`` too), the recorder's
``/recorder/progress``. The launcher's own view (from the death it noticed to the
restarted process's ready line, ``events.csv``) is printed next to it. Also
reported: the largest gap of sim time in the run's ``metrics.csv`` and whether the
launcher exited 0. Repeated ``--runs`` times.

Targets (issue #11): robot host and supervisor <= 3 s, bridge <= 5 s.

Usage::

    python bench/bench_faults.py                 # 3 runs of 16 robots (~3 min)
    python bench/bench_faults.py --runs 1 --robots 36

Prints a table and, as its last line, ``RESULT robot_host_s=<max>
supervisor_s=<max> bridge_s=<max> recorder_s=<max> gap_s=<max> targets_met=<yes|no>``;
writes ``bench_faults.csv`` to ``--out``.
"""

from __future__ import annotations

import argparse
import csv
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import rclpy
from geometry_msgs.msg import Twist
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

from aes_ros.cli.deprecated import add_deprecated
from aes_ros.cli.options import MAX_RUNS, number_type
from aes_ros.ros import interface as names
from aes_ros.ros.launch.events import read_events
from aes_ros.ros.launch.processes import fastdds_environment
from aes_ros.ros.qos import COMMAND, LATCHED

TARGETS = {"robot_host": 3.0, "supervisor": 3.0, "sim_bridge": 5.0}
#: A message arriving this soon after a kill may still be the dead process's.
AFTER_KILL = 0.3
BIN = Path(sys.executable).parent


class Observer:
    """Wall arrival times of messages, recorded by a node spun in a thread."""

    def __init__(self) -> None:
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("bench_faults", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.arrivals: dict[str, list[float]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def watch(self, msg_type: type, topic: str, qos: QoSProfile) -> None:
        times: list[float] = []
        self.arrivals[topic] = times
        self.node.create_subscription(
            msg_type, topic, lambda _m: times.append(time.monotonic()), qos
        )

    def recovery(self, topics: list[str], killed: float, timeout: float = 60.0) -> float:
        """Seconds from ``killed`` to the first message after it on every topic."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            firsts = [next((a for a in self.arrivals[t] if a > killed + AFTER_KILL), None)
                      for t in topics]  # fmt: skip
            if all(f is not None for f in firsts):
                return max(firsts) - killed
            time.sleep(0.02)
        raise RuntimeError(f"no recovery of {topics} within {timeout} s")

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def pid_of(domain: str, needle: str) -> int:
    """The live process of ``domain`` whose command line holds ``needle``."""
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if f"ROS_DOMAIN_ID={domain}".encode() not in (entry / "environ").read_bytes().split(
                b"\0"
            ):
                continue
            if needle.encode() in (entry / "cmdline").read_bytes():
                return int(entry.name)
        except OSError:
            continue
    raise RuntimeError(f"no process {needle!r} in domain {domain}")


def one_run(robots: int, domain: str, work: Path) -> dict[str, float]:
    out = work / "out"
    launcher = subprocess.Popen(
        [str(BIN / "aes-swarm"), "launch", "--setup", "linear", "--robots", str(robots),
         "--duration", "0", "--out", str(out), "--record", str(work / "run.mcap")],
        stdout=open(work / "launch.log", "w"), stderr=subprocess.STDOUT,
        start_new_session=True,
    )  # fmt: skip
    obs = Observer()
    host_1 = list(range(robots // 2, robots))
    try:
        for i in [0, *host_1]:
            obs.watch(Twist, names.robot_topic(i, names.CMD_VEL), COMMAND)
        obs.watch(Float64, names.ALIGNMENT, LATCHED)
        best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        obs.watch(Clock, names.CLOCK, best_effort)
        obs.watch(Clock, names.RECORDER_PROGRESS, LATCHED)
        log = work / "launch.log"
        deadline = time.monotonic() + 120
        while "robots moving" not in log.read_text():
            if time.monotonic() > deadline or launcher.poll() is not None:
                raise RuntimeError(f"the launch did not start:\n{log.read_text()[-2000:]}")
            time.sleep(0.1)
        time.sleep(3.0)
        kills = [
            ("robot_host", "robot_host:__node:=robot_host_1",
             [names.robot_topic(i, names.CMD_VEL) for i in host_1]),
            ("supervisor", "aes-supervisor", [names.ALIGNMENT]),
            ("sim_bridge", "aes-sim-bridge",
             [names.CLOCK, names.robot_topic(0, names.CMD_VEL),
              names.robot_topic(robots - 1, names.CMD_VEL)]),
            ("recorder", "aes_ros.ros.recorder", [names.RECORDER_PROGRESS]),
        ]  # fmt: skip
        took: dict[str, float] = {}
        for name, needle, topics in kills:
            os.kill(pid_of(domain, needle), signal.SIGKILL)
            killed = time.monotonic()
            took[name] = obs.recovery(topics, killed)
            time.sleep(3.0)
    finally:
        obs.close()
        os.killpg(launcher.pid, signal.SIGINT)
        code = launcher.wait(120)
    rows = list(csv.DictReader(open(out / "metrics.csv")))
    t = np.array([float(r["t"]) for r in rows])
    took["gap"] = float(np.diff(t).max())
    took["exit_code"] = float(code)
    for event in read_events(out / "events.csv"):
        if event["event"] == "recovered":
            name = event["process"].removesuffix("_1")
            took[f"{name} (launcher)"] = float(event["action"].split()[0])
    return took


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=16)
    parser.add_argument(
        "--runs", type=number_type(int, 1, MAX_RUNS), default=3, metavar="N",
        help="fault runs of each kind (default 3)",
    )  # fmt: skip
    add_deprecated(parser, "--repeats", "--runs")
    parser.add_argument("--domain", default="97", help="the ROS_DOMAIN_ID of the runs")
    parser.add_argument("--out", type=Path, default=Path("out/bench_faults"))
    args = parser.parse_args(argv)
    os.environ["ROS_DOMAIN_ID"] = args.domain
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.update(fastdds_environment(dict(os.environ)))
    args.out.mkdir(parents=True, exist_ok=True)
    runs = []
    for k in range(args.runs):
        with tempfile.TemporaryDirectory(prefix="aes-bench-faults-") as work:
            took = one_run(args.robots, args.domain, Path(work))
        runs.append(took)
        print(f"run {k}: " + ", ".join(f"{n} {v:.2f}" for n, v in took.items()), flush=True)
    names_ = ["robot_host", "supervisor", "sim_bridge", "recorder", "gap"]
    names_ += [f"{n} (launcher)" for n in names_[:4]]
    print(f"\n{'recovery [s]':<24}{'target':>8}{'median':>9}{'max':>8}")
    worst = {}
    for name in names_:
        values = [r[name] for r in runs if name in r]
        worst[name] = max(values)
        target = f"{TARGETS[name]:g}" if name in TARGETS else "-"
        print(f"{name:<24}{target:>8}{np.median(values):>9.2f}{max(values):>8.2f}")
    with open(args.out / "bench_faults.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(runs[0]), restval="")
        writer.writeheader()
        writer.writerows(runs)
    met = all(worst[n] <= t for n, t in TARGETS.items()) and all(r["exit_code"] == 0 for r in runs)
    print(
        f"RESULT robot_host_s={worst['robot_host']:.2f} supervisor_s={worst['supervisor']:.2f} "
        f"bridge_s={worst['sim_bridge']:.2f} recorder_s={worst['recorder']:.2f} "
        f"gap_s={worst['gap']:.2f} targets_met={'yes' if met else 'no'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The latency of one robot's command through the real firmware: ``cmd_vel`` → PWM
(bench/bench_firmware.py; docs/firmware.md).

One ``mona-sil`` on ``mona.elf``, ``aes-mona-driver`` on its pseudo-terminal and
``firmware_loop`` on its log, as ``aes-swarm launch --firmware sil`` starts them, in a
ROS domain of their own. This process publishes ``/mona_0/cmd_vel`` every 50 ms, two
forward speeds in turn (so that each one changes the PWM), notes the wall time of each
publication, and measures from it:

- ``pwm``: to the MCU's ``motors`` line (its PWM compare registers changed), read from
  ``mona-sil``'s stdout as it comes (and passed on to the log ``firmware_loop`` reads);
- ``wheel_cmd``: to the ``/mona_0/wheel_cmd`` that ``firmware_loop`` publishes from that
  line, as the bridge receives it.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import rclpy
from geometry_msgs.msg import Twist
from rclpy.executors import SingleThreadedExecutor

from aes_ros.ros import interface as names
from aes_ros.ros.launch import firmware as fw
from aes_ros.ros.launch.processes import ProcessSet
from aes_ros.ros.qos import LATEST_COMMAND

PERIOD_S = 0.05  # a robot node's cmd_vel period (20 Hz)
SPEEDS = (0.03, 0.06)  # [m/s] in turn: PWM 57 and 113 on both wheels
WARMUP_S = 1.0
READY_TIMEOUT_S = 60.0


def latencies_ms(sends: list[tuple[float, int]], events: list[tuple[float, int]]) -> list[float]:
    """From each publication (wall time, speed index) to the first event (wall time,
    speed index) that shows its speed after the other one: an event follows the last
    publication of its speed, which is at most two periods old."""
    out, last, j = [], None, 0
    latest: dict[int, float] = {}
    for t, k in events:
        while j < len(sends) and sends[j][0] <= t:
            latest[sends[j][1]] = sends[j][0]
            j += 1
        if k != last and k in latest and t - latest[k] < 2 * PERIOD_S:
            out.append((t - latest[k]) * 1e3)
        last = k
    return out


def quantiles(values: list[float]) -> tuple[float, float]:
    """p50 and p99 [ms] (NaN for fewer than two values)."""
    if len(values) < 2:
        return float("nan"), float("nan")
    q = statistics.quantiles(values, n=100)
    return q[49], q[98]


class _Mcu:
    """``mona-sil`` with its stdout read as it comes: ``motors`` lines timed, every line
    passed on to ``log`` for ``firmware_loop``."""

    def __init__(self, log: Path) -> None:
        self.proc = subprocess.Popen(
            [str(fw.BUILD / "mona-sil"), "--robot-id", "0", str(fw.BUILD / "mona.elf")],
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, text=True,
        )  # fmt: skip
        assert self.proc.stdout is not None
        first = self.proc.stdout.readline()
        if not first.startswith(fw.PTY_LINE):
            raise RuntimeError(f"mona-sil did not start: {first!r}")
        self.pty = first.split()[1]
        self.log = open(log, "w")  # closed in stop
        self.log.write(first)
        self.log.flush()
        self.motors: list[tuple[float, int]] = []  # (wall time, speed index)
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            now = time.monotonic()
            if line.startswith("motors "):
                left = int(line.split("left=")[1].split()[0])
                self.motors.append((now, int(left > 85)))  # between PWM 57 and 113
            self.log.write(line)
            self.log.flush()

    def stop(self) -> None:
        self.proc.terminate()
        self.proc.wait(timeout=10)
        self.log.close()


def measure(duration: float, env: dict[str, str]) -> dict[str, float]:
    """Publish ``cmd_vel`` for ``duration`` s after a warm-up; the latencies' p50/p99 [ms].

    ``env``: the ROS environment of the driver, ``firmware_loop`` and this process."""
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "mona_sil_0.log"
        mcu = _Mcu(log)
        procs = ProcessSet(Path(tmp) / "logs", env)
        for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE"):  # for rclpy here
            os.environ[key] = env[key]
        context = rclpy.Context()
        rclpy.init(args=[], context=context)
        executor = SingleThreadedExecutor(context=context)
        try:
            procs.start(*fw.driver_command([mcu.pty]))
            procs.start(*fw.loop_command([log], sys.executable))
            node = rclpy.create_node("bench_firmware_latency", context=context)
            executor.add_node(node)
            wheel_cmd: list[tuple[float, int]] = []

            def on_wheel_cmd(msg: Twist) -> None:
                wheel_cmd.append((time.monotonic(), int(msg.linear.x > sum(SPEEDS) / 2)))

            topic = names.robot_topic(0, names.CMD_VEL)
            pub = node.create_publisher(Twist, topic, LATEST_COMMAND)
            node.create_subscription(
                Twist, names.robot_topic(0, names.WHEEL_CMD), on_wheel_cmd, LATEST_COMMAND
            )
            threading.Thread(target=executor.spin, daemon=True).start()
            deadline = time.monotonic() + READY_TIMEOUT_S
            while (
                pub.get_subscription_count() == 0
                or node.count_publishers(names.robot_topic(0, names.WHEEL_CMD)) == 0
            ):
                if time.monotonic() > deadline:
                    tails = "\n".join(c.tail(1000) for c in procs.children)
                    raise RuntimeError(f"the driver or firmware_loop did not start:\n{tails}")
                time.sleep(0.1)
            sends: list[tuple[float, int]] = []
            msg, k = Twist(), 0
            tick = time.monotonic()
            start, end = tick + WARMUP_S, tick + WARMUP_S + duration
            while tick < end:
                k = 1 - k
                msg.linear.x = SPEEDS[k]
                now = time.monotonic()
                pub.publish(msg)
                if now >= start:
                    sends.append((now, k))
                tick += PERIOD_S
                time.sleep(max(0.0, tick - time.monotonic()))
            time.sleep(0.5)  # the last events
        finally:
            executor.shutdown(timeout_sec=5.0)
            rclpy.try_shutdown(context=context)
            procs.stop_all(10.0)
            mcu.stop()
    pwm = latencies_ms(sends, [e for e in mcu.motors if e[0] >= start])
    loop = latencies_ms(sends, [e for e in wheel_cmd if e[0] >= start])
    (pwm50, pwm99), (loop50, loop99) = quantiles(pwm), quantiles(loop)
    return {
        "sent": len(sends),
        "pwm_samples": len(pwm),
        "pwm_p50_ms": pwm50,
        "pwm_p99_ms": pwm99,
        "wheel_cmd_samples": len(loop),
        "wheel_cmd_p50_ms": loop50,
        "wheel_cmd_p99_ms": loop99,
    }

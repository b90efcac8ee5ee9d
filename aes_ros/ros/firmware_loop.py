"""The simulated MCUs' motor outputs as each robot's wheel twist (``--firmware sil``).

Reads the ``motors t=… left=… right=…`` lines that every ``mona-sil`` writes to its log
(robot ``i``: the ``i``-th file), turns the PWM compare values back into wheel rim
speeds (the inverse of ``firmware/mona/motors.c``: 255 = ``MonaGeometry``'s top rim
speed) and publishes the body twist they drive on ``/mona_<i>/wheel_cmd``
(geometry_msgs/Twist), which the bridge takes instead of ``cmd_vel``
(:mod:`aes_ros.ros.launch.firmware`). A Twist, not a custom message: the bridge and any
ROS tool read it unchanged.

Reading the logs rather than the MCUs' pipes lets the launcher start and supervise each
``mona-sil`` like every other process (a log never fills up and stalls an MCU). The
driver opens each MCU through a symlink beside its log (:func:`pty_link`); a restarted
MCU says a new ``pty:`` line, and this node points the link at it, so the driver's
reconnect finds the new MCU.

    python -m aes_ros.ros.firmware_loop LOG0 LOG1 ... [--ros-args ...]
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
from pathlib import Path

from geometry_msgs.msg import Twist
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from aes_ros.mona.geometry import MonaGeometry, twist_from_wheels
from aes_ros.ros import interface as names
from aes_ros.ros.qos import LATEST_COMMAND
from aes_ros.ros.spin import run_node_process

NODE = names.FIRMWARE_LOOP_NODE
#: The topic in each robot's namespace with the twist its MCU's motors drive.
WHEEL_CMD = names.WHEEL_CMD
PTY = re.compile(rb"^pty: (\S+)$", re.M)
MOTORS = re.compile(rb"^motors t=\S+ left=(-?\d+) right=(-?\d+)$", re.M)
DUTY_FULL = 255  # the PWM compare value of full duty (OCR1A/OCR1B)
POLL_S = 0.01  # how often the logs are read: a small part of a 20 ms control step
# Every twist again, for a bridge that (re)started late, and within half the bridge's
# cmd_timeout (0.5 s): a duty held longer than that must not go stale there.
REPUBLISH_S = 0.2


def rim_speeds(left: int, right: int, geometry: MonaGeometry | None = None) -> tuple[float, float]:
    """Wheel rim speeds [mm/s] of signed PWM compare values (−255 … 255)."""
    top = (geometry or MonaGeometry()).max_rim_speed_mm_s
    return left * top / DUTY_FULL, right * top / DUTY_FULL


def pty_link(log: Path) -> Path:
    """The symlink to the serial device of the MCU that writes ``log``."""
    return log.with_suffix(".pty")


def point_link(link: Path, device: str) -> None:
    """Make ``link`` a symlink to ``device`` (replaced in one step)."""
    if os.path.islink(link) and os.readlink(link) == device:
        return
    tmp = link.with_name(link.name + ".new")
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()
    os.symlink(device, tmp)
    os.replace(tmp, link)


def last_motors(text: bytes) -> tuple[int, int] | None:
    """The (left, right) of the last complete ``motors`` line in ``text`` (None: none)."""
    found = MOTORS.findall(text)
    return (int(found[-1][0]), int(found[-1][1])) if found else None


class FirmwareLoopNode(Node):
    """Publishes ``/mona_<i>/wheel_cmd`` from robot ``i``'s MCU log; no parameters."""

    def __init__(self, logs: list[Path]) -> None:
        super().__init__(NODE)
        self.logs = logs
        self.files = [open(path, "rb") for path in logs]  # closed in destroy_node
        self.pending = [b""] * len(logs)
        self.duty: list[tuple[int, int]] = [(0, 0)] * len(logs)
        self.pubs = [
            self.create_publisher(Twist, names.robot_topic(i, WHEEL_CMD), LATEST_COMMAND)
            for i in range(len(logs))
        ]
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(POLL_S, self.on_poll, clock=steady)
        self.create_timer(REPUBLISH_S, self.on_republish, clock=steady)
        self.get_logger().info(f"{names.FIRMWARE_LOOP_READY} {len(logs)} MCUs → {WHEEL_CMD}")

    def on_poll(self) -> None:
        """Publish the twist of every MCU whose motor outputs changed."""
        for i, fh in enumerate(self.files):
            chunk = fh.read()
            if not chunk:
                continue
            text = self.pending[i] + chunk
            cut = text.rfind(b"\n") + 1
            self.pending[i] = text[cut:]
            for device in PTY.findall(text[:cut]):  # a restarted MCU: a new device
                point_link(pty_link(self.logs[i]), device.decode())
            duty = last_motors(text[:cut])
            if duty is not None and duty != self.duty[i]:
                self.duty[i] = duty
                self.publish(i)

    def on_republish(self) -> None:
        for i in range(len(self.pubs)):
            self.publish(i)

    def publish(self, i: int) -> None:
        msg = Twist()
        msg.linear.x, msg.angular.z = twist_from_wheels(*rim_speeds(*self.duty[i]))
        self.pubs[i].publish(msg)

    def destroy_node(self) -> None:
        for fh in self.files:
            fh.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    argv = list(sys.argv if args is None else args)
    end = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    logs = [Path(a) for a in argv[1:end]]
    missing = [str(p) for p in logs if not os.path.isfile(p)]
    if not logs or missing:
        print(f"{NODE}: error: logs: need existing files, missing {missing}", file=sys.stderr)
        return 2
    return run_node_process(NODE, argv[:1] + argv[end:], lambda: FirmwareLoopNode(logs))


if __name__ == "__main__":
    sys.exit(main())

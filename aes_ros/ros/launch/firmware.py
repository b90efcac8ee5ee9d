"""The firmware in the loop of ``aes-swarm launch --firmware sil`` (docs/firmware.md,
"Firmware in the loop in a launch").

The chain: robot node → ``cmd_vel`` → ``aes-mona-driver`` → Mona link bytes on a
pseudo-terminal → the real ``mona.elf`` in ``mona-sil`` (one per robot) → its PWM outputs
→ :mod:`aes_ros.ros.firmware_loop` → ``/mona_<i>/wheel_cmd`` → the bridge's wheels.

The bridge reads ``wheel_cmd`` through a remapping of its ``cmd_vel`` subscriptions
(:func:`with_firmware`), so it needs no mode of its own: what reaches its wheels is a
plain ``geometry_msgs/Twist``, the twist the MCU's motor outputs drive, and any ROS
tool can watch both ends of the firmware (``cmd_vel`` in, ``wheel_cmd`` out).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

from aes_ros.ros import interface as names
from aes_ros.ros.firmware_loop import WHEEL_CMD, point_link, pty_link
from aes_ros.ros.launch.commands import ProcessSpec, StartOrder
from aes_ros.ros.launch.processes import ProcessSet

#: Where ``make -C firmware`` puts ``mona.elf`` and ``mona-sil``.
BUILD = Path(__file__).resolve().parents[3] / "firmware" / "build"
BAUD = 115200
#: ``mona-sil``'s first line: its serial device follows.
PTY_LINE = "pty:"
MAX_ROBOTS = 255  # robot ids 0 … 254 (mona-sil's --robot-id)
#: The process name of robot ``i``'s MCU: ``mona_sil_<i>``.
MCU_PREFIX = "mona_sil_"


def ready_signal(name: str) -> str | None:
    """What the firmware-in-the-loop process ``name`` prints once it works (again): an MCU
    its serial device, the driver and ``firmware_loop`` their ready lines; None for any
    other process."""
    if name.startswith(MCU_PREFIX) and name[len(MCU_PREFIX) :].isdigit():
        return PTY_LINE
    return {
        names.MONA_DRIVER_NODE: names.MONA_DRIVER_READY,
        names.FIRMWARE_LOOP_NODE: names.FIRMWARE_LOOP_READY,
    }.get(name)


def missing_build(build: Path | None = None) -> str | None:
    """Why ``--firmware sil`` cannot run (None: it can); ``build``: default :data:`BUILD`."""
    build = BUILD if build is None else build
    missing = [p.name for p in (build / "mona-sil", build / "mona.elf") if not p.is_file()]
    if not missing:
        return None
    return f"{' and '.join(missing)} missing in {build}: build them with make -C firmware"


def mcu_commands(num_robots: int, build: Path = BUILD) -> list[ProcessSpec]:
    """One ``mona-sil`` per robot on the firmware ELF, robot id = robot index."""
    sil, elf = str(build / "mona-sil"), str(build / "mona.elf")
    return [
        ProcessSpec(f"{MCU_PREFIX}{i}", [sil, "--robot-id", str(i), elf]) for i in range(num_robots)
    ]


def bridge_remaps(num_robots: int) -> list[str]:
    """``-r`` rules that make the bridge take ``wheel_cmd`` where it took ``cmd_vel``."""
    out: list[str] = []
    for i in range(num_robots):
        out += ["-r", f"{names.robot_topic(i, names.CMD_VEL)}:={names.robot_topic(i, WHEEL_CMD)}"]
    return out


def with_firmware(order: StartOrder, num_robots: int) -> StartOrder:
    """``order`` with a bridge that takes each robot's ``wheel_cmd`` for its ``cmd_vel``."""
    bridge = order.bridge
    if bridge is None:  # a real arena: real firmware (refused by LaunchConfig)
        return order
    return order._replace(bridge=bridge._replace(argv=bridge.argv + bridge_remaps(num_robots)))


def driver_command(ptys: list[str]) -> ProcessSpec:
    """``aes-mona-driver`` with robot ``i`` on serial device ``ptys[i]``."""
    links = [arg for i, pty in enumerate(ptys) for arg in ("--link", f"{i}=serial:{pty}@{BAUD}")]
    return ProcessSpec(names.MONA_DRIVER_NODE, ["aes-mona-driver", *links])


def loop_command(logs: list[Path], python: str = sys.executable) -> ProcessSpec:
    """:mod:`aes_ros.ros.firmware_loop` on the MCUs' logs (robot ``i``: ``logs[i]``)."""
    return ProcessSpec(
        names.FIRMWARE_LOOP_NODE, [python, "-m", "aes_ros.ros.firmware_loop", *map(str, logs)]
    )


def start_firmware(
    procs: ProcessSet, num_robots: int, timeout: float, stopping: Callable[[], bool]
) -> list[ProcessSpec]:
    """Start the MCUs, then (once each has said its serial device) the driver and the
    loop that hands their motor outputs to the bridge; returns every spec started."""
    mcus = mcu_commands(num_robots)
    children = [procs.start(*spec) for spec in mcus]
    links = []
    for child in children:
        child.wait_for(PTY_LINE, timeout, stopping)
        # the driver opens a link that firmware_loop moves to a restarted MCU's device
        point_link(pty_link(child.log), child.line_after(PTY_LINE) or "")
        links.append(str(pty_link(child.log)))
    later = [driver_command(links), loop_command([c.log for c in children])]
    for spec in later:
        procs.start(*spec)
    return [*mcus, *later]

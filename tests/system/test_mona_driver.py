"""``aes-mona-driver`` against robot stand-ins (tests/helpers/mona_standin.py) over a
pseudo-terminal and UDP on loopback, seen through a real rclpy probe.

One driver serves the module: robot 0 on a pty, robot 1 on a pty that never says
HELLO, robot 2 on UDP. Commands become WHEELS of the right mm/s, telemetry becomes
topics and diagnostics, ``/swarm/enabled`` false stops every robot, every bad input
is counted and moves nothing, a device that disappears is reopened without a stale
command; SIGTERM and bad link strings get drivers of their own, and one more drives
the real firmware in simavr (skipped, with the reason, without the AVR toolchain).
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Twist
from helpers.firmware import ELF, SIL, build, toolchain_missing
from helpers.mona_standin import BATTERY_MV, IR_RAW, StandIn
from helpers.probe import Probe
from helpers.ros_env import TIMEOUT, Processes, reserved_domain_id, ros_variables, wait_for
from nav_msgs.msg import Odometry
from sensor_msgs.msg import BatteryState, Range
from std_msgs.msg import Bool

from aes_ros.mona import framing
from aes_ros.mona.geometry import MonaGeometry, wheels_from_twist
from aes_ros.mona.messages import Ping, Stop, Telemetry, Wheels
from aes_ros.mona.sensors import IrModel
from aes_ros.ros import interface as names
from aes_ros.ros.interface import robot_topic
from aes_ros.ros.qos import COMMAND, LATCHED, SENSOR

#: The WHEELS timeout the driver runs with [s] (its default).
TIMEOUT_S = 0.5


def twist(v: float, w: float) -> Twist:
    msg = Twist()
    msg.linear.x, msg.angular.z = v, w
    return msg


@dataclass
class Rig:
    """The module's driver, its robots and the probe's view of its topics."""

    procs: Processes
    driver: subprocess.Popen
    probe: Probe
    robots: dict[int, StandIn]
    diagnostics: list
    odom: list
    cmd: dict

    def log(self) -> str:
        return self.procs.log(self.driver).read_text()

    def status(self, name: str) -> tuple[int, dict[str, str], str]:
        """The newest (level, values, message) of a driver status (``mona_0``, ``udp``)."""
        for msg in reversed(self.diagnostics):
            for s in msg.status:
                if s.name == f"mona_driver: {name}":
                    return ord(s.level), {kv.key: kv.value for kv in s.values}, s.message
        return -1, {}, ""

    def wait_status(self, name: str, check, what: str) -> dict[str, str]:
        self.probe.wait(lambda: check(self.status(name)), TIMEOUT, what)
        return self.status(name)[1]

    def drive(self, robot: int, v: float, w: float) -> tuple[float, Wheels]:
        """Publish one cmd_vel; the time it went out and the WHEELS the robot got for it."""
        expected = Wheels(*wheels_from_twist(v, w), int(TIMEOUT_S * 1000))
        sent = time.monotonic()
        got = self.robots[robot].got
        # resent as a robot node does: the driver reads cmd_vel best-effort
        self.probe.until(lambda: self.cmd[robot].publish(twist(v, w)),
                         lambda: expected in got.of(Wheels, sent))  # fmt: skip
        return sent, expected


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    tmp = tmp_path_factory.mktemp("mona")
    with reserved_domain_id() as domain, pytest.MonkeyPatch.context() as env:
        for key, value in ros_variables(domain).items():
            env.setenv(key, value)
        robots = {
            0: StandIn(0, tmp / "mona0"),
            1: StandIn(1, tmp / "mona1", hello=False),
            2: StandIn(2, udp=True),
        }
        procs = Processes(dict(os.environ), tmp / "logs")
        probe = Probe("mona_probe")
        try:
            diagnostics = probe.record(DiagnosticArray, names.DIAGNOSTICS, LATCHED)
            odom = probe.record(Odometry, robot_topic(0, names.WHEEL_ODOM), SENSOR)
            links = [f"--link={robots[i].link()}" for i in robots]
            driver = procs.start(
                "aes-mona-driver", *links, "--ros-args", "-p", "hello_timeout:=1.5"
            )
            cmd = {
                i: probe.publisher(Twist, robot_topic(i, names.CMD_VEL), COMMAND) for i in robots
            }
            yield Rig(procs, driver, probe, robots, diagnostics, odom, cmd)
            assert driver.poll() is None, "the driver died:\n" + procs.logs()
        finally:
            probe.close()
            procs.stop_all()
            for robot in robots.values():
                robot.close()


def test_cmd_vel_reaches_each_robot_as_wheels_and_is_resent_until_its_timeout(rig: Rig) -> None:
    for robot, (v, w) in [(0, (0.05, 0.5)), (2, (0.02, -1.0)), (1, (1.0, 0.0))]:
        _, wheels = rig.drive(robot, v, w)
    assert wheels == Wheels(135, 135, 500)  # 1 m/s: clamped to the Mona's top speed
    sent, wheels = rig.drive(0, 0.03, 0.2)
    published = time.monotonic()  # the last cmd_vel went out before this
    time.sleep(3 * TIMEOUT_S)
    times = [t for t, m in rig.robots[0].got.messages if t >= sent and m == wheels]
    # resent while the command is younger than the timeout (every timeout/3: on average
    # well within timeout/2 even on a loaded machine), and never after, so the robot's
    # watchdog stops it (0.2 s: delivery and the stand-in's reading delay)
    assert len(times) >= 2 and np.mean(np.diff(times)) <= TIMEOUT_S / 2, times
    assert times[-1] < published + TIMEOUT_S + 0.2, (published, times)
    assert rig.robots[0].left == 0 and rig.robots[0].right == 0


def test_telemetry_reaches_odometry_ir_battery_and_diagnostics(rig: Rig) -> None:
    ir = [rig.probe.record(Range, robot_topic(0, f"{names.IR}_{k}"), SENSOR) for k in range(5)]
    battery = rig.probe.record(BatteryState, robot_topic(0, names.BATTERY), SENSOR)
    rig.drive(0, 0.05, 0.5)
    v, w = 1e-3 * (31 + 70) / 2, 1e-3 * (70 - 31) / 0.078
    rig.probe.wait(
        lambda: any(
            abs(m.twist.twist.linear.x - v) < 1e-6 and abs(m.twist.twist.angular.z - w) < 1e-6
            for m in list(rig.odom)
        ),
        TIMEOUT,
        "wheel_odom with the robot's wheel speeds",
    )
    rig.probe.wait(lambda: all(ir) and battery, TIMEOUT, "IR ranges and battery")
    model = IrModel()
    assert [r[-1].range for r in ir] == pytest.approx(list(model.range(IR_RAW)))
    assert ir[0][-1].header.frame_id == "mona_0/ir_0"
    assert battery[-1].voltage == pytest.approx(1e-3 * BATTERY_MV)
    odom = rig.odom[-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ("mona_0/odom", "mona_0/base_link")
    values = rig.wait_status("mona_0", lambda s: s[1].get("rtt_ms"), "a round-trip time")
    assert values["link"] == "up" and values["firmware"] == "1.0"
    assert values["hardware"] == "mona328" and values["frames_lost"] == "0"
    assert 0.0 < float(values["rtt_ms"]) < 1000.0
    assert rig.status("udp")[1]["port"] != "0"


def test_a_robot_that_never_says_hello_is_reported_and_still_driven(rig: Rig) -> None:
    rig.wait_status("mona_1", lambda s: "no HELLO" in s[2], "mona_1 reported without HELLO")
    level, values, _ = rig.status("mona_1")
    assert level == ord(DiagnosticStatus.WARN) and values["firmware"] == ""
    assert "no HELLO" in rig.log()
    rig.drive(1, 0.02, 0.0)  # commands still go out
    # and PINGs, once the wait for HELLO is over
    rig.probe.wait(lambda: rig.robots[1].got.of(Ping), TIMEOUT, "a PING to mona_1")


def test_swarm_disabled_stops_every_robot_and_sends_no_wheels_until_enabled(rig: Rig) -> None:
    enabled = rig.probe.publisher(Bool, names.ENABLED, LATCHED)
    rig.drive(0, 0.05, 0.0)
    before = time.monotonic()
    enabled.publish(Bool(data=False))
    for robot in rig.robots.values():
        rig.probe.wait(lambda r=robot: r.got.of(Stop, before), TIMEOUT, "STOP to every robot")
    stopped = time.monotonic()
    for _ in range(3):
        rig.cmd[0].publish(twist(0.05, 0.0))
        time.sleep(0.2)
    assert rig.robots[0].got.of(Wheels, stopped) == []
    enabled.publish(Bool(data=True))
    rig.probe.wait(lambda: "swarm enabled" in rig.log(), TIMEOUT, "the driver enabled")
    rig.drive(0, 0.04, 0.0)


def bad_telemetry_frames() -> dict[str, bytes]:
    """Frames of a TELEMETRY at 999 mm/s that fail each check."""
    body = Telemetry(0, 999, 999).body()
    good = bytearray(framing.HEADER.pack(1, Telemetry.TYPE, 7) + body)
    crc = framing.crc16(bytes(good)).to_bytes(2, "little")
    wrong_version = bytearray(good)
    wrong_version[0] = 2
    version_crc = framing.crc16(bytes(wrong_version)).to_bytes(2, "little")
    return {
        "crc": framing.cobs_encode(bytes(good) + bytes([crc[0] ^ 1, crc[1]])) + b"\x00",
        "version": framing.cobs_encode(bytes(wrong_version) + version_crc) + b"\x00",
        "length": framing.cobs_encode(bytes(good) + crc + bytes(range(1, 60))) + b"\x00",
        "cobs": b"\x09\x01\x82\x00",
        "body": framing.encode_frame(Telemetry.TYPE, 8, body[:-1]),
    }


def test_bad_frames_are_counted_warned_and_move_nothing(rig: Rig) -> None:
    robot = rig.robots[0]
    for wire in bad_telemetry_frames().values():
        robot.send_raw(wire)
    robot.send_raw(bytes(range(1, 200)) + b"\x00")  # garbage, longer than any frame
    rig.probe.until(
        lambda: rig.cmd[0].publish(twist(float("nan"), 0.0)),
        lambda: rig.status("mona_0")[1].get("bad_cmd_vel", "0") != "0",
    )
    values = rig.wait_status(
        "mona_0", lambda s: s[1].get("bad_body") == "1", "every bad frame counted"
    )
    assert values["crc_errors"] == "1" and values["bad_version"] == "1"
    assert values["bad_cobs"] == "1" and int(values["bad_length"]) == 2
    assert all(abs(m.twist.twist.linear.x) < 0.9 for m in rig.odom)  # no 999 mm/s ever
    log = rig.log()
    for kind in ("crc", "version", "length", "cobs", "body"):
        assert f"mona_0 bad frame ({kind})" in log
    assert "cmd_vel: a non-finite value" in log
    rig.drive(0, 0.01, 0.0)  # and the link still works


def test_udp_datagrams_from_strangers_are_dropped_and_counted(rig: Rig) -> None:
    robot = rig.robots[2]
    rig.probe.wait(lambda: robot._peer is not None, TIMEOUT, "the driver's UDP address")
    port = robot._peer[1]
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for seq in range(3):
            stranger.sendto(Telemetry(0, 999, 999).encode(seq), ("127.0.0.1", port))
    finally:
        stranger.close()
    values = rig.wait_status("udp", lambda s: s[1].get("strangers") == "3", "3 strangers")
    assert values["last_stranger"].startswith("127.0.0.1:")
    assert "not in the links" in rig.log()


def test_a_device_that_disappears_is_reopened_without_a_stale_command(rig: Rig) -> None:
    robot = rig.robots[0]
    rig.drive(0, 0.05, 0.3)
    robot.close_pty()
    rig.wait_status("mona_0", lambda s: s[1].get("link") == "down", "the link reported down")
    time.sleep(2 * TIMEOUT_S)  # the command grows older than its timeout
    reopened = time.monotonic()
    robot.reopen()
    rig.wait_status("mona_0", lambda s: s[1].get("reconnects") == "1", "a reconnect")
    rig.probe.wait(lambda: robot.got.of(Ping, reopened), TIMEOUT, "a PING after reopening")
    assert robot.got.of(Wheels, reopened) == []  # nothing stale
    assert "link of mona_0 down" in rig.log() and "reopened" in rig.log()
    rig.drive(0, 0.02, 0.0)


def test_sigterm_and_ctrl_c_send_stop_to_every_robot(spawn, tmp_path: Path) -> None:
    for sig in (signal.SIGTERM, signal.SIGINT):
        robots = [StandIn(0, tmp_path / f"m{sig}"), StandIn(1, udp=True)]
        try:
            driver = spawn.start(
                "aes-mona-driver", *(f"--link={r.link()}" for r in robots), name=f"driver{sig}"
            )
            assert wait_for(lambda robots=robots: all(r.got.of(Ping) for r in robots), TIMEOUT), (
                spawn.logs()
            )
            os.kill(driver.pid, sig)
            assert driver.wait(TIMEOUT) == 0
            assert wait_for(lambda robots=robots: all(r.got.of(Stop) for r in robots), TIMEOUT)
        finally:
            for robot in robots:
                robot.close()


def test_a_robot_that_says_another_id_gets_nothing_and_a_moved_link_is_followed(
    spawn, probe: Probe, tmp_path: Path
) -> None:
    """The device of link 3 leads to robot 9 (a stale or swapped device path): it gets no
    WHEELS, PING or STOP and is reported. Once the path leads to robot 3 (a restarted MCU,
    a ``by-id`` link after a replug) the driver follows it there and drives robot 3; when it
    leads to robot 8 next, the driver waits for its HELLO again and leaves it alone."""
    path = tmp_path / "mona3"
    robots = [StandIn(9, path)]
    try:
        driver = spawn.start(
            "aes-mona-driver", f"--link=3=serial:{path}@115200",
            "--ros-args", "-p", "hello_timeout:=2.5",
        )  # fmt: skip
        diagnostics = probe.record(DiagnosticArray, names.DIAGNOSTICS, LATCHED)
        cmd = probe.publisher(Twist, robot_topic(3, names.CMD_VEL), COMMAND)

        def status() -> tuple[int, str]:
            for msg in reversed(list(diagnostics)):
                for s in msg.status:
                    if s.name == "mona_driver: mona_3":
                        return ord(s.level), s.message
            return -1, ""

        def command_for(seconds: float) -> None:
            until = time.monotonic() + seconds
            while time.monotonic() < until:
                cmd.publish(twist(0.05, 0.5))
                time.sleep(0.05)

        probe.until(lambda: cmd.publish(twist(0.05, 0.5)),
                    lambda: "says it is 9" in status()[1])  # fmt: skip
        assert status() == (ord(DiagnosticStatus.ERROR), "the robot says it is 9: not driven")
        command_for(3.0)  # past hello_timeout, commands coming all along
        assert robots[0].got.messages == [], robots[0].got.messages
        assert "id mismatch" in spawn.log(driver).read_text()

        moved = time.monotonic()
        robots.append(StandIn(3, path))  # the path leads to robot 3; robot 9 stays open
        expected = Wheels(*wheels_from_twist(0.05, 0.5), int(TIMEOUT_S * 1000))
        probe.until(lambda: cmd.publish(twist(0.05, 0.5)),
                    lambda: expected in robots[1].got.of(Wheels, moved))  # fmt: skip
        assert "moved" in spawn.log(driver).read_text()

        robots.append(StandIn(8, path))  # and then to robot 8: robot 3's HELLO is not its
        command_for(4.0)  # the move seen (1 s), robot 8's HELLO, past hello_timeout
        os.kill(driver.pid, signal.SIGTERM)
        assert driver.wait(TIMEOUT) == 0
        for stranger in (robots[0], robots[2]):  # not even the STOP at the end
            assert stranger.got.messages == [], (stranger.robot_id, stranger.got.messages)
    finally:
        for r in robots:
            r.close()


@pytest.mark.parametrize(
    ("link", "reason"),
    [
        ("zero=serial:/dev/ttyUSB0", "robot ID"),
        ("0=usb:/dev/ttyUSB0", "expected ID=serial"),
        ("0=serial:/dev/ttyUSB0@1234", "baud '1234'"),
        ("0=udp:127.0.0.1:70000", "port '70000'"),
        ("0=serial:/nonexistent/tty@115200", "cannot open /nonexistent/tty"),
        ("0=serial:/dev/null", "not a serial device"),
    ],
)
def test_a_bad_link_exits_2_with_the_reason(link: str, reason: str) -> None:
    out = subprocess.run(
        [Path(sys.executable).with_name("aes-mona-driver"), "--link", link],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert out.returncode == 2 and reason in out.stderr, out.stderr


def motor_lines(log: Path) -> list[tuple[float, int, int]]:
    """``mona-sil``'s motor outputs: (simulated t, left, right duty)."""
    found = re.findall(r"^motors t=([\d.]+) left=(-?\d+) right=(-?\d+)$", log.read_text(), re.M)
    return [(float(t), int(a), int(b)) for t, a, b in found]


@pytest.mark.skipif(toolchain_missing() is not None, reason=str(toolchain_missing()))
def test_the_driver_drives_the_real_firmware_in_simavr(spawn, probe: Probe) -> None:
    """cmd_vel → driver → bytes → the firmware (tests/system/test_firmware.py checks it
    alone) → PWM; its TELEMETRY → wheel_odom; SIGTERM → STOP → motors off, well before
    the firmware's own watchdog (a 5 s WHEELS timeout) could have stopped them."""
    build()
    sil = spawn.start(str(SIL), "--robot-id", "0", str(ELF))
    log = spawn.log(sil)
    assert wait_for(lambda: "pty: " in log.read_text(), TIMEOUT), spawn.logs()
    pty = re.search(r"^pty: (\S+)$", log.read_text(), re.M).group(1)  # type: ignore[union-attr]
    driver = spawn.start(
        "aes-mona-driver", f"--link=0=serial:{pty}", "--ros-args", "-p", "timeout_ms:=5000"
    )
    odom = probe.record(Odometry, robot_topic(0, names.WHEEL_ODOM), SENSOR)
    cmd = probe.publisher(Twist, robot_topic(0, names.CMD_VEL), COMMAND)
    left, right = wheels_from_twist(0.05, 0.5)  # 31, 70 mm/s
    top = MonaGeometry().max_rim_speed_mm_s
    duty = (round(255 * left / top), round(255 * right / top))
    probe.until(lambda: cmd.publish(twist(0.05, 0.5)),
                lambda: any((a, b) == duty for _, a, b in motor_lines(log)))  # fmt: skip
    probe.wait(lambda: any(abs(m.twist.twist.linear.x - 1e-3 * (left + right) / 2) < 1e-6
                           for m in list(odom)), TIMEOUT, "wheel_odom of the firmware")  # fmt: skip
    assert "HELLO from 'mona328'" in spawn.log(driver).read_text()
    started = next(t for t, a, b in motor_lines(log) if (a, b) == duty)
    os.kill(driver.pid, signal.SIGTERM)
    assert driver.wait(TIMEOUT) == 0
    assert wait_for(lambda: motor_lines(log)[-1][1:] == (0, 0), TIMEOUT), motor_lines(log)
    assert motor_lines(log)[-1][0] - started < 5.0  # the STOP, not the watchdog

"""``aes-swarm launch --firmware sil``'s plan (no processes): the bridge's remapping, the
driver's links, the refusals, and the MCU's PWM read back as the speeds commanded."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest

from aes_ros import scenario
from aes_ros.mona.geometry import MonaGeometry, twist_from_wheels, wheels_from_twist
from aes_ros.ros import interface as names
from aes_ros.ros.firmware_loop import last_motors, point_link, pty_link, rim_speeds
from aes_ros.ros.launch import LaunchConfig
from aes_ros.ros.launch import firmware as fw
from aes_ros.ros.launch.commands import start_order
from aes_ros.ros.launch.events import EventLog, fault_summary
from aes_ros.ros.launch.processes import ProcessSet
from aes_ros.ros.launch.recovery import Backoff
from aes_ros.ros.launch.supervision import Supervision, ready_signal


def firmware_duty(rim_mm_s: int) -> int:
    """firmware/mona/motors.c: a clamped rim speed [mm/s] to its signed compare value."""
    top = 135
    speed = min(abs(rim_mm_s), top)
    duty = (speed * 255 + top // 2) // top
    return duty if rim_mm_s >= 0 else -duty


def config(**kw) -> LaunchConfig:
    return LaunchConfig(scenario.load("linear").with_robots(4), **kw)


def test_the_bridge_takes_wheel_cmd_for_cmd_vel(tmp_path: Path) -> None:
    cfg = config(firmware="sil")
    order = fw.with_firmware(start_order(cfg, tmp_path, tmp_path, tmp_path), 4)
    argv = order.bridge.argv
    assert argv[0] == "aes-sim-bridge"
    rules = [argv[k + 1] for k, a in enumerate(argv) if a == "-r"]
    assert rules == [f"/mona_{i}/cmd_vel:=/mona_{i}/wheel_cmd" for i in range(4)]


def test_each_robot_gets_its_own_mcu_and_link() -> None:
    mcus = fw.mcu_commands(3, Path("/b"))
    assert [m.argv for m in mcus] == [
        ["/b/mona-sil", "--robot-id", str(i), "/b/mona.elf"] for i in range(3)
    ]
    driver = fw.driver_command(["/dev/pts/7", "/dev/pts/2"])
    assert driver.argv == [
        "aes-mona-driver",
        "--link", "0=serial:/dev/pts/7@115200",
        "--link", "1=serial:/dev/pts/2@115200",
    ]  # fmt: skip


@pytest.mark.parametrize(
    ("kw", "reason"),
    [
        ({"lockstep": True}, "--lockstep"),
        ({"real_time_factor": 0.0}, "--real-time-factor 1"),
        ({"firmware": "hil"}, "allowed: none, sil"),
    ],
)
def test_firmware_sil_is_refused_where_it_cannot_run(kw: dict, reason: str) -> None:
    with pytest.raises(ValueError, match="firmware") as err:
        config(**{"firmware": "sil", **kw})
    assert reason in str(err.value)


def test_a_missing_build_names_make(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fw, "BUILD", tmp_path)
    with pytest.raises(ValueError, match=r"mona-sil and mona.elf missing .* make -C firmware"):
        config(firmware="sil")


@pytest.mark.parametrize(("v", "omega"), [(0.05, 0.0), (0.1, -1.0), (-0.03, 2.0), (0.2, 5.0)])
def test_the_pwm_read_back_is_the_twist_the_driver_sent(v: float, omega: float) -> None:
    left, right = wheels_from_twist(v, omega)
    duty = firmware_duty(left), firmware_duty(right)
    text = (
        f"pty: /dev/pts/1\nmotors t=0.5 left=0 right=0\nmotors t=1 left={duty[0]} right={duty[1]}\n"
    )
    back = rim_speeds(*last_motors(text.encode()))
    assert back == pytest.approx((left, right), abs=135 / 255)  # one step of duty
    v_back, omega_back = twist_from_wheels(*back)
    g = MonaGeometry()
    assert v_back == pytest.approx(twist_from_wheels(left, right)[0], abs=1e-3)
    assert abs(omega_back) <= g.max_angular_speed + 1e-9


def test_an_unfinished_line_is_not_read() -> None:
    assert last_motors(b"motors t=1.0 left=12 right=-3\nmotors t=1.1 left=9") == (12, -3)
    assert last_motors(b"stats t=1 wall=1\n") is None


def test_a_restarted_mcus_device_moves_the_drivers_link(tmp_path: Path) -> None:
    link = pty_link(tmp_path / "mona_sil_3.log")
    assert link == tmp_path / "mona_sil_3.pty"
    point_link(link, "/dev/pts/3")
    point_link(link, "/dev/pts/9")  # the same MCU, restarted on another device
    assert os.readlink(link) == "/dev/pts/9"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mona_sil_3.pty"]


def test_each_firmware_process_has_the_ready_line_it_prints() -> None:
    assert ready_signal("mona_sil_0") == ready_signal("mona_sil_12") == fw.PTY_LINE
    assert ready_signal("mona_driver") == names.MONA_DRIVER_READY
    assert ready_signal("firmware_loop") == names.FIRMWARE_LOOP_READY
    assert ready_signal("mona_sil_x") == ready_signal("robot_host_0") == names.ROBOTS_READY


def test_a_killed_mcu_restarted_by_the_launcher_counts_as_recovered(tmp_path: Path) -> None:
    """The launcher's own supervision restarts an MCU (firmware_loop only moves its
    driver's link); once the new one says its device, the summary counts it recovered."""
    procs = ProcessSet(tmp_path / "logs")
    # a stand-in that says what mona-sil says first: a real one needs the toolchain
    mcu = [
        sys.executable,
        "-c",
        "import time; print('pty: /dev/pts/99', flush=True); time.sleep(60)",
    ]
    child = procs.start("mona_sil_3", mcu)
    said: list[str] = []
    events = EventLog(tmp_path / "events.csv", said.append)
    watch = Supervision(procs, events, "respawn", lambda name: mcu, lambda: 1.0,
                        backoff=Backoff(first=0.05))  # fmt: skip
    try:
        child.wait_for(fw.PTY_LINE, 20.0)
        os.kill(child.proc.pid, signal.SIGKILL)
        child.proc.wait(20.0)
        deadline = time.monotonic() + 20.0
        while events.counts["recovered"] == 0 and time.monotonic() < deadline:
            watch.check()
            time.sleep(0.02)
    finally:
        procs.stop(procs.children, 5.0)  # no rclpy here: no shared memory to clean
    assert [e.event for e in events.events] == ["died", "restarted", "recovered"], said
    assert fault_summary(events.events, watch.given_up).startswith(
        "1 fault (mona_sil_3 1×), 1 recovered"
    )

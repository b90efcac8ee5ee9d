"""The Mona firmware (firmware/mona) on a simulated ATmega328P (firmware/sil, libsimavr).

Each test boots the real firmware ELF in ``mona-sil``, speaks the Mona link v1 on its
pseudo-terminal with :mod:`aes_ros.mona`, and reads the motor outputs (PWM compare
values and direction pins) that ``mona-sil`` reports. Times of motor changes are the
simulated MCU's own (``t=`` of the ``motors`` lines), so the watchdog checks do not
depend on how busy this machine is; only the TELEMETRY rate is judged on the wall clock.
Skipped, with the reason, where avr-gcc or libsimavr is missing (scripts/setup.sh
installs both).
"""

from __future__ import annotations

import itertools
import os
import queue
import select
import subprocess
import termios
import threading
import time
import tty
from collections.abc import Iterator

import pytest
from helpers.firmware import ELF, SIL, build, toolchain_missing

from aes_ros.mona.framing import CRC, FrameReader, ProtocolError, cobs_encode, crc16
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.mona.messages import (
    BATTERY_LOW,
    STOPPED_BY_STOP,
    STOPPED_BY_TIMEOUT,
    Hello,
    Message,
    Ping,
    Pong,
    Stop,
    Telemetry,
    Wheels,
    decode,
)

TOP_MM_S = MonaGeometry().max_rim_speed_mm_s


pytestmark = pytest.mark.skipif(toolchain_missing() is not None, reason=str(toolchain_missing()))


@pytest.fixture(scope="module")
def built() -> None:
    """``make -C firmware`` once."""
    build()


def duty(mm_s: int) -> int:
    """The signed PWM compare value the firmware must set for a rim speed [mm/s]."""
    speed = min(abs(mm_s), TOP_MM_S)
    value = (speed * 255 + TOP_MM_S // 2) // TOP_MM_S
    return -value if mm_s < 0 else value


class Mcu:
    """One ``mona-sil`` process: its pty as a serial line, its motor lines in a queue."""

    def __init__(self, robot_id: int = 0) -> None:
        self.proc = subprocess.Popen(
            [str(SIL), "--robot-id", str(robot_id), "--stats", "0", str(ELF)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert self.proc.stdout is not None
        first = self.proc.stdout.readline().split()
        assert first[:1] == ["pty:"], first
        self.fd = os.open(first[1], os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd, termios.TCSANOW)  # TCSAFLUSH would drop the boot HELLO
        self.reader = FrameReader()
        self.seq = 0
        self.motors: queue.Queue[tuple[float, int, int]] = queue.Queue()
        self._thread = threading.Thread(target=self._read_stdout, daemon=True)
        self._thread.start()

    def _read_stdout(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            if line.startswith("motors "):
                fields = dict(part.split("=") for part in line.split()[1:])
                self.motors.put((float(fields["t"]), int(fields["left"]), int(fields["right"])))

    def send(self, message: Message) -> int:
        self.seq += 1
        os.write(self.fd, message.encode(self.seq))
        return self.seq

    def send_raw(self, data: bytes) -> None:
        os.write(self.fd, data)

    def frames(self, seconds: float) -> Iterator[tuple[float, int, Message | ProtocolError]]:
        """(wall time, seq, message or protocol error) of what arrives within ``seconds``."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            if not select.select([self.fd], [], [], left)[0]:
                continue
            data = os.read(self.fd, 4096)
            now = time.monotonic()
            for item in list(self.reader.feed(data)):  # whole: the caller may stop early
                if isinstance(item, ProtocolError):
                    yield now, -1, item
                else:
                    yield now, item.seq, decode(item)

    def wait_for(self, kind: type[Message], seconds: float = 2.0, **fields: int) -> Message:
        """The first message of ``kind`` whose fields equal ``fields``."""
        for _, _, message in self.frames(seconds):
            if isinstance(message, kind) and all(
                getattr(message, k) == v for k, v in fields.items()
            ):
                return message
        raise AssertionError(f"no {kind.__name__} {fields} within {seconds} s")

    def next_motors(self, timeout: float = 2.0) -> tuple[float, int, int]:
        """The next change of the motor outputs: (simulated t [s], left, right)."""
        try:
            return self.motors.get(timeout=timeout)
        except queue.Empty:
            raise AssertionError(f"no motor change within {timeout} s") from None

    def close(self) -> None:
        os.close(self.fd)
        self.proc.terminate()
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._thread.join(timeout=5)
        for pipe in (self.proc.stdin, self.proc.stdout):
            if pipe is not None:
                pipe.close()


@pytest.fixture
def mcu(built: None) -> Iterator[Mcu]:
    m = Mcu(robot_id=7)
    try:
        yield m
    finally:
        m.close()
    assert m.proc.returncode == 0, "mona-sil did not end cleanly on SIGTERM"


def test_hello_every_second_until_a_frame_then_telemetry_at_20_hz(mcu: Mcu) -> None:
    got = list(mcu.frames(2.3))
    hellos = [(t, m) for t, _, m in got if isinstance(m, Hello)]
    assert len(hellos) == 3, hellos  # at boot, 1 s, 2 s
    assert all(m == Hello(robot_id=7, fw_major=1, fw_minor=0, hw="mona328") for _, m in hellos)
    gaps = [b[0] - a[0] for a, b in itertools.pairwise(hellos)]
    assert all(0.8 < g < 1.2 for g in gaps), gaps

    seq = mcu.send(Ping())
    mcu.wait_for(Pong, ack_seq=seq)
    after = list(mcu.frames(2.0))
    assert not [m for _, _, m in after if isinstance(m, Hello)], "HELLO after a valid frame"
    telemetry = [m for _, _, m in after if isinstance(m, Telemetry)]
    assert 36 <= len(telemetry) <= 44, f"{len(telemetry)} TELEMETRY in 2 s (20 Hz ± 10 %)"
    assert not [m for _, _, m in after if isinstance(m, ProtocolError)]
    # every frame the robot sends takes the next seq: none lost on a pty
    for window in (got, after):
        seqs = [s for _, s, _ in window]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    t = telemetry[-1]
    assert t.ir == (1023,) * 5  # the original Mona's IR read 1023 when nothing is seen
    assert abs(t.battery_mv - 3900) <= 20 and not t.flags & BATTERY_LOW  # mona-sil's default


def test_ir_and_battery_inputs_reach_telemetry(mcu: Mcu) -> None:
    assert mcu.proc.stdin is not None
    mcu.proc.stdin.write("ir 100 200 300 400 500\nbattery 3300\n")
    mcu.proc.stdin.flush()
    t = mcu.wait_for(Telemetry, ir=(100, 200, 300, 400, 500))
    assert isinstance(t, Telemetry)
    assert abs(t.battery_mv - 3300) <= 20 and t.flags & BATTERY_LOW


@pytest.mark.parametrize(
    ("left", "right"), [(67, -135), (-40, 100), (500, -500), (0, 1)]
)  # both signs, both wheels; beyond the top speed is clamped
def test_wheels_sets_duty_cycles_and_directions(mcu: Mcu, left: int, right: int) -> None:
    seq = mcu.send(Wheels(left, right, 1000))
    _, pwm_left, pwm_right = mcu.next_motors()
    assert (pwm_left, pwm_right) == (duty(left), duty(right))
    clamp = max(-TOP_MM_S, min(TOP_MM_S, left)), max(-TOP_MM_S, min(TOP_MM_S, right))
    mcu.wait_for(Telemetry, ack_seq=seq, left=clamp[0], right=clamp[1], flags=0)


def test_watchdog_stops_the_motors_after_the_timeout(mcu: Mcu) -> None:
    mcu.send(Wheels(100, -100, 300))
    t_on, *on = mcu.next_motors()
    t_off, *off = mcu.next_motors()
    assert on == [duty(100), duty(-100)] and off == [0, 0]
    # simulated time: the 1 ms tick, less the time the MCU takes to check the frame
    # before it sets the PWM (the watchdog counts from its arrival; ~0.1 ms at 8 MHz)
    assert 0.298 <= t_off - t_on < 0.305, t_off - t_on
    mcu.wait_for(Telemetry, left=0, right=0, flags=STOPPED_BY_TIMEOUT)

    # WHEELS resent within the timeout keep the motors running past it
    mcu.send(Wheels(60, 60, 1000))
    t_on, *on = mcu.next_motors()
    for _ in range(15):
        time.sleep(0.1)
        mcu.send(Wheels(60, 60, 1000))
    assert mcu.motors.empty(), f"stopped while WHEELS kept coming: {mcu.motors.get()}"
    t_off, *off = mcu.next_motors(timeout=3.0)
    assert on == [duty(60), duty(60)] and off == [0, 0]
    assert t_off - t_on > 1.5 + 1.0 - 0.1  # the last WHEELS' timeout, from ~1.5 s


def test_stop_stops_the_motors(mcu: Mcu) -> None:
    mcu.send(Wheels(-120, 80, 5000))
    assert mcu.next_motors()[1:] == (duty(-120), duty(80))
    t_wheels = time.monotonic()
    seq = mcu.send(Stop())
    assert mcu.next_motors()[1:] == (0, 0)
    assert time.monotonic() - t_wheels < 4.0  # the STOP, long before the 5 s timeout
    mcu.wait_for(Telemetry, ack_seq=seq, left=0, right=0, flags=STOPPED_BY_STOP)


def _frame(payload: bytes) -> bytes:
    return cobs_encode(payload) + b"\x00"


def _payload(version: int, type_: int, seq: int, body: bytes) -> bytes:
    head = bytes([version, type_]) + seq.to_bytes(2, "little") + body
    return head + CRC.pack(crc16(head))


BODY = Wheels(100, 100, 1000).body()
BAD_FRAMES = {
    "wrong crc": _frame(_payload(1, 0x01, 1, BODY)[:-1] + b"\x55"),
    "wrong version": _frame(_payload(2, 0x01, 2, BODY)),
    "oversize": _frame(_payload(1, 0x01, 3, BODY + bytes(range(1, 70)))),
    "oversize without delimiter": bytes(range(1, 200)) + b"\x00",
    "wrong body length": _frame(_payload(1, 0x01, 4, BODY[:-1])),
    "unknown type": _frame(_payload(1, 0x7F, 5, BODY)),
    "a robot's message": _frame(_payload(1, 0x82, 6, bytes(21))),
    "broken COBS": b"\x05\x01\x01\x00",
    "too short": _frame(b"\x01\x01"),
}


def test_bad_frames_move_nothing(mcu: Mcu) -> None:
    for data in BAD_FRAMES.values():
        mcu.send_raw(data)
    got = list(mcu.frames(1.5))
    assert mcu.motors.empty(), f"a bad frame moved a wheel: {mcu.motors.get()}"
    assert all(isinstance(m, Hello | Telemetry) for _, _, m in got)
    telemetry = [m for _, _, m in got if isinstance(m, Telemetry)]
    assert telemetry and all(m.left == m.right == 0 and m.ack_seq == 0 for m in telemetry)
    # none of them counted as a valid frame: HELLO goes on
    assert any(isinstance(m, Hello) for _, _, m in got)
    # and the line still works
    mcu.send(Wheels(50, 50, 1000))
    assert mcu.next_motors()[1:] == (duty(50), duty(50))

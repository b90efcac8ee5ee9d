"""A Mona robot stand-in that speaks the Mona link v1 (docs/mona_protocol.md) in a thread.

On a pseudo-terminal (``os.openpty``; the driver opens the slave through a symlink
that :meth:`StandIn.reopen` points at a new terminal, as a USB adapter that is
unplugged and plugged in again) or on UDP over loopback. Like the firmware it sends
HELLO at start and every second until its first valid frame, TELEMETRY at 20 Hz and
after every WHEELS, PONG for PING; it applies WHEELS until their timeout (the
watchdog) and STOP at once, and records every message and protocol error it gets.
:meth:`StandIn.send_raw` sends any bytes on demand (the bad-input tests).
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading
import time
import tty
from dataclasses import dataclass, field
from pathlib import Path

from aes_ros.mona import messages
from aes_ros.mona.framing import FrameReader, ProtocolError
from aes_ros.mona.messages import (
    STOPPED_BY_STOP,
    STOPPED_BY_TIMEOUT,
    Hello,
    Message,
    Ping,
    Pong,
    Stop,
    Telemetry,
    Wheels,
)

#: TELEMETRY rate [Hz] and HELLO period [s] of the firmware (docs/mona_protocol.md).
TELEMETRY_HZ = 20.0
HELLO_PERIOD = 1.0
#: IR readings and battery [mV] the stand-in reports.
IR_RAW = (60, 150, 1023, 0, 300)
BATTERY_MV = 3900


@dataclass
class Received:
    """What the stand-in got: (monotonic time, message) and the bad frames."""

    messages: list[tuple[float, Message]] = field(default_factory=list)
    errors: list[ProtocolError] = field(default_factory=list)

    def of(self, kind: type, since: float = 0.0) -> list[Message]:
        return [m for t, m in list(self.messages) if isinstance(m, kind) and t >= since]


class StandIn:
    """Robot ``robot_id`` on a pty (``link_path`` becomes its symlink) or, with
    ``udp=True``, on a UDP socket of 127.0.0.1. ``hello=False``: a robot that never
    says HELLO."""

    def __init__(
        self, robot_id: int, link_path: Path | None = None, *, udp: bool = False,
        hello: bool = True,
    ) -> None:  # fmt: skip
        self.robot_id = robot_id
        self.link_path = link_path
        self.udp = udp
        self.hello = hello
        self.got = Received()
        self.left = self.right = 0  #: applied wheel speeds [mm/s]
        self.flags = 0
        self.ack_seq = 0
        self.seq = 0
        self._until = 0.0  #: the watchdog's deadline
        self._heard = False  #: a valid frame came (HELLO stops)
        self._peer: tuple[str, int] | None = None
        self._lock = threading.Lock()
        self._reader = FrameReader()
        self._master = self._slave = -1
        self.sock: socket.socket | None = None
        if udp:
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.bind(("127.0.0.1", 0))
        else:
            self._open_pty()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"mona-{robot_id}", daemon=True)
        self._thread.start()

    # ----------------------------------------------------------------- set-up

    def link(self) -> str:
        """The driver's ``--link`` string for this robot."""
        if self.sock is not None:
            return f"{self.robot_id}=udp:127.0.0.1:{self.sock.getsockname()[1]}"
        return f"{self.robot_id}=serial:{self.link_path}@115200"

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo of our own bytes before the driver sets it raw
        os.set_blocking(master, False)
        tmp = Path(f"{self.link_path}.new")
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(os.ttyname(slave))
        tmp.replace(self.link_path)  # type: ignore[arg-type]
        with self._lock:
            self._master, self._slave = master, slave
            self._reader = FrameReader()

    def close_pty(self) -> None:
        """The device disappears: the terminal closes and its path goes away."""
        with self._lock:
            master, slave, self._master, self._slave = self._master, self._slave, -1, -1
        Path(self.link_path).unlink(missing_ok=True)  # type: ignore[arg-type]
        for fd in (master, slave):
            with contextlib.suppress(OSError):
                os.close(fd)

    def reopen(self) -> None:
        """The device comes back (a new terminal at the same path)."""
        self._open_pty()

    # ----------------------------------------------------------------- sending

    def send_raw(self, data: bytes) -> None:
        """Send bytes as they are (bad input on demand)."""
        with self._lock:
            if self.sock is not None:
                if self._peer is not None:
                    self.sock.sendto(data, self._peer)
            elif self._master >= 0:
                with contextlib.suppress(OSError):
                    os.write(self._master, data)

    def send(self, msg: Message) -> None:
        with self._lock:
            seq, self.seq = self.seq, (self.seq + 1) & 0xFFFF
        self.send_raw(msg.encode(seq))

    def telemetry(self) -> Telemetry:
        return Telemetry(self.ack_seq, self.left, self.right, IR_RAW, BATTERY_MV, self.flags)

    # ----------------------------------------------------------------- the robot

    def _run(self) -> None:
        next_telemetry = next_hello = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if (self.left or self.right) and now >= self._until:
                self.left = self.right = 0
                self.flags |= STOPPED_BY_TIMEOUT
            # over UDP the boot HELLO waits for a peer: it goes to the first host that
            # sends a frame (docs/mona_protocol.md, "UDP")
            if self.hello and not self._heard and now >= next_hello and self.sock is None:
                next_hello = now + HELLO_PERIOD
                self.send(Hello(self.robot_id, 1, 0, "mona328"))
            if now >= next_telemetry:
                next_telemetry += 1.0 / TELEMETRY_HZ
                if now - next_telemetry > 1.0:  # the thread was held up: no burst
                    next_telemetry = now
                if self._heard:
                    self.send(self.telemetry())
            for data in self._read(max(0.0, min(next_telemetry, next_hello) - now)):
                self._on_bytes(data, time.monotonic())

    def _read(self, timeout: float) -> list[bytes]:
        if self.sock is not None:
            ready, _, _ = select.select([self.sock], [], [], min(timeout, 0.02))
            if not ready:
                return []
            data, peer = self.sock.recvfrom(2048)
            self._peer = peer
            return [data if data.endswith(b"\x00") else data + b"\x00"]
        master = self._master
        if master < 0:
            time.sleep(min(timeout, 0.02))
            return []
        try:
            ready, _, _ = select.select([master], [], [], min(timeout, 0.02))
            return [os.read(master, 4096)] if ready else []
        except OSError:  # closed under us by close_pty
            return []

    def _on_bytes(self, data: bytes, now: float) -> None:
        for item in self._reader.feed(data):
            if isinstance(item, ProtocolError):
                self.got.errors.append(item)
                continue
            try:
                msg = messages.decode(item, messages.HOST_TO_ROBOT)
            except ProtocolError as exc:
                self.got.errors.append(exc)
                continue
            if self.sock is not None and self.hello and not self._heard:
                self.send(Hello(self.robot_id, 1, 0, "mona328"))
            self._heard = True
            self.got.messages.append((now, msg))
            if isinstance(msg, Wheels):
                self.ack_seq = item.seq
                self.left, self.right = msg.left, msg.right
                self._until = now + 1e-3 * msg.timeout_ms
                self.flags &= ~(STOPPED_BY_TIMEOUT | STOPPED_BY_STOP)
                self.send(self.telemetry())
            elif isinstance(msg, Stop):
                self.ack_seq = item.seq
                self.left = self.right = 0
                self.flags |= STOPPED_BY_STOP
            elif isinstance(msg, Ping):
                self.send(Pong(item.seq))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        if self.sock is not None:
            self.sock.close()
        else:
            self.close_pty()

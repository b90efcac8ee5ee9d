"""One robot's end of the Mona link in the driver, without ROS.

A :class:`RobotLink` owns a transport, numbers the frames it sends, checks and
decodes what arrives (a bad frame is counted by kind and never acted on), keeps the
robot's last command with its age, measures the round-trip time from PING/PONG and
reopens a serial line that dropped with an exponential backoff. Times are
``time.monotonic()`` seconds, passed in so that the node decides when things happen.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

from aes_ros.mona import messages
from aes_ros.mona.framing import ERROR_KINDS, Frame, FrameReader, ProtocolError
from aes_ros.mona.messages import Hello, Message, Ping, Pong, SeqCounter, Stop, Wheels
from mona_driver.links import LinkSpec

#: First and longest wait before reopening a link that dropped [s].
BACKOFF_FIRST = 0.1
BACKOFF_MAX = 2.0
#: PINGs remembered for their PONG (older ones count as unanswered).
PINGS_KEPT = 8


class Transport(Protocol):
    is_open: bool

    def open(self) -> None: ...

    def close(self) -> None: ...

    def write(self, data: bytes) -> None: ...


@dataclass
class LinkStats:
    """What :mod:`mona_driver.diagnostics` reports of one link."""

    frames: int = 0  #: valid frames received
    bad: dict[str, int] = field(default_factory=lambda: dict.fromkeys(ERROR_KINDS, 0))
    drops: int = 0  #: times the link went down
    reconnects: int = 0
    wheels: int = 0  #: WHEELS sent
    stops: int = 0  #: STOPs sent
    bad_commands: int = 0  #: cmd_vel messages refused (non-finite)
    rtt: float | None = None  #: last round-trip time [s]
    last_error: str = ""  #: why the link last went down or could not open


class RobotLink:
    """The link to robot ``spec.robot_id`` over ``transport``."""

    def __init__(self, spec: LinkSpec, transport: Transport) -> None:
        self.spec = spec
        self.robot_id = spec.robot_id
        self.transport = transport
        self.reader = FrameReader()
        self.seq = 0  #: the next frame's seq
        self.received = SeqCounter()
        self.stats = LinkStats()
        self.hello: Hello | None = None
        self.opened_at: float | None = None  #: when the link (re)opened
        self.last_frame_at: float | None = None  #: when the last valid frame came
        self.retry_at = 0.0
        self._backoff = BACKOFF_FIRST
        self.command: Wheels | None = None  #: the last cmd_vel as wheel speeds
        self.command_at = -1e9  #: when that cmd_vel came
        self.wheels_sent_at = -1e9
        self._pings: dict[int, float] = {}

    # ----------------------------------------------------------------- opening

    def open(self, now: float) -> str | None:
        """Open the transport; None if it opened, else why not (a retry is scheduled)."""
        try:
            self.transport.open()
        except OSError as exc:
            self.stats.last_error = f"cannot open {self.spec.device}: {exc.strerror or exc}"
            self.retry_at = now + self._backoff
            self._backoff = min(2.0 * self._backoff, BACKOFF_MAX)
            return self.stats.last_error
        self.reader = FrameReader()
        self.received.reset()
        self.hello = None  # a reopened device may be another robot: it says HELLO anew
        self.opened_at = now
        self._backoff = BACKOFF_FIRST
        return None

    def drop(self, reason: str, now: float) -> None:
        """The link failed: close it and schedule a reopen."""
        self.transport.close()
        self.stats.drops += 1
        self.stats.last_error = reason
        self.opened_at = None
        self.last_frame_at = None
        self.retry_at = now + self._backoff

    # ----------------------------------------------------------------- sending

    def send(self, msg: Message, now: float) -> str | None:
        """Send one frame; None if it went out, else why not (the link is dropped)."""
        if not self.transport.is_open:
            return "the link is down"
        try:
            self.transport.write(msg.encode(self.seq))
        except OSError as exc:
            reason = f"cannot write: {exc.strerror or exc}"
            self.drop(reason, now)
            return reason
        if isinstance(msg, Ping):
            self._pings[self.seq] = now
            while len(self._pings) > PINGS_KEPT:
                self._pings.pop(next(iter(self._pings)))
        elif isinstance(msg, Wheels):
            self.stats.wheels += 1
            self.wheels_sent_at = now
        elif isinstance(msg, Stop):
            self.stats.stops += 1
        self.seq = (self.seq + 1) & 0xFFFF
        return None

    def fresh_command(self, now: float, timeout: float) -> Wheels | None:
        """The last command if it is younger than ``timeout`` s (else None: never resent)."""
        if self.command is not None and now - self.command_at < timeout:
            return self.command
        return None

    # ----------------------------------------------------------------- receiving

    def receive(self, data: bytes, now: float) -> tuple[list[Message], list[ProtocolError]]:
        """The messages and the errors of ``data`` (bytes as they came)."""
        got: list[Message] = []
        errors: list[ProtocolError] = []
        for item in self.reader.feed(data):
            try:
                if isinstance(item, ProtocolError):
                    raise item
                got.append(self._accept(item, now))
            except ProtocolError as exc:
                self.stats.bad[exc.kind] = self.stats.bad.get(exc.kind, 0) + 1
                errors.append(exc)
        return got, errors

    def _accept(self, frame: Frame, now: float) -> Message:
        msg = messages.decode(frame, messages.ROBOT_TO_HOST)
        if isinstance(msg, Hello):
            self.hello = msg
            self.received.reset()  # a robot that booted counts from 0 again
        self.received.see(frame.seq)
        self.stats.frames += 1
        self.last_frame_at = now
        if isinstance(msg, Pong) and msg.ack_seq in self._pings:
            self.stats.rtt = now - self._pings.pop(msg.ack_seq)
        return msg

    def other_robot(self) -> int | None:
        """The robot id this link's robot said in its HELLO if it is not the link's
        (None: the link's, or no HELLO yet)."""
        if self.hello is not None and self.hello.robot_id != self.robot_id:
            return self.hello.robot_id
        return None

    def awaits_hello(self, now: float, hello_after: float) -> bool:
        """A serial link opened less than ``hello_after`` s ago whose robot has not said
        HELLO yet (a UDP robot learns the driver's address from its first frame, so the
        driver speaks first there)."""
        return (
            self.spec.kind == "serial"
            and self.hello is None
            and self.opened_at is not None
            and now - self.opened_at < hello_after
        )

    def is_up(self, now: float, silent_after: float) -> bool:
        """Open, and a valid frame came within ``silent_after`` s."""
        return (
            self.transport.is_open
            and self.last_frame_at is not None
            and now - self.last_frame_at < silent_after
        )

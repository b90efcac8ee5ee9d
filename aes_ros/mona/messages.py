"""The messages of the Mona link v1 (docs/mona_protocol.md) and the counting of lost frames.

Each message type is a frozen dataclass with its ``TYPE`` code, its body's ``BODY``
struct (little-endian), :meth:`~Message.encode` (the frame on the wire, given a
``seq``) and the class method ``decode`` (a frame's body back into the message).
:func:`decode` turns any checked :class:`~aes_ros.mona.framing.Frame` into its message,
raising :class:`~aes_ros.mona.framing.UnknownTypeError` or
:class:`~aes_ros.mona.framing.BodyLengthError` for a frame that is no message here.
"""

from __future__ import annotations

import struct
from dataclasses import astuple, dataclass, field
from typing import ClassVar

from aes_ros.mona.framing import BodyLengthError, Frame, UnknownTypeError, encode_frame

#: TELEMETRY ``flags`` bits.
STOPPED_BY_TIMEOUT = 0x01
STOPPED_BY_STOP = 0x02
BATTERY_LOW = 0x04
#: IR sensors of a Mona, in TELEMETRY's order: their bearings [deg], CCW from ahead.
IR_BEARINGS_DEG = (0.0, 37.0, -37.0, 67.0, -67.0)
#: Length of HELLO's hardware name [bytes].
HW_LENGTH = 8


@dataclass(frozen=True)
class Message:
    """Base of the message types: a body of fields packed by ``BODY``."""

    TYPE: ClassVar[int]
    BODY: ClassVar[struct.Struct] = struct.Struct("<")

    def body(self) -> bytes:
        return self.BODY.pack(*astuple(self))

    def encode(self, seq: int) -> bytes:
        """The frame on the wire: COBS(payload) then ``0x00``."""
        return encode_frame(self.TYPE, seq, self.body())

    @classmethod
    def decode(cls, body: bytes) -> Message:
        """The message of a frame's body; :class:`BodyLengthError` if its length is wrong."""
        if len(body) != cls.BODY.size:
            raise BodyLengthError(
                f"body: {cls.__name__.upper()} of {len(body)} bytes (must be {cls.BODY.size})"
            )
        return cls(*cls.BODY.unpack(body))


# ------------------------------------------------------------------------ host → robot


@dataclass(frozen=True)
class Wheels(Message):
    """Drive: wheel rim speeds ``left``, ``right`` [mm/s] until ``timeout_ms`` passes."""

    TYPE: ClassVar[int] = 0x01
    BODY: ClassVar[struct.Struct] = struct.Struct("<hhH")
    left: int
    right: int
    timeout_ms: int


@dataclass(frozen=True)
class Stop(Message):
    """Motors off now."""

    TYPE: ClassVar[int] = 0x02


@dataclass(frozen=True)
class Ping(Message):
    """Ask for a PONG (the round-trip time)."""

    TYPE: ClassVar[int] = 0x03


# ------------------------------------------------------------------------ robot → host


@dataclass(frozen=True)
class Hello(Message):
    """The robot's id, firmware version and hardware (``mona328``, ``monaesp``)."""

    TYPE: ClassVar[int] = 0x81
    BODY: ClassVar[struct.Struct] = struct.Struct(f"<BBB{HW_LENGTH}s")
    robot_id: int
    fw_major: int
    fw_minor: int
    hw: str

    def body(self) -> bytes:
        return self.BODY.pack(self.robot_id, self.fw_major, self.fw_minor, self.hw.encode())

    @classmethod
    def decode(cls, body: bytes) -> Hello:
        raw = super().decode(body)
        # ASCII, zero-padded; anything else is shown escaped rather than refused
        hw = raw.hw.rstrip(b"\x00").decode("ascii", "backslashreplace")  # type: ignore[union-attr]
        return cls(raw.robot_id, raw.fw_major, raw.fw_minor, hw)


@dataclass(frozen=True)
class Telemetry(Message):
    """What the robot applied and measured: wheel rim speeds [mm/s], raw IR ADC readings
    (sensor order of :data:`IR_BEARINGS_DEG`), battery [mV], ``flags``."""

    TYPE: ClassVar[int] = 0x82
    BODY: ClassVar[struct.Struct] = struct.Struct("<Hhh5HHB")
    ack_seq: int
    left: int
    right: int
    ir: tuple[int, int, int, int, int] = field(default=(0, 0, 0, 0, 0))
    battery_mv: int = 0
    flags: int = 0

    def body(self) -> bytes:
        return self.BODY.pack(
            self.ack_seq, self.left, self.right, *self.ir, self.battery_mv, self.flags
        )

    @classmethod
    def decode(cls, body: bytes) -> Telemetry:
        if len(body) != cls.BODY.size:
            raise BodyLengthError(f"body: TELEMETRY of {len(body)} bytes (must be {cls.BODY.size})")
        ack, left, right, *rest = cls.BODY.unpack(body)
        return cls(ack, left, right, tuple(rest[:5]), rest[5], rest[6])  # type: ignore[arg-type]


@dataclass(frozen=True)
class Pong(Message):
    """The answer to the PING of sequence number ``ack_seq``."""

    TYPE: ClassVar[int] = 0x83
    BODY: ClassVar[struct.Struct] = struct.Struct("<H")
    ack_seq: int


#: The message types each side sends.
HOST_TO_ROBOT: dict[int, type[Message]] = {m.TYPE: m for m in (Wheels, Stop, Ping)}
ROBOT_TO_HOST: dict[int, type[Message]] = {m.TYPE: m for m in (Hello, Telemetry, Pong)}


def decode(frame: Frame, accept: dict[int, type[Message]] | None = None) -> Message:
    """The message of a checked frame, of one of the types ``accept`` (default: all)."""
    types = {**HOST_TO_ROBOT, **ROBOT_TO_HOST} if accept is None else accept
    kind = types.get(frame.type)
    if kind is None:
        raise UnknownTypeError(f"type: 0x{frame.type:02X} is no message this side accepts")
    return kind.decode(frame.body)


class SeqCounter:
    """Frames lost, from the gaps in a sender's ``seq`` (one counter over all its frames).

    A step back, or forward by half the range or more, is a restart of the sender (or
    a late duplicate), counted in :attr:`resyncs` and not as a loss; :meth:`reset`
    forgets the last ``seq`` (a HELLO: the robot has booted).
    """

    def __init__(self) -> None:
        self.last: int | None = None
        self.lost = 0
        self.resyncs = 0

    def reset(self) -> None:
        self.last = None

    def see(self, seq: int) -> int:
        """Count ``seq``; returns the frames lost just before it."""
        gap = 0
        if self.last is not None:
            step = (seq - self.last) & 0xFFFF
            if 1 <= step < 0x8000:
                gap = step - 1
            else:
                self.resyncs += 1
        self.lost += gap
        self.last = seq
        return gap

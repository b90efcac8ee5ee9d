"""Frames of the Mona link v1 (docs/mona_protocol.md): COBS, CRC-16, the streaming reader.

A frame on the wire is the COBS encoding of its payload followed by one ``0x00``. The
payload is ``version`` u8 · ``type`` u8 · ``seq`` u16 · body · ``crc`` u16, little-endian,
at most :data:`MAX_PAYLOAD` bytes; the CRC covers version … body. Every check a frame
can fail raises a subclass of :class:`ProtocolError` whose :attr:`~ProtocolError.kind`
names it, so that a receiver counts each kind and never acts on a bad frame.
docs/mona_protocol.md describes the protocol for users.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass

#: The protocol version this module speaks.
VERSION = 1
#: Largest payload (version … crc) [bytes].
MAX_PAYLOAD = 64
#: Header (version, type, seq) and trailer (crc) around the body [bytes].
HEADER = struct.Struct("<BBH")
CRC = struct.Struct("<H")
MIN_PAYLOAD = HEADER.size + CRC.size
#: Largest COBS encoding of a payload: one overhead byte per 254 bytes, at least one.
MAX_ENCODED = MAX_PAYLOAD + 1 + MAX_PAYLOAD // 254
#: The frame delimiter.
DELIMITER = 0


class ProtocolError(ValueError):
    """A frame that failed a check; :attr:`kind` names the check (a diagnostics key)."""

    kind = "frame"


class CobsError(ProtocolError):
    """The bytes between two delimiters are not a valid COBS encoding."""

    kind = "cobs"


class LengthError(ProtocolError):
    """A payload shorter than header and CRC, or longer than :data:`MAX_PAYLOAD`."""

    kind = "length"


class VersionError(ProtocolError):
    """A payload of another protocol version."""

    kind = "version"


class CrcError(ProtocolError):
    """A payload whose CRC does not match its bytes."""

    kind = "crc"


class UnknownTypeError(ProtocolError):
    """A message type this side does not accept."""

    kind = "type"


class BodyLengthError(ProtocolError):
    """A body whose length is not its type's."""

    kind = "body"


#: Every kind of bad frame, in the order of the checks.
ERROR_KINDS = tuple(
    e.kind
    for e in (CobsError, LengthError, VersionError, CrcError, UnknownTypeError, BodyLengthError)
)


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no xor-out."""
    crc = 0xFFFF
    for byte in data:
        crc = ((crc << 8) & 0xFFFF) ^ _TABLE[(crc >> 8) ^ byte]
    return crc


def cobs_encode(data: bytes) -> bytes:
    """COBS encoding of ``data``: no ``0x00`` in the result (the delimiter is not added).

    A block of 254 non-zero bytes that ends the data is not followed by an empty block
    (the variant of Cheshire and Baker's paper and of most implementations); the
    decoder accepts both.
    """
    out = bytearray(b"\x00")
    code_at, code = 0, 1
    for i, byte in enumerate(data):
        if byte == 0:
            out[code_at], code_at, code = code, len(out), 1
            out.append(0)
            continue
        out.append(byte)
        code += 1
        if code == 0xFF and i + 1 < len(data):
            out[code_at], code_at, code = code, len(out), 1
            out.append(0)
    out[code_at] = code
    return bytes(out)


def cobs_decode(encoded: bytes) -> bytes:
    """The data of a COBS encoding (without its delimiter); :class:`CobsError` if invalid."""
    out = bytearray()
    i, n = 0, len(encoded)
    while i < n:
        code = encoded[i]
        end = i + code
        if code == 0:
            raise CobsError("COBS: a 0x00 inside the frame")
        if end > n:
            raise CobsError(f"COBS: a block of {code - 1} bytes where {n - i - 1} are left")
        block = encoded[i + 1 : end]
        if 0 in block:
            raise CobsError("COBS: a 0x00 inside the frame")
        out += block
        i = end
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)


@dataclass(frozen=True)
class Frame:
    """A payload that passed every check: its message ``type``, ``seq`` and ``body``."""

    type: int
    seq: int
    body: bytes


def encode_frame(type_: int, seq: int, body: bytes = b"") -> bytes:
    """The bytes on the wire of one frame: COBS(payload with CRC) then ``0x00``."""
    head = HEADER.pack(VERSION, type_, seq & 0xFFFF) + body
    payload = head + CRC.pack(crc16(head))
    if len(payload) > MAX_PAYLOAD:
        raise LengthError(f"length: a payload of {len(payload)} bytes (at most {MAX_PAYLOAD})")
    return cobs_encode(payload) + b"\x00"


def decode_payload(payload: bytes) -> Frame:
    """Check a decoded payload's length, version and CRC; :class:`ProtocolError` if bad."""
    if not MIN_PAYLOAD <= len(payload) <= MAX_PAYLOAD:
        raise LengthError(
            f"length: a payload of {len(payload)} bytes ({MIN_PAYLOAD} to {MAX_PAYLOAD})"
        )
    version, type_, seq = HEADER.unpack_from(payload)
    if version != VERSION:
        raise VersionError(f"version: {version} (this side speaks {VERSION})")
    (crc,) = CRC.unpack_from(payload, len(payload) - CRC.size)
    expected = crc16(payload[: -CRC.size])
    if crc != expected:
        raise CrcError(f"crc: 0x{crc:04X} where the bytes give 0x{expected:04X}")
    return Frame(type_, seq, bytes(payload[HEADER.size : -CRC.size]))


def decode_frame(encoded: bytes) -> Frame:
    """One frame from its COBS bytes (without the delimiter)."""
    if len(encoded) > MAX_ENCODED:
        raise LengthError(f"length: a frame of {len(encoded)} bytes (at most {MAX_ENCODED})")
    return decode_payload(cobs_decode(encoded))


class FrameReader:
    """Splits a byte stream on ``0x00`` into frames.

    :meth:`feed` takes bytes as they arrive and yields a :class:`Frame` or a
    :class:`ProtocolError` (yielded, not raised) per delimited chunk; bytes of an
    unfinished frame wait for the next call. A chunk that grows beyond
    :data:`MAX_ENCODED` bytes without a delimiter yields one :class:`LengthError` and
    is skipped up to the next delimiter, so memory stays bounded whatever arrives.
    Empty chunks (``0x00 0x00``, a sender flushing the line) are skipped silently.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._skipping = False

    def feed(self, data: bytes) -> Iterator[Frame | ProtocolError]:
        """Frames and errors of ``data`` appended to what came before."""
        start = 0
        while start <= len(data):
            end = data.find(b"\x00", start)
            piece = data[start:] if end < 0 else data[start:end]
            if not self._skipping:
                self._buffer += piece
                if len(self._buffer) > MAX_ENCODED:
                    self._skipping = True
                    self._buffer.clear()
                    yield LengthError(f"length: no delimiter within {MAX_ENCODED} bytes")
            if end < 0:
                return
            if self._skipping:
                self._skipping = False
            elif self._buffer:
                try:
                    yield decode_frame(bytes(self._buffer))
                except ProtocolError as exc:
                    yield exc
                self._buffer.clear()
            start = end + 1

"""The Mona link v1 in Python (aes_ros.mona): COBS, CRC, every message, the streaming
reader under arbitrary bytes, lost-frame counting, twist ↔ wheel speeds, sensors."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aes_ros.mona import framing, messages
from aes_ros.mona.framing import (
    MAX_PAYLOAD,
    CobsError,
    CrcError,
    Frame,
    FrameReader,
    LengthError,
    ProtocolError,
    VersionError,
    cobs_decode,
    cobs_encode,
    crc16,
    encode_frame,
)
from aes_ros.mona.geometry import MonaGeometry, twist_from_wheels, wheels_from_twist
from aes_ros.mona.messages import (
    ROBOT_TO_HOST,
    Hello,
    Ping,
    Pong,
    SeqCounter,
    Stop,
    Telemetry,
    Wheels,
)
from aes_ros.mona.sensors import IrModel, integrate_pose

EVERY_MESSAGE = [
    Wheels(-135, 135, 500),
    Wheels(0, 0, 0),
    Stop(),
    Ping(),
    Hello(7, 1, 2, "mona328"),
    Hello(255, 0, 0, "monaesp"),
    Telemetry(65535, -32768, 32767, (0, 1023, 512, 7, 65535), 3700, 0b101),
    Pong(12),
]


def one_frame(data: bytes) -> Frame | ProtocolError:
    (item,) = list(FrameReader().feed(data))
    return item


def test_crc16_ccitt_false_check_value() -> None:
    assert crc16(b"123456789") == 0x29B1
    assert crc16(b"") == 0xFFFF


@pytest.mark.parametrize(
    ("data", "encoded"),
    [
        (b"", b"\x01"),
        (b"\x00", b"\x01\x01"),
        (b"\x00\x00", b"\x01\x01\x01"),
        (b"\x11\x22\x00\x33", b"\x03\x11\x22\x02\x33"),
        (b"\x11\x00\x00\x00", b"\x02\x11\x01\x01\x01"),
        (bytes(range(1, 255)), b"\xff" + bytes(range(1, 255))),
        (bytes(range(1, 256)), b"\xff" + bytes(range(1, 255)) + b"\x02\xff"),
    ],
)
def test_cobs_known_encodings(data: bytes, encoded: bytes) -> None:
    # the examples of the COBS paper (and Wikipedia's table)
    assert cobs_encode(data) == encoded
    assert cobs_decode(encoded) == data


@given(st.binary(max_size=600))
def test_cobs_round_trip_has_no_zero(data: bytes) -> None:
    encoded = cobs_encode(data)
    assert 0 not in encoded
    assert cobs_decode(encoded) == data


@pytest.mark.parametrize("bad", [b"\x05\x11\x22", b"\x03\x11\x00\x22", b"\x00"])
def test_cobs_rejects_truncated_and_zero_bytes(bad: bytes) -> None:
    with pytest.raises(CobsError):
        cobs_decode(bad)


@pytest.mark.parametrize("msg", EVERY_MESSAGE, ids=lambda m: type(m).__name__)
@pytest.mark.parametrize("seq", [0, 1, 65535])
def test_every_message_round_trips(msg: messages.Message, seq: int) -> None:
    wire = msg.encode(seq)
    assert wire.endswith(b"\x00") and 0 not in wire[:-1]
    frame = one_frame(wire)
    assert frame == Frame(msg.TYPE, seq, msg.body())
    assert messages.decode(frame) == msg


def test_wheels_bytes_are_the_spec_layout() -> None:
    # version 1, type 0x01, seq 0x0102, left -1, right 300, timeout 500: little-endian
    payload = bytes([1, 0x01, 0x02, 0x01, 0xFF, 0xFF, 0x2C, 0x01, 0xF4, 0x01])
    payload += crc16(payload).to_bytes(2, "little")
    assert Wheels(-1, 300, 500).encode(0x0102) == cobs_encode(payload) + b"\x00"


def test_payload_size_limit() -> None:
    assert len(Telemetry(0, 0, 0).body()) + 6 <= MAX_PAYLOAD
    with pytest.raises(LengthError):
        encode_frame(0x82, 0, bytes(MAX_PAYLOAD - 5))


def frame_with(payload_edit) -> bytes:
    """A PONG's payload changed by ``payload_edit`` (before COBS), as wire bytes."""
    payload = bytearray(framing.HEADER.pack(1, Pong.TYPE, 3) + Pong(2).body())
    payload += crc16(bytes(payload)).to_bytes(2, "little")
    return cobs_encode(bytes(payload_edit(payload))) + b"\x00"


def flip_crc(p: bytearray) -> bytearray:
    p[-1] ^= 0x01
    return p


def version_2(p: bytearray) -> bytearray:
    p[0] = 2
    p[-2:] = crc16(bytes(p[:-2])).to_bytes(2, "little")
    return p


@pytest.mark.parametrize(
    ("wire", "error"),
    [
        (frame_with(flip_crc), CrcError),
        (frame_with(version_2), VersionError),
        (frame_with(lambda p: p[:3]), LengthError),  # shorter than header + crc
        (b"\x07\x01\x83\x00", CobsError),  # a block longer than the frame
        (cobs_encode(bytes(range(1, 80))) + b"\x00", LengthError),  # oversize
    ],
)
def test_each_bad_frame_is_its_own_error(wire: bytes, error: type) -> None:
    item = one_frame(wire)
    assert isinstance(item, error), item
    assert item.kind in framing.ERROR_KINDS


def test_unknown_type_and_wrong_body_length() -> None:
    with pytest.raises(framing.UnknownTypeError):
        messages.decode(one_frame(encode_frame(0x7F, 0)))
    with pytest.raises(framing.UnknownTypeError):  # a host command arriving at the host
        messages.decode(one_frame(Wheels(1, 1, 1).encode(0)), ROBOT_TO_HOST)
    with pytest.raises(framing.BodyLengthError):
        messages.decode(one_frame(encode_frame(Telemetry.TYPE, 0, b"\x00" * 5)))


def test_reader_splits_a_stream_at_any_cut() -> None:
    wire = b"".join(m.encode(i) for i, m in enumerate(EVERY_MESSAGE))
    for cut in range(len(wire) + 1):
        reader = FrameReader()
        got = [*reader.feed(wire[:cut]), *reader.feed(wire[cut:])]
        assert [messages.decode(f) for f in got] == EVERY_MESSAGE


def test_reader_recovers_after_garbage_and_an_endless_frame() -> None:
    reader = FrameReader()
    good = Ping().encode(5)
    items = [*reader.feed(b"\x00\x00" + b"\x42" * 500), *reader.feed(b"\x42" * 300 + b"\x00")]
    assert len(items) == 1 and isinstance(items[0], LengthError)  # one error, bounded memory
    assert list(reader.feed(b"\x13\x37\x00" + good))[1:] == [Frame(Ping.TYPE, 5, b"")]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=120), max_size=8), st.lists(st.sampled_from(EVERY_MESSAGE)))
def test_fuzz_reader_gives_only_frames_or_protocol_errors(
    chunks: list[bytes], good: list[messages.Message]
) -> None:
    reader = FrameReader()
    for chunk in [*chunks, b"\x00", *(m.encode(1) for m in good)]:
        for item in reader.feed(chunk):
            assert isinstance(item, Frame | ProtocolError)
            if isinstance(item, Frame):
                try:
                    msg = messages.decode(item)
                except ProtocolError:
                    continue
                assert isinstance(msg, messages.Message)
    # after a delimiter the reader is in step again: valid frames come out whole
    tail = list(reader.feed(b"\x00" + b"".join(m.encode(1) for m in good)))
    assert [messages.decode(f) for f in tail] == good


@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=1, max_size=70))
def test_fuzz_any_delimited_bytes_decode_or_raise_protocol_error(data: bytes) -> None:
    try:
        frame = framing.decode_frame(data.replace(b"\x00", b""))
        messages.decode(frame)
    except ProtocolError:
        pass


def test_seq_counter_counts_gaps_and_wraps() -> None:
    count = SeqCounter()
    lost = [count.see(s) for s in (65533, 65534, 1, 2, 5)]
    assert lost == [0, 0, 2, 0, 2] and count.lost == 4
    count.see(3)  # a step back: a restart, not 65533 lost frames
    assert count.lost == 4 and count.resyncs == 1
    count.reset()
    assert count.see(40000) == 0


# ------------------------------------------------------------------------ geometry


def test_geometry_is_the_one_the_simulator_uses() -> None:
    from sim_bridge import mona

    assert mona.MonaGeometry is MonaGeometry
    g = MonaGeometry()
    assert g.max_rim_speed_mm_s == math.floor(g.max_wheel_speed * g.wheel_radius * 1000 + 1e-9)


@pytest.mark.parametrize(("v", "omega"), [(0.05, 0.0), (0.0, 1.0), (0.03, -0.7), (-0.02, 0.4)])
def test_wheels_from_twist_follows_the_spec(v: float, omega: float) -> None:
    s = MonaGeometry().wheel_separation
    left, right = wheels_from_twist(v, omega)
    assert (left, right) == (round(1000 * (v - omega * s / 2)), round(1000 * (v + omega * s / 2)))
    back_v, back_omega = twist_from_wheels(left, right)
    assert back_v == pytest.approx(v, abs=1e-3)
    assert back_omega == pytest.approx(omega, abs=2e-3 / s)


@given(st.floats(-10, 10), st.floats(-100, 100))
def test_wheels_are_clamped_and_keep_the_turn_direction(v: float, omega: float) -> None:
    g = MonaGeometry()
    left, right = wheels_from_twist(v, omega, g)
    top = g.max_rim_speed_mm_s
    assert -top <= left <= top and -top <= right <= top
    if abs(omega) * g.wheel_separation / 2 > 0.002:  # a turn that survives rounding
        assert np.sign(right - left) in (0, np.sign(omega))


def test_wheel_limit_keeps_the_curvature() -> None:
    g = MonaGeometry()
    left, right = wheels_from_twist(1.0, 2.0, g)  # far beyond the motors
    v, omega = twist_from_wheels(left, right, g)
    assert max(abs(left), abs(right)) == g.max_rim_speed_mm_s
    assert omega / v == pytest.approx(2.0, rel=0.05)  # up to rounding to mm/s


# ------------------------------------------------------------------------ sensors


@pytest.mark.parametrize("falling", [True, False])
def test_ir_model_is_finite_monotone_and_clipped(falling: bool) -> None:
    model = IrModel(falling=falling)
    raw = np.arange(0, 65536, 97)
    r = model.range(raw)
    assert np.all(np.isfinite(r))
    # more reflected light, closer: on the original Mona the reading falls with it
    assert np.all(np.diff(r) >= 0) if falling else np.all(np.diff(r) <= 0)
    assert r.min() >= model.min_range and r.max() == model.max_range
    if not falling:  # a signal this large is only reached when the reading grows
        assert r.min() == model.min_range
    assert model.check() is None


def test_ir_model_reads_the_original_monas_falling_readings() -> None:
    """The firmware reports 1023 when nothing is seen (docs/firmware.md)."""
    model = IrModel()
    assert model.range(1023) == model.max_range
    assert model.range(0) == pytest.approx(model.min_range, abs=1e-3)
    assert IrModel(min_range=0.2).check() is not None


def test_integrate_pose_drives_arcs() -> None:
    # a full circle at constant twist comes back to the start
    x, y, th = 0.0, 0.0, 0.3
    for _ in range(100):
        x, y, th = integrate_pose(x, y, th, 0.05, 2 * math.pi / 10, 0.1)
    assert (x, y) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert th == pytest.approx(0.3)
    assert integrate_pose(0, 0, math.pi / 2, 0.1, 0.0, 2.0) == pytest.approx(
        (0.0, 0.2, math.pi / 2)
    )


def test_the_examples_in_the_docs_are_the_bytes_on_the_wire() -> None:
    doc = (Path(__file__).parents[2] / "docs" / "mona_protocol.md").read_text()
    rows = re.findall(
        r"^\| `(\w+\(.*?\))` \| (\d+) \| `([0-9a-f ]+)` \| `([0-9a-f ]+)` \|$", doc, re.M
    )
    assert len(rows) == 6
    kinds = {k.__name__: k for k in (Wheels, Stop, Ping, Hello, Telemetry, Pong)}
    for text, seq, payload, wire in rows:
        msg = eval(text, {"__builtins__": {}}, kinds)  # a constructor call of the table
        assert msg.encode(int(seq)).hex(" ") == wire, text
        assert cobs_decode(bytes.fromhex(wire)[:-1]).hex(" ") == payload, text

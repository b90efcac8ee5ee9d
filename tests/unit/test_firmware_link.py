"""The firmware's Mona link code (firmware/mona/link.c) against the driver's
(:mod:`aes_ros.mona.framing`), on the host: the same verdict on every frame, good or bad.

A harness (tests/helpers/link_harness.c) built with AddressSanitizer and UBSan decodes,
encodes and receives what the test sends. Tens of thousands of frames: valid ones, the
same with bits flipped, bytes dropped, inserted or cut, and random bytes of every length
up to 255; and byte streams of such frames, delimiters lost or doubled, as the firmware
receives them byte by byte (:class:`aes_ros.mona.framing.FrameReader` on the driver's
side). Both sides must accept the same frames with the same type, seq and body, reject
the others for the same reason, and encode every frame to the same bytes; no input may
read or write out of bounds. tests/system/test_firmware.py checks the built firmware in
simavr.
"""

from __future__ import annotations

import random
import shutil
import subprocess
from pathlib import Path

import pytest

from aes_ros.mona import framing
from aes_ros.mona.framing import MAX_PAYLOAD, MIN_PAYLOAD, ProtocolError

REPO = Path(__file__).resolve().parents[2]
HARNESS = REPO / "tests" / "helpers" / "link_harness.c"
#: link.h's enum link_error, as the driver names the checks.
C_ERRORS = {1: "cobs", 2: "length", 3: "version", 4: "crc"}
CC = shutil.which("cc") or shutil.which("gcc")


@pytest.fixture(scope="module")
def harness(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if CC is None:
        pytest.skip("needs a C compiler (cc)")
    exe = tmp_path_factory.mktemp("link") / "link_harness"
    cmd = [
        CC, "-std=gnu99", "-O1", "-g", "-Wall", "-Wextra", "-Werror",
        "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
        "-I", str(REPO / "firmware" / "mona"), str(HARNESS),
        str(REPO / "firmware" / "mona" / "link.c"), "-o", str(exe),
    ]  # fmt: skip
    built = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    if built.returncode != 0 and any(w in built.stderr for w in ("sanitize", "asan", "ubsan")):
        pytest.skip(f"the compiler has no sanitizers: {built.stderr.strip()[:200]}")
    assert built.returncode == 0, built.stderr
    return exe


def run(harness: Path, records: bytes) -> list[str]:
    out = subprocess.run(
        [str(harness)], input=records, capture_output=True, timeout=120,
        env={"ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"},
    )  # fmt: skip
    assert out.returncode == 0, out.stderr.decode(errors="replace")[-3000:]
    return out.stdout.decode().splitlines()


def python_verdict(encoded: bytes) -> str:
    """The driver's verdict on one frame's COBS bytes, in the harness's words."""
    try:
        frame = framing.decode_frame(encoded)
    except ProtocolError as exc:
        return f"err {exc.kind}"
    return f"ok {frame.type} {frame.seq} {frame.body.hex()}"


def c_verdict(line: str) -> str:
    kind, _, rest = line.partition(" ")
    return f"err {C_ERRORS[int(rest)]}" if kind == "err" else line


def valid_frame(rng: random.Random) -> bytes:
    """A frame of any type, seq and body (zeros included), COBS without the delimiter."""
    body = bytes(rng.choice((0, rng.randrange(256))) for _ in range(rng.randrange(MAX_PAYLOAD - 5)))
    return framing.encode_frame(rng.randrange(256), rng.randrange(1 << 16), body)[:-1]


def mutated(frame: bytes, rng: random.Random) -> bytes:
    data = bytearray(frame)
    for _ in range(rng.randrange(1, 4)):
        what = rng.randrange(5)
        at = rng.randrange(len(data) + 1)
        if what == 0 and data:  # a bit flipped
            data[at % len(data)] ^= 1 << rng.randrange(8)
        elif what == 1 and data:  # a byte lost
            del data[at % len(data)]
        elif what == 2:  # a byte inserted
            data.insert(at, rng.randrange(256))
        elif what == 3:  # cut short
            del data[at:]
        else:  # a byte that is a valid code or length at the wrong place
            data.insert(at, rng.choice((0x01, 0xFF, len(data), 0x00)))
    return bytes(data[:255])


def corpus(seed: int, n: int) -> list[bytes]:
    rng = random.Random(seed)
    frames: list[bytes] = [b"", b"\x01", b"\xff" * 65, b"\x01" * 66, bytes(range(1, 200))]
    for _ in range(n):
        pick = rng.randrange(10)
        if pick < 3:
            frames.append(valid_frame(rng))
        elif pick < 8:
            frames.append(mutated(valid_frame(rng), rng))
        else:
            frames.append(bytes(rng.randrange(256) for _ in range(rng.randrange(256))))
    return frames


def test_the_firmware_and_the_driver_decode_every_frame_alike(harness: Path) -> None:
    frames = corpus(seed=1, n=30000)
    lines = run(harness, b"".join(b"d" + bytes([len(f)]) + f for f in frames))
    assert len(lines) == len(frames)
    verdicts = [c_verdict(line) for line in lines]
    differ = [(f.hex(), c, python_verdict(f))
              for f, c in zip(frames, verdicts, strict=True) if c != python_verdict(f)]  # fmt: skip
    assert not differ, f"{len(differ)} frames decoded differently, e.g. {differ[:3]}"
    # the corpus reaches every verdict: accepted, and each of the four checks
    assert {v.split()[0] if v.startswith("ok") else v for v in verdicts} == {
        "ok",
        *(f"err {k}" for k in C_ERRORS.values()),
    }


def test_the_firmware_and_the_driver_encode_every_frame_alike(harness: Path) -> None:
    rng = random.Random(2)
    frames = [(rng.randrange(256), rng.randrange(1 << 16),
               bytes(rng.choice((0, 0xFF, rng.randrange(256))) for _ in range(size)))
              for size in [0, MAX_PAYLOAD - MIN_PAYLOAD] + [rng.randrange(MAX_PAYLOAD - 5)
                                                            for _ in range(3000)]]  # fmt: skip
    records = b"".join(b"e" + bytes([t]) + s.to_bytes(2, "little") + bytes([len(b)]) + b
                       for t, s, b in frames)  # fmt: skip
    lines = run(harness, records)
    assert lines == [f"enc {framing.encode_frame(t, s, b).hex()}" for t, s, b in frames]


def stream(rng: random.Random) -> bytes:
    """Frames on a line: valid, damaged or random, delimiters sometimes lost or doubled,
    now and then a run of non-zero bytes longer than any frame."""
    data = bytearray()
    for _ in range(rng.randrange(1, 12)):
        pick = rng.randrange(10)
        if pick < 4:
            data += valid_frame(rng)
        elif pick < 8:
            data += mutated(valid_frame(rng), rng)
        elif pick < 9:
            data += bytes(rng.randrange(1, 256) for _ in range(rng.randrange(60, 200)))
        else:
            data += bytes(rng.randrange(256) for _ in range(rng.randrange(20)))
        data += b"\x00" * rng.choice((1, 1, 1, 0, 2))
    return bytes(data)


def test_the_firmware_and_the_driver_cut_every_stream_alike(harness: Path) -> None:
    rng = random.Random(3)
    streams = [stream(rng) for _ in range(3000)]
    lines = run(harness, b"".join(b"s" + len(s).to_bytes(2, "little") + s for s in streams))
    firmware: list[list[str]] = [[]]
    for line in lines:
        if line == "end":
            firmware.append([])
        else:
            firmware[-1].append(c_verdict(line))
    assert firmware.pop() == [] and len(firmware) == len(streams)
    driver = [
        [f"err {x.kind}" if isinstance(x, ProtocolError) else f"ok {x.type} {x.seq} {x.body.hex()}"
         for x in framing.FrameReader().feed(s)]
        for s in streams
    ]  # fmt: skip
    differ = [(s.hex(), f, d) for s, f, d in zip(streams, firmware, driver, strict=True) if f != d]
    assert not differ, (
        f"{len(differ)} streams cut differently, e.g. (stream, firmware, driver) {differ[0]}"
    )
    # they reached every verdict, the oversize frame among them
    seen = {v.split()[0] if v.startswith("ok") else v for f in firmware for v in f}
    assert seen == {"ok", *(f"err {k}" for k in C_ERRORS.values())}

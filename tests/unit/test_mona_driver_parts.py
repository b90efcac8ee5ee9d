"""The driver's parts without ROS: link strings and files, and one robot's link state
(sequence numbers, stale commands, backoff, bad frames) over a fake transport."""

from __future__ import annotations

from pathlib import Path

import pytest

from aes_ros.mona.framing import FrameReader, cobs_decode, cobs_encode
from aes_ros.mona.messages import Hello, Ping, Pong, Stop, Telemetry, Wheels, decode
from mona_driver.links import LinkError, load_links_file, parse_link, parse_links
from mona_driver.robot import BACKOFF_MAX, RobotLink


class FakeTransport:
    """Records what is written; ``fail`` makes opening or writing raise."""

    def __init__(self) -> None:
        self.is_open = False
        self.fail = False
        self.written = bytearray()

    def open(self) -> None:
        if self.fail:
            raise FileNotFoundError(2, "No such file or directory")
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def write(self, data: bytes) -> None:
        if self.fail:
            raise OSError(5, "Input/output error")
        self.written += data

    def sent(self) -> list:
        return [decode(f) for f in FrameReader().feed(bytes(self.written))]


def test_link_strings() -> None:
    s = parse_link("3=serial:/dev/ttyUSB0@57600")
    assert (s.robot_id, s.kind, s.device, s.baud) == (3, "serial", "/dev/ttyUSB0", 57600)
    assert parse_link("4=serial:/dev/ttyACM0").baud == 115200
    u = parse_link("5=udp:127.0.0.1")
    assert (u.kind, u.address) == ("udp", ("127.0.0.1", 4210))
    assert parse_link("6=udp:localhost:5000").address == ("127.0.0.1", 5000)


@pytest.mark.parametrize(
    ("links", "reason"),
    [
        (["3"], "expected ID=serial"),
        (["-1=serial:/dev/x"], "robot ID"),
        (["1=serial:@115200"], "no serial device"),
        (["1=serial:/dev/x@abc"], "baud 'abc'"),
        (["1=udp:127.0.0.1:0"], "port '0'"),
        (["1=udp:no.such.host.invalid"], "cannot resolve"),
        (["1=serial:/dev/x", "1=serial:/dev/y"], "the same robot ID"),
        (["1=serial:/dev/x", "2=serial:/dev/x"], "the same device"),
        ([], "no links"),
    ],
)
def test_bad_links_say_why(links: list[str], reason: str) -> None:
    with pytest.raises(LinkError, match=reason):
        parse_links(links)


def test_links_file(tmp_path: Path) -> None:
    listed = tmp_path / "links.yaml"
    listed.write_text("- 0=serial:/dev/ttyUSB0\n- 1=udp:127.0.0.1:4300\n")
    keyed = tmp_path / "keyed.yaml"
    keyed.write_text("links: ['2=serial:/dev/ttyUSB1']\n")
    assert len(parse_links(load_links_file(listed))) == 2
    assert load_links_file(keyed) == ["2=serial:/dev/ttyUSB1"]
    bad = tmp_path / "bad.yaml"
    bad.write_text("robots: 3\n")
    with pytest.raises(LinkError, match="a list of link strings"):
        load_links_file(bad)
    with pytest.raises(LinkError, match="cannot read"):
        load_links_file(tmp_path / "missing.yaml")


def opened_link() -> tuple[RobotLink, FakeTransport]:
    transport = FakeTransport()
    link = RobotLink(parse_link("0=serial:/dev/fake"), transport)  # type: ignore[arg-type]
    assert link.open(0.0) is None
    return link, transport


def test_frames_are_numbered_and_pong_gives_the_round_trip() -> None:
    link, transport = opened_link()
    link.send(Wheels(10, 20, 500), 0.0)
    link.send(Ping(), 1.0)
    link.send(Stop(), 1.0)
    assert transport.sent() == [Wheels(10, 20, 500), Ping(), Stop()]
    assert [f.seq for f in FrameReader().feed(bytes(transport.written))] == [0, 1, 2]
    got, errors = link.receive(Pong(1).encode(0), 1.25)
    assert got == [Pong(1)] and errors == [] and link.stats.rtt == pytest.approx(0.25)


def test_a_command_is_fresh_only_within_its_timeout() -> None:
    link, _ = opened_link()
    link.command, link.command_at = Wheels(10, 10, 500), 5.0
    assert link.fresh_command(5.4, 0.5) == Wheels(10, 10, 500)
    assert link.fresh_command(5.5, 0.5) is None


def test_a_failed_write_drops_the_link_and_reopening_backs_off() -> None:
    link, transport = opened_link()
    transport.fail = True
    assert "Input/output error" in (link.send(Ping(), 1.0) or "")
    assert not transport.is_open and link.stats.drops == 1
    waits = []
    now = link.retry_at
    for _ in range(8):
        assert link.open(now) is not None
        waits.append(link.retry_at - now)
        now = link.retry_at
    assert waits == sorted(waits) and waits[-1] == BACKOFF_MAX
    transport.fail = False
    assert link.open(now) is None and link.send(Ping(), now) is None


def test_bad_frames_are_counted_by_kind_and_lost_frames_from_seq_gaps() -> None:
    link, _ = opened_link()
    good = [Hello(0, 1, 2, "mona328").encode(0), Telemetry(0, 1, 2).encode(1)]
    payload = bytearray(cobs_decode(Telemetry(0, 999, 999).encode(2)[:-1]))
    payload[6] ^= 0xFF  # the left wheel's speed: the CRC no longer matches
    wrong = cobs_encode(bytes(payload)) + b"\x00"
    got, errors = link.receive(b"".join(good) + bytes(wrong) + Telemetry(0, 3, 4).encode(4), 0.0)
    assert got == [Hello(0, 1, 2, "mona328"), Telemetry(0, 1, 2), Telemetry(0, 3, 4)]
    assert [e.kind for e in errors] == ["crc"] and link.stats.bad["crc"] == 1
    assert link.received.lost == 2  # seq 2 (the bad one) and 3 never arrived whole
    _, errors = link.receive(Wheels(1, 1, 1).encode(5), 0.0)  # a host message from the robot
    assert [e.kind for e in errors] == ["type"]

"""The robots' links as written on the command line or in a links file.

``ID=serial:DEVICE[@BAUD]`` (a serial line, 115200 8N1 unless another baud is given) or
``ID=udp:HOST[:PORT]`` (a Mona ESP over Wi-Fi, robot port 4210 unless given). A links
file is YAML: a list of such strings, or a mapping with the list under ``links``.
Parsing is pure; :class:`LinkError` says what is wrong with which string.
"""

from __future__ import annotations

import socket
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import yaml

#: Serial speed of the Mona link (docs/mona_protocol.md).
DEFAULT_BAUD = 115200
#: The robot's UDP port (docs/mona_protocol.md).
ROBOT_UDP_PORT = 4210
#: Baud rates a serial line can be set to here (termios).
BAUDS = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000)
#: The forms of a link string, for messages.
FORMS = "ID=serial:DEVICE[@BAUD] or ID=udp:HOST[:PORT]"


class LinkError(ValueError):
    """A link string or links file that cannot be used; the message says why."""


@dataclass(frozen=True)
class LinkSpec:
    """One robot's link: ``kind`` ``serial`` (``device``, ``baud``) or ``udp`` (``host``,
    ``port``; ``address`` is the resolved (ip, port))."""

    robot_id: int
    kind: str
    device: str = ""
    baud: int = DEFAULT_BAUD
    host: str = ""
    port: int = ROBOT_UDP_PORT
    address: tuple[str, int] = ("", 0)

    def __str__(self) -> str:
        where = f"serial:{self.device}@{self.baud}" if self.kind == "serial" else (
            f"udp:{self.host}:{self.port}")  # fmt: skip
        return f"{self.robot_id}={where}"


def parse_link(text: str) -> LinkSpec:
    """The :class:`LinkSpec` of one link string; :class:`LinkError` if it is not one."""
    head, sep, rest = str(text).strip().partition("=")
    if not sep:
        raise LinkError(f"link {text!r}: expected {FORMS}")
    if not head.isdigit() or int(head) > 65535:
        raise LinkError(f"link {text!r}: the robot ID must be an integer in [0, 65535]")
    robot_id = int(head)
    kind, sep, where = rest.partition(":")
    if kind == "serial" and sep and where:
        device, at, baud_text = where.rpartition("@") if "@" in where else (where, "", "")
        if not device:
            raise LinkError(f"link {text!r}: no serial device")
        baud = DEFAULT_BAUD
        if at:
            if not baud_text.isdigit() or int(baud_text) not in BAUDS:
                raise LinkError(
                    f"link {text!r}: baud {baud_text!r} is not one of {', '.join(map(str, BAUDS))}"
                )
            baud = int(baud_text)
        return LinkSpec(robot_id, "serial", device=device, baud=baud)
    if kind == "udp" and sep and where:
        host, colon, port_text = where.rpartition(":") if ":" in where else (where, "", "")
        port = ROBOT_UDP_PORT
        if colon:
            if not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
                raise LinkError(f"link {text!r}: port {port_text!r} must be in [1, 65535]")
            port = int(port_text)
        host = host.strip("[]")
        try:
            info = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)
        except (OSError, UnicodeError) as exc:
            raise LinkError(f"link {text!r}: cannot resolve host {host!r}: {exc}") from None
        ip, resolved_port = info[0][4][:2]
        return LinkSpec(robot_id, "udp", host=host, port=port, address=(ip, resolved_port))
    raise LinkError(f"link {text!r}: expected {FORMS}")


def load_links_file(path: str | Path) -> list[str]:
    """The link strings of a YAML links file."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise LinkError(f"--links {path}: cannot read it: {exc}") from None
    if isinstance(data, dict):
        data = data.get("links")
    if not isinstance(data, list) or not all(isinstance(s, str | int) for s in data):
        raise LinkError(f"--links {path}: expected a list of link strings ({FORMS})")
    return [str(s) for s in data]


def parse_links(texts: Iterable[str]) -> list[LinkSpec]:
    """Every link, checked together: at least one, distinct robot IDs and endpoints."""
    specs = [parse_link(t) for t in texts]
    if not specs:
        raise LinkError(f"no links: give --link {FORMS} (repeatable) or --links FILE")
    for key, what in ((lambda s: s.robot_id, "robot ID"), (_endpoint, "device or address")):
        seen: dict[object, LinkSpec] = {}
        for spec in specs:
            if key(spec) in seen:
                raise LinkError(f"links {seen[key(spec)]} and {spec}: the same {what}")
            seen[key(spec)] = spec
    return specs


def _endpoint(spec: LinkSpec) -> object:
    return spec.device if spec.kind == "serial" else spec.address

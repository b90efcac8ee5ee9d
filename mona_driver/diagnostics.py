"""The driver's ``/diagnostics``: one status per robot link, one for the UDP socket.

Status names are ``mona_driver: mona_<i>`` and ``mona_driver: udp``; the keys are
listed in docs/mona_protocol.md ("Diagnostics").
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from mona_driver.robot import RobotLink
from mona_driver.transport import UdpHub

#: Prefix of every status name of the driver.
STATUS_PREFIX = "mona_driver: "


def link_status(
    link: RobotLink,
    now: float,
    *,
    silent_after: float,
    hello_after: float,
    refuse_other: bool = True,
) -> DiagnosticStatus:
    """The status of one robot's link (``refuse_other``: a robot that says another id
    is not driven, an error; else a warning)."""
    s = link.stats
    up = link.is_up(now, silent_after)
    state = "up" if up else ("silent" if link.transport.is_open else "down")
    problems = []
    if not up:
        problems.append(f"link {state}" + (f" ({s.last_error})" if s.last_error else ""))
    opened = link.opened_at
    if link.hello is None and opened is not None and now - opened >= hello_after:
        problems.append(f"no HELLO within {hello_after:g} s")
    level = DiagnosticStatus.OK
    if problems:
        level = DiagnosticStatus.ERROR if not link.transport.is_open else DiagnosticStatus.WARN
    other = link.other_robot()
    if other is not None:
        problems.append(f"the robot says it is {other}" + (": not driven" if refuse_other else ""))
        level = DiagnosticStatus.ERROR if refuse_other else max(level, DiagnosticStatus.WARN)
    hello = link.hello
    values = {
        "link": state,
        "endpoint": str(link.spec).partition("=")[2],
        "frames_received": s.frames,
        "frames_lost": link.received.lost,
        "crc_errors": s.bad.get("crc", 0),
        **{f"bad_{kind}": n for kind, n in s.bad.items()},
        "drops": s.drops,
        "reconnects": s.reconnects,
        "wheels_sent": s.wheels,
        "stops_sent": s.stops,
        "bad_cmd_vel": s.bad_commands,
        "rtt_ms": "" if s.rtt is None else f"{1000.0 * s.rtt:.1f}",
        "robot_id": "" if hello is None else hello.robot_id,
        "firmware": "" if hello is None else f"{hello.fw_major}.{hello.fw_minor}",
        "hardware": "" if hello is None else hello.hw,
        "last_error": s.last_error,
    }
    return DiagnosticStatus(
        level=level,
        name=f"{STATUS_PREFIX}mona_{link.robot_id}",
        message="; ".join(problems) if problems else "ok",
        hardware_id="" if hello is None else hello.hw,
        values=[KeyValue(key=k, value=str(v)) for k, v in values.items()],
    )


def udp_status(hub: UdpHub) -> DiagnosticStatus:
    """The status of the UDP socket: its port and the datagrams of strangers."""
    warn = hub.strangers > 0
    return DiagnosticStatus(
        level=DiagnosticStatus.WARN if warn else DiagnosticStatus.OK,
        name=f"{STATUS_PREFIX}udp",
        message=f"{hub.strangers} datagrams from addresses not in the links" if warn else "ok",
        values=[
            KeyValue(key="port", value=str(hub.port)),
            KeyValue(key="strangers", value=str(hub.strangers)),
            KeyValue(key="last_stranger", value=":".join(map(str, hub.last_stranger or ()))),
        ],
    )

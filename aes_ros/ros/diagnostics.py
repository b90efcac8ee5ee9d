"""The robots' liveness as ``diagnostic_msgs/DiagnosticArray``: the bridge's view on
``/diagnostics``, and the robot processes' heartbeats on ``/swarm/heartbeat``.

The bridge hears every robot's ``cmd_vel``; once a second it publishes one status,
named :data:`ROBOTS_STATUS`, that says which robots have been silent for
:data:`SILENT_AFTER` wall seconds or longer: level OK when none, WARN otherwise,
the ids in its value ``silent`` (space-separated). ``rqt_robot_monitor`` and
``ros2 topic echo /diagnostics`` show it as any ROS diagnostic; the dashboard reads
it instead of subscribing to every robot's ``cmd_vel`` itself (which would cost it
one message per robot per step, and every robot one more reader).

Every robot process publishes on ``/swarm/heartbeat``, for each ``/swarm/poses``
it acted on, one status named after it (:data:`HEARTBEAT_PREFIX` + node name)
stamped with those poses' stamp, whose value ``robots`` lists its robots
(``"0-49,52"``). The robots of the other processes read their neighbours'
liveness from it: one message per process and step, where each robot's
``aes_force`` read by each of its neighbours in other processes cost a third of
the CPU of two robot hosts (100 robots at 50 Hz).
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

#: The status's name.
ROBOTS_STATUS = "sim_bridge: robots"
#: Wall seconds without a cmd_vel after which a robot counts as silent.
SILENT_AFTER = 1.0


def robots_status(n: int, silent: Sequence[int], stamp: Time) -> DiagnosticArray:
    """The status of ``n`` robots of which ``silent`` have not spoken for SILENT_AFTER s."""
    ids = [int(i) for i in silent]
    status = DiagnosticStatus(
        level=DiagnosticStatus.WARN if ids else DiagnosticStatus.OK,
        name=ROBOTS_STATUS,
        message=f"{n} robots, {len(ids)} silent (no cmd_vel for {SILENT_AFTER:g} s)",
        values=[KeyValue(key="robots", value=str(n)),
                KeyValue(key="silent", value=" ".join(map(str, ids)))],
    )  # fmt: skip
    msg = DiagnosticArray(status=[status])
    msg.header.stamp = stamp
    return msg


def silent_robots(msg: DiagnosticArray) -> list[int] | None:
    """The silent robots' ids of a ``/diagnostics`` message; None if it has no
    :data:`ROBOTS_STATUS` (another node's diagnostics) or a malformed one."""
    for status in msg.status:
        if status.name != ROBOTS_STATUS:
            continue
        values = {kv.key: kv.value for kv in status.values}
        try:
            return [int(i) for i in values.get("silent", "").split()]
        except ValueError:
            return None
    return None


#: Name of a heartbeat's status: this, then the robot process's node name.
HEARTBEAT_PREFIX = "aes robots: "
_ID_RANGES = re.compile(r"^\d+(-\d+)?(,\d+(-\d+)?)*$")


def format_ids(ids: Sequence[int]) -> str:
    """Robot ids as ranges: ``[0, 1, 2, 5]`` -> ``"0-2,5"`` (sorted, distinct)."""
    parts: list[str] = []
    values = sorted({int(i) for i in ids})
    start = 0
    for k in range(1, len(values) + 1):
        if k == len(values) or values[k] != values[k - 1] + 1:
            first, last = values[start], values[k - 1]
            parts.append(str(first) if first == last else f"{first}-{last}")
            start = k
    return ",".join(parts)


def parse_ids(text: str) -> list[int]:
    """The inverse of :func:`format_ids`; ValueError for anything else."""
    if not text:
        return []
    if not _ID_RANGES.match(text):
        raise ValueError(f"not robot id ranges: {text[:40]!r}")
    ids: list[int] = []
    for part in text.split(","):
        first, _, last = part.partition("-")
        ids.extend(range(int(first), int(last or first) + 1))
    return ids


def heartbeat(process: str, hardware_id: str, ids: Sequence[int]) -> DiagnosticArray:
    """The heartbeat of robot process ``process`` running ``ids`` (set the stamp per step).

    ``hardware_id`` tells processes of the same name apart (host name and pid).
    """
    status = DiagnosticStatus(
        level=DiagnosticStatus.OK,
        name=HEARTBEAT_PREFIX + process,
        hardware_id=hardware_id,
        message=f"{len(ids)} robots acting",
        values=[KeyValue(key="robots", value=format_ids(ids))],
    )
    return DiagnosticArray(status=[status])


def heartbeat_robots(msg: DiagnosticArray) -> list[tuple[str, str]]:
    """(hardware_id, ids text) of each heartbeat status in ``msg``; parse the ids
    with :func:`parse_ids`."""
    found = []
    for status in msg.status:
        if status.name.startswith(HEARTBEAT_PREFIX):
            for kv in status.values:
                if kv.key == "robots":
                    found.append((status.hardware_id, kv.value))
    return found

"""The robots' liveness on ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``).

The bridge hears every robot's ``cmd_vel``; once a second it publishes one status,
named :data:`ROBOTS_STATUS`, that says which robots have been silent for
:data:`SILENT_AFTER` wall seconds or longer: level OK when none, WARN otherwise,
the ids in its value ``silent`` (space-separated). ``rqt_robot_monitor`` and
``ros2 topic echo /diagnostics`` show it as any ROS diagnostic; the dashboard reads
it instead of subscribing to every robot's ``cmd_vel`` itself (which would cost it
one message per robot per step, and every robot one more reader).
"""

from __future__ import annotations

from collections.abc import Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

#: The status's name.
ROBOTS_STATUS = "sim_bridge: robots"
#: The tracker's status (tracker_node.node): what the camera sees, and the ``lost``
#: robots, which every robot process leaves out of its robots' spring sums.
TRACKER_STATUS = "tracker: robots"
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
    return _ids(msg, ROBOTS_STATUS, "silent")


def lost_robots(msg: DiagnosticArray) -> list[int] | None:
    """The ids the tracker has lost, of a ``/diagnostics`` message; None if it has no
    :data:`TRACKER_STATUS` or a malformed one."""
    return _ids(msg, TRACKER_STATUS, "lost")


def _ids(msg: DiagnosticArray, name: str, key: str) -> list[int] | None:
    for status in msg.status:
        if status.name != name:
            continue
        values = {kv.key: kv.value for kv in status.values}
        try:
            return [int(i) for i in values.get(key, "").split()]
        except ValueError:
            return None
    return None

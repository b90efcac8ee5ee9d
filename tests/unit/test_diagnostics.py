"""The robot processes' heartbeat (aes_ros.ros.diagnostics): ids written as ranges
and read back, other diagnostics ignored, malformed lists refused."""

from __future__ import annotations

import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticStatus
from hypothesis import given
from hypothesis import strategies as st

from aes_ros.ros.diagnostics import (
    format_ids,
    heartbeat,
    heartbeat_robots,
    parse_ids,
    robots_status,
)


@given(st.sets(st.integers(0, 5000), max_size=300))
def test_ids_round_trip_as_ranges(ids: set[int]) -> None:
    assert parse_ids(format_ids(list(ids))) == sorted(ids)


def test_contiguous_ids_are_one_range() -> None:
    assert format_ids(range(50)) == "0-49"
    assert format_ids([7, 0, 1, 2, 5]) == "0-2,5,7"


@pytest.mark.parametrize("text", ["0-", "a", "1,,2", "-3", "1 2", "0-4;"])
def test_malformed_id_lists_are_refused(text: str) -> None:
    with pytest.raises(ValueError):
        parse_ids(text)


def test_heartbeat_names_its_process_and_robots() -> None:
    from builtin_interfaces.msg import Time

    msg = heartbeat("/robot_host_1", "pc:42", [3, 4, 5, 9])
    msg.status.append(robots_status(10, [1], Time()).status[0])  # not a heartbeat
    msg.status.append(DiagnosticStatus(name="aes robots: /x"))  # no robots value
    assert heartbeat_robots(msg) == [("pc:42", "3-5,9")]

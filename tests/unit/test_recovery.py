"""The launcher's restart rule and its event log (aes_ros.ros.launch.recovery, .events)."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest

from aes_ros.ros.launch.events import EventLog, exit_text, read_events
from aes_ros.ros.launch.recovery import Backoff, RestartPolicy


def test_restarts_back_off_from_half_a_second_to_eight() -> None:
    policy = RestartPolicy()
    delays, now = [], 0.0
    for _ in range(5):
        delay = policy.delay(now)
        delays.append(delay)
        now += delay
        policy.restarted(now)
        now += 1.0  # it runs a second, then dies again
    assert delays == [0.5, 1.0, 2.0, 4.0, 8.0]


def test_five_restarts_a_minute_then_it_is_given_up() -> None:
    policy = RestartPolicy(Backoff(first=0.1, longest=0.1))
    for k in range(5):
        assert policy.delay(float(k)) == 0.1
        policy.restarted(float(k))
    assert policy.delay(5.0) is None  # a sixth within the minute: give up
    assert policy.delay(60.5) == 0.1  # the first restart has left the window
    quiet = RestartPolicy()
    quiet.restarted(0.0)
    assert quiet.delay(100.0) == 0.5  # a quiet minute starts the back-off over


def test_events_are_on_disk_line_by_line(tmp_path: Path) -> None:
    said: list[str] = []
    log = EventLog(tmp_path / "events.csv", said.append)
    log.record("robot_host_1", "died", exit=exit_text(-signal.SIGKILL), action="restart in 0.5 s",
               sim_time=15.25)  # fmt: skip
    log.record("robot_host_1", "restarted", sim_time=15.8)
    rows = read_events(tmp_path / "events.csv")  # readable before close: nothing buffered
    assert [(r["process"], r["event"], r["exit"], r["sim_time"]) for r in rows] == [
        ("robot_host_1", "died", "SIGKILL", "15.250"),
        ("robot_host_1", "restarted", "", "15.800"),
    ]
    assert rows[0]["action"] == "restart in 0.5 s" and rows[0]["wall_time"]
    assert said[0] == ("launch: robot_host_1 died (SIGKILL) at sim time 15.25 s: restart in 0.5 s")
    assert log.counts == {"died": 1, "restarted": 1}
    log.close()
    again = EventLog(tmp_path / "events.csv", said.append)  # appends, one header
    again.record("supervisor", "died", exit="1")
    assert len(read_events(tmp_path / "events.csv")) == 3


@pytest.mark.parametrize(("code", "text"), [(0, "0"), (1, "1"), (-9, "SIGKILL"), (None, "")])
def test_exit_text(code: int | None, text: str) -> None:
    assert exit_text(code) == text


def test_an_unwritable_log_says_so_and_keeps_the_events(tmp_path: Path) -> None:
    said: list[str] = []
    log = EventLog(tmp_path / "gone" / "events.csv", said.append)  # no such directory
    log.record("sim_bridge", "died", exit="SIGKILL")
    assert log.error is not None and "cannot write events.csv" in said[0]
    assert log.counts["died"] == 1

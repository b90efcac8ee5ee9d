"""The dashboard's pure parts: control checking, the rate limit, the view and the markers."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from aes_ros import scenario
from aes_ros.ros.diagnostics import robots_status, silent_robots
from aes_ros.ros.markers import BODY_DIAMETER, swarm_markers
from dashboard_node.controls import (
    MAX_MESSAGE_BYTES,
    ControlError,
    Drive,
    Enable,
    RateLimit,
    SetGain,
    SimAction,
    parse_control,
)
from dashboard_node.server import needs_token
from dashboard_node.view import SwarmView, spring_strains
from sim_bridge.lockstep import LockstepBarrier


def test_valid_controls_parse_to_what_they_ask() -> None:
    drive = parse_control('{"type": "drive", "direction": [0, 0.05], "omega": 0.1}')
    assert drive == Drive((0.0, 0.05), 0.1)
    # a drag changes only what it changes: the other part is left to the swarm
    assert parse_control('{"type": "drive", "direction": [-1, 0]}') == Drive((-1.0, 0.0), None)
    assert parse_control('{"type": "drive", "omega": -0.7}') == Drive(None, -0.7)
    assert parse_control('{"type": "enable", "enabled": false}') == Enable(False)
    assert parse_control('{"type": "gain", "name": "alpha", "value": -5}') == SetGain("alpha", -5.0)
    assert parse_control(b'{"type": "sim", "action": "reset"}') == SimAction("reset")


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ('{"type": "drive", "direction": [NaN, 0], "omega": 0}', "NaN"),
        ('{"type": "drive", "direction": [Infinity, 0], "omega": 0}', "Infinity"),
        ('{"type": "drive", "direction": [0, 0], "omega": 1e400}', "not finite"),
        ('{"type": "drive", "direction": [0, 0], "omega": 99}', "omega"),
        ('{"type": "drive", "direction": [50, 0], "omega": 0}', "direction"),
        ('{"type": "drive", "direction": [0], "omega": 0}', "two numbers"),
        ('{"type": "drive", "direction": ["0", 0], "omega": 0}', "not a number"),
        ('{"type": "enable", "enabled": 1}', "true or false"),
        ('{"type": "gain", "name": "gamma", "value": 1}', "gamma"),
        ('{"type": "gain", "name": "k", "value": true}', "not a number"),
        ('{"type": "sim", "action": "explode"}', "explode"),
        ('{"type": "launch"}', "type"),
        ('{"type": "enable", "enabled": true, "extra": 1}', "extra"),
        ('{"type": "drive"}', "direction, omega"),
        ('{"type": "drive", "omega": 0, "speed": 1}', "speed"),
        ("[1, 2]", "not a JSON object"),
        ("{not json", "not JSON"),
        ("[" * 5000, "bytes"),
        ('{"type": "enable", "enabled": true, "pad": "' + "x" * MAX_MESSAGE_BYTES + '"}', "bytes"),
    ],
)
def test_bad_controls_are_refused_with_the_reason(text: str, reason: str) -> None:
    with pytest.raises(ControlError, match=reason):
        parse_control(text)


def test_rate_limit_allows_bursts_then_the_rate() -> None:
    limit = RateLimit(rate=10.0, burst=20)
    assert sum(limit.allow(0.0) for _ in range(50)) == 20
    assert sum(limit.allow(1.0) for _ in range(50)) == 10  # one second refills 10
    assert not limit.allow(1.0)
    assert limit.allow(1.1)


@pytest.mark.parametrize(
    ("host", "needed"),
    [("127.0.0.1", False), ("localhost", False), ("::1", False), ("0.0.0.0", True),
     ("192.168.1.20", True)],
)  # fmt: skip
def test_a_token_is_needed_off_this_machine(host: str, needed: bool) -> None:
    assert needs_token(host) is needed


def _view(n: int = 9) -> tuple[SwarmView, np.ndarray]:
    sc = scenario.load("linear").with_robots(n)
    view = SwarmView(sc, label="linear")
    return view, sc.nominal_positions()


def test_frame_has_every_robot_and_the_sheet_every_spring() -> None:
    view, pos = _view(9)
    view.on_poses(1.0, pos, np.zeros(9))
    frame = json.loads(json.dumps(view.frame()))  # what the page gets is JSON
    sheet = view.sheet_message()
    assert frame["n"] == sheet["n"] == 9
    assert len(frame["x"]) == len(frame["psi"]) == 9
    assert len(frame["strain"]) == len(sheet["springs"]) > 0
    # at rest length: no strain; the robots' own force is the drive, along x: ψ_i = 1
    assert np.allclose(frame["strain"], 0.0, atol=1e-3)
    assert np.allclose(frame["psi"], 1.0)
    assert frame["silent"] == []
    assert frame["centroid"] == pytest.approx(pos.mean(axis=0).tolist(), abs=1e-4)


def test_silent_robots_come_from_the_bridges_diagnostics() -> None:
    from builtin_interfaces.msg import Time
    from diagnostic_msgs.msg import DiagnosticStatus

    view, pos = _view(4)
    view.on_poses(0.5, pos, np.zeros(4))
    msg = robots_status(4, [2], Time())
    assert msg.status[0].level == DiagnosticStatus.WARN and "1 silent" in msg.status[0].message
    view.on_silent(silent_robots(msg))
    assert view.frame()["silent"] == [2]
    view.on_silent(silent_robots(robots_status(4, [], Time())))
    assert view.frame()["silent"] == []
    other = robots_status(4, [1], Time())
    other.status[0].name = "some other node"
    assert silent_robots(other) is None  # not the bridge's: ignored


def test_the_bridge_counts_robots_silent_since_their_last_command() -> None:
    barrier = LockstepBarrier(3)
    barrier.arrived(0, now=10.0)
    barrier.arrived(1, now=9.0)
    assert barrier.silent(now=10.5, after=1.0).tolist() == [1, 2]  # 2: never heard
    assert barrier.silent(now=11.0, after=1.0).tolist() == [0, 1, 2]


def test_spring_strain_is_relative_stretch() -> None:
    pos = np.array([[0.0, 0.0], [1.0, 0.0]])
    neighbors = np.array([[1], [0]])
    rest = np.array([[0.8], [0.8]])
    strain = spring_strains(pos, np.array([[0, 1]]), neighbors, rest)
    assert strain == pytest.approx([0.25])


def test_metrics_history_keeps_the_last_minute_and_no_nan_in_json() -> None:
    view, pos = _view(4)
    for t in np.arange(0.0, 90.0, 1.0):
        view.on_poses(float(t), pos, np.zeros(4))
        view.on_metric("alignment", 0.9)
        view.on_metric("total_force", 1.0)
    ts = [row[0] for row in view.history]
    assert min(ts) >= 89.0 - 60.0 and max(ts) == 89.0
    text = json.dumps(view.sheet_message(), allow_nan=False)  # ψ_heading never came: null
    assert json.loads(text)["history"][-1][2] is None


def test_a_new_size_makes_a_new_sheet() -> None:
    view, _ = _view(4)
    pos16 = scenario.load("linear").with_robots(16).nominal_positions()
    view.on_poses(0.0, pos16, np.zeros(16))
    assert view.sheet_message()["n"] == 16
    assert len(view.frame()["x"]) == 16


def test_markers_are_in_odom_with_mona_bodies_and_spring_lines() -> None:
    from builtin_interfaces.msg import Time
    from visualization_msgs.msg import Marker

    view, pos = _view(9)
    for step in range(20):
        view.on_poses(0.1 * step, pos + np.array([0.0, 0.01 * step]), np.full(9, math.pi / 2))
    sheet = view.sheet_message()
    markers = swarm_markers(view.frame(), sheet["springs"], Time(sec=2)).markers
    assert {m.header.frame_id for m in markers} == {"odom"}
    bodies = [m for m in markers if m.ns == "bodies"]
    assert len(bodies) == 9
    assert all(m.type == Marker.CYLINDER and m.scale.x == BODY_DIAMETER == 0.08 for m in bodies)
    springs = next(m for m in markers if m.ns == "springs")
    assert springs.type == Marker.LINE_LIST
    assert len(springs.points) == 2 * len(sheet["springs"]) == len(springs.colors)
    heading = next(m for m in markers if m.ns == "headings")
    tip = heading.points[1]
    assert tip.y > heading.points[0].y and abs(tip.x - heading.points[0].x) < 1e-3  # north
    assert {m.ns for m in markers} >= {"centroid_path", "direction", "rotation_center"}

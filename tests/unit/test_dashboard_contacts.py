"""Walls, obstacles and contacts in what the dashboard shows (dashboard_node.view) and in
/swarm/markers (aes_ros.ros.markers): no ROS graph, the messages built as published."""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from visualization_msgs.msg import Marker

from aes_ros.mona.geometry import MonaGeometry
from aes_ros.ros.markers import ARENA_HEIGHT, swarm_markers
from aes_ros.scenario import load
from dashboard_node.view import SwarmView

G = MonaGeometry()
WALLS = [-1.0, 1.0, -0.5, 0.5]
OBSTACLES = "circle:0.5,0.2,0.05;box:-0.8,-0.6,-0.3,-0.1"


def view() -> SwarmView:
    scenario = load("linear").with_robots(2)
    return SwarmView(scenario.with_overrides({"walls": WALLS, "obstacles": OBSTACLES}))


def test_the_sheet_carries_the_walls_and_obstacles() -> None:
    sheet = view().sheet_message()
    assert sheet["walls"] == WALLS
    assert sheet["circles"] == [[0.5, 0.2, 0.05]]
    assert sheet["boxes"] == [[-0.8, -0.6, -0.3, -0.1]]


def test_the_status_line_gets_contacts_per_second_and_the_closest_bodies() -> None:
    v = view()
    assert "contacts_per_s" not in v.frame()  # nothing heard yet
    heads = np.zeros(2)
    apart = np.array([[0.0, 0.0], [0.2, 0.0]])
    touching = np.array([[0.0, 0.0], [2 * G.body_radius - 0.002, 0.0]])  # 2 mm overlap
    # 10 steps of 0.05 s, one message in two lost; in contact in half of those heard
    for step in range(0, 10, 2):
        v.on_poses(step * 0.05, touching if step % 4 == 0 else apart, heads)
    frame = v.frame()
    heard = [1, 0, 1, 0, 1]
    assert frame["contacts_per_s"] == pytest.approx(np.mean(heard) / 0.1)
    assert frame["min_centre_distance"] == pytest.approx(2 * G.body_radius - 0.002)
    # a body in a wall counts too; a window later the old contacts are gone
    in_wall = np.array([[0.99 - G.axle_offset, 0.0], [0.89 - G.axle_offset, 0.0]])
    for step in range(40, 70):
        v.on_poses(step * 0.05, in_wall, heads)
    frame = v.frame()
    assert frame["contacts_per_s"] == pytest.approx(1 / 0.05)
    assert frame["min_centre_distance"] == pytest.approx(0.1)


def test_markers_draw_the_walls_and_obstacles() -> None:
    v = view()
    v.on_poses(0.0, np.array([[0.0, 0.0], [0.2, 0.0]]), np.zeros(2))
    frame = v.frame()
    markers = swarm_markers(frame, v.pairs.tolist(), Time(), v.arena).markers
    (walls,) = [m for m in markers if m.ns == "walls"]
    assert walls.type == Marker.LINE_STRIP
    corners = {(p.x, p.y) for p in walls.points}
    assert corners == {(-1.0, -0.5), (1.0, -0.5), (1.0, 0.5), (-1.0, 0.5)}
    post, box = sorted((m for m in markers if m.ns == "obstacles"), key=lambda m: m.id)
    assert post.type == Marker.CYLINDER and (post.pose.position.x, post.pose.position.y) == (
        0.5,
        0.2,
    )
    assert post.scale.x == pytest.approx(0.1) and post.scale.z == ARENA_HEIGHT
    assert box.type == Marker.CUBE and box.id != post.id
    assert (box.scale.x, box.scale.y) == pytest.approx((0.2, 0.2))
    assert box.pose.position.x == pytest.approx(-0.7)
    # none without an arena
    plain = swarm_markers(frame, v.pairs.tolist(), Time()).markers
    assert not {m.ns for m in plain} & {"walls", "obstacles"}

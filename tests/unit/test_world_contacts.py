"""Contacts in the pybullet world (sim_bridge.world.World), both modes, no ROS: bodies
driven together, into a wall and at obstacles stay apart; a real pybullet world."""

from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest

from aes_ros.contacts import ITERATIONS, resolve_contacts
from aes_ros.model import unicycle_step
from sim_bridge.arena import HEIGHT, wall_boxes
from sim_bridge.world import World

MODES = ["kinematic", "dynamic"]


def centres(world: World) -> np.ndarray:
    """Body-disc centres (N, 2) [m], axle_offset ahead of each pose."""
    pos, head = world.poses()
    a = world.geometry.axle_offset
    return pos + a * np.stack([np.cos(head), np.sin(head)], -1)


def drive(world: World, u: float, steps: int) -> float:
    """Every robot forward at ``u`` [m/s] for ``steps`` periods; the smallest robot-robot
    centre distance met [m]."""
    closest = np.inf
    for _ in range(steps):
        world.step((np.full(world.n, u), np.zeros(world.n)))
        c = centres(world)
        if world.n > 1:
            closest = min(closest, float(np.linalg.norm(c[0] - c[1])))
    return closest


@pytest.mark.parametrize("mode", MODES)
def test_two_robots_driven_at_each_other_stay_apart(mode):
    pos, head = np.array([[0.0, 0.0], [0.25, 0.0]]), np.array([0.0, math.pi])
    with World(pos, head, mode=mode, contacts=True, cmd_timeout=10.0) as world:
        closest = drive(world, 0.1, 60)  # 3 s: without contacts they would cross
        count, after = world.last_contacts
        r = world.geometry.body_radius
        assert closest >= 2 * r - 0.001
        assert count >= 1  # still pushing against each other
        assert after == pytest.approx(np.linalg.norm(np.diff(centres(world), axis=0)))


@pytest.mark.parametrize("mode", MODES)
def test_a_robot_driven_into_a_wall_stops_at_it(mode):
    walls = np.array([-0.5, 0.3, -0.5, 0.5])
    with World(
        np.zeros((1, 2)), np.zeros(1), mode=mode, contacts=True, walls=walls, cmd_timeout=10.0
    ) as world:
        drive(world, 0.1, 60)  # would reach x = 0.3 + a + r after 3 s
        rim = centres(world)[0, 0] + world.geometry.body_radius
        count, closest = world.last_contacts
    assert rim == pytest.approx(0.3, abs=0.001)
    assert count == 1 and closest == math.inf  # the wall, no other robot


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("offset", [0.0, 0.02])  # head on, and glancing
def test_a_robot_driven_at_obstacles_does_not_enter_them(mode, offset):
    circle = np.array([[0.3, offset, 0.05]])
    box = np.array([[0.3, 0.4, -0.45 - offset, -0.35 - offset]])  # a second robot's path
    pos, head = np.array([[0.0, 0.0], [0.0, -0.4]]), np.zeros(2)
    with World(
        pos, head, mode=mode, contacts=True, circles=circle, boxes=box, cmd_timeout=10.0
    ) as world:
        r = world.geometry.body_radius
        deepest = np.zeros(2)
        for _ in range(60):
            world.step((np.full(2, 0.1), np.zeros(2)))
            c = centres(world)
            deepest[0] = max(deepest[0], r + 0.05 - np.linalg.norm(c[0] - circle[0, :2]))
            deepest[1] = max(deepest[1], c[1, 0] + r - 0.3)  # past the box's near face
    assert deepest.max() <= 0.001
    assert deepest.min() >= -0.001  # both reached their obstacle


def test_kinematic_contacts_are_the_offline_rule_step_by_step():
    # three robots piled up, driving into a wall: the world does the Euler step then
    # resolve_contacts, exactly (bit for bit) as aes_ros.simulator does
    pos = np.array([[0.0, 0.0], [0.05, 0.01], [0.02, 0.06]])
    head = np.array([0.0, 2.0, -1.0])
    u, w = np.array([0.1, 0.08, 0.12]), np.array([0.3, -0.2, 0.0])
    walls = np.array([-0.2, 0.2, -0.2, 0.2])
    circles = np.array([[0.1, -0.1, 0.03]])
    with World(pos, head, contacts=True, walls=walls, circles=circles) as world:
        r, a = world.geometry.body_radius, world.geometry.axle_offset
        for _ in range(40):
            world.step((u, w))
            pos, head = unicycle_step(pos, head, u, w, world.dt)
            expected = resolve_contacts(
                pos, head, r, a, walls, circles, np.empty((0, 4)), ITERATIONS
            )
            got_pos, got_head = world.poses()
            np.testing.assert_array_equal(got_pos, pos)
            np.testing.assert_array_equal(got_head, head)
            assert world.last_contacts == expected


def test_contacts_off_kinematic_robots_pass_through_and_are_counted():
    pos, head = np.array([[0.0, 0.0], [0.25, 0.0]]), np.array([0.0, math.pi])
    with World(pos, head, contacts=False, cmd_timeout=10.0) as world:
        closest = drive(world, 0.1, 60)
        got, _ = world.poses()
        assert got[0, 0] > got[1, 0]  # crossed
        assert closest < 0.01
        world.step((np.zeros(2), np.zeros(2)))
        assert world.last_contacts[0] == 0  # apart again


def test_walls_and_obstacles_are_static_bodies_in_pybullet():
    walls = np.array([-0.5, 0.5, -0.4, 0.4])
    with World(
        np.zeros((1, 2)),
        np.zeros(1),
        mode="dynamic",
        walls=walls,
        circles=np.array([[0.2, 0.2, 0.03]]),
        boxes=np.array([[-0.3, -0.2, 0.1, 0.2]]),
    ) as world:
        assert len(world.arena_bodies) == 6  # four walls, a circle, a box
        for body in world.arena_bodies:
            assert pb.getDynamicsInfo(body, -1, physicsClientId=world._client)[0] == 0.0
        # each wall's inner face on the rectangle, the corners closed, all HEIGHT tall
        boxes = wall_boxes(walls)
        np.testing.assert_array_equal(boxes[:, [1, 0, 3, 2]].diagonal(), walls)
        assert boxes[0, 2] < walls[2] and boxes[0, 3] > walls[3]  # the left one spans corners
        for body, box in zip(world.arena_bodies[:4], boxes, strict=True):
            low, high = pb.getAABB(body, physicsClientId=world._client)
            np.testing.assert_allclose([low[0], high[0], low[1], high[1]], box, atol=1e-3)
            assert high[2] == pytest.approx(HEIGHT, abs=1e-3)


def test_bad_walls_are_rejected():
    with pytest.raises(ValueError, match="walls"):
        World(np.zeros((1, 2)), np.zeros(1), walls=np.array([0.0, 1.0]))

"""The IR rays in pybullet (sim_bridge.ir_sensors.cast_ir) agree with the numba kernel
(aes_ros.ir) within 2 mm on a synthetic layout, in a real pybullet world, no ROS.

The world (sim_bridge.world.World) holds the layout's robots, walls and obstacles.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from aes_ros.ir import IR_ANGLES
from aes_ros.ir_readings import ir_ranges
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.mona.sensors import IrModel
from sim_bridge import ir_sensors
from sim_bridge.ir_sensors import cast_ir
from sim_bridge.world import World

G = MonaGeometry()
R, A = G.body_radius, G.axle_offset
MAX = IrModel().max_range
WALLS = np.array([-0.5, 0.5, -0.4, 0.4])
CIRCLES = np.array([[0.0, 0.25, 0.03], [-0.3, -0.1, 0.05]])
BOXES = np.array([[0.2, 0.3, -0.3, -0.2], [-0.1, -0.05, -0.35, -0.15]])
ARENA = {"walls": WALLS, "circles": CIRCLES, "boxes": BOXES}


def facing_pair() -> tuple[np.ndarray, np.ndarray]:
    """Robot 0 at the origin facing +x, robot 1 facing it with 0.063 m between their rims."""
    return np.array([[0.0, 0.0], [0.063 + 2 * R + 2 * A, 0.0]]), np.array([0.0, math.pi])


def layout() -> tuple[np.ndarray, np.ndarray]:
    """The facing pair, then robots that see a wall, a corner, a circle and a box, and a
    ring of robots at every heading; no two things overlap."""
    positions, headings = facing_pair()
    extra = [
        ([0.5 - A - R - 0.04, 0.1], 0.0),  # a wall 0.04 m ahead
        ([-0.42, 0.32], 2.4),  # in a corner
        ([0.0, 0.25 - 0.03 - 0.05 - R - A], math.pi / 2),  # circle 0 0.05 m ahead
        ([0.12, -0.25], -0.3),  # box 0 ahead and to the left
    ]
    for p, h in extra:
        positions = np.vstack([positions, p])
        headings = np.append(headings, h)
    # a ring of 8 robots around (-0.25, 0.2) facing outwards
    angles = np.linspace(0.0, 2 * math.pi, 8, endpoint=False) + 0.2
    ring = np.stack([-0.25 + 0.11 * np.cos(angles), 0.2 + 0.11 * np.sin(angles)], -1)
    return np.vstack([positions, ring]), np.append(headings, angles)


@pytest.mark.parametrize("mode", ["kinematic", "dynamic"])
def test_pybullet_rays_agree_with_the_kernel_within_2_mm(mode):
    positions, headings = layout()
    kernel = ir_ranges(positions, headings, walls=WALLS, circles=CIRCLES, boxes=BOXES)
    with World(positions, headings, mode=mode, **ARENA) as world:
        rays = cast_ir(world, MAX)
        np.testing.assert_allclose(rays, kernel, atol=0.002)
        # the layout shows every kind of thing: robots, walls, a corner, circles, boxes
        assert rays[0, 0] == pytest.approx(0.063, abs=0.002)
        assert rays[2, 0] == pytest.approx(0.04, abs=0.002)
        assert (rays[3] < MAX).sum() >= 3
        assert rays[4, 0] == pytest.approx(0.05, abs=0.002)
        assert (rays[5] < MAX).any()
        assert (rays[6:] < MAX).sum() >= 8
        # a subset of the robots gets the same rays
        some = np.array([4, 0, 9])  # in any order
        np.testing.assert_allclose(cast_ir(world, MAX, some), rays[some], atol=1e-12)


def test_rays_split_over_several_batches_give_the_same_distances(monkeypatch):
    positions, headings = layout()
    with World(positions, headings, **ARENA) as world:
        whole = cast_ir(world, MAX)
        monkeypatch.setattr(ir_sensors, "MAX_RAYS", 7)
        np.testing.assert_array_equal(cast_ir(world, MAX), whole)


def test_kinematic_bodies_move_before_the_rays_are_cast():
    positions, headings = facing_pair()
    with World(positions, headings, mode="kinematic", dt=0.1) as world:
        world.step((np.array([0.1, 0.0]), np.zeros(2)))  # robot 0 drives 1 cm closer
        rays = cast_ir(world, MAX)
        kernel = ir_ranges(*world.poses())
        assert rays[:, 0] == pytest.approx([0.053, 0.053], abs=1e-6)
        np.testing.assert_allclose(rays, kernel, atol=0.002)


@pytest.mark.parametrize("heading", np.linspace(-math.pi, math.pi, 9))
def test_a_robot_never_sees_itself(heading):
    with World(np.zeros((1, 2)), np.array([heading])) as world:
        assert cast_ir(world, MAX) == pytest.approx(np.full((1, len(IR_ANGLES)), MAX))

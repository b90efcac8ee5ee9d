"""Walls and obstacles in the simulated camera's image (sim_bridge.camera_render): drawn dark,
where they stand, and the tracker's detection (aes_ros.tracking) still finds every robot,
robots pressed against them included, and nothing else."""

from __future__ import annotations

import numpy as np

from aes_ros.camera import covering_height, overhead_camera
from aes_ros.contacts import resolve_contacts
from aes_ros.markers import scattered_robots
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.tracking.calibration import Calibration
from aes_ros.tracking.detection import detect_markers
from aes_ros.tracking.pose import marker_poses
from sim_bridge.camera_render import CameraRenderer

G = MonaGeometry()
R, A = G.body_radius, G.axle_offset
WALLS = np.array([-1.0, 1.0, -0.75, 0.75])
CIRCLES = np.array([[0.3, 0.2, 0.05], [-0.5, -0.3, 0.08]])
BOXES = np.array([[0.5, 0.7, -0.5, -0.3]])
MILD = (-0.08, 0.02, 0.0005, -0.0005, 0.0)


def camera(distortion=MILD):
    h = covering_height((2.4, 1.9), 1280, 960, 70.0)
    return overhead_camera((0.0, 0.0), h, 1280, 960, 70.0, distortion)


def robots() -> tuple[np.ndarray, np.ndarray]:
    """25 robots: four pressed against a post, the box and a wall, the rest scattered and
    pushed out of everything by the contact rule."""
    pressed = np.array(
        [
            [0.3 - 0.05 - R - A, 0.2],  # west of post 0, facing it
            [-0.5, -0.3 + 0.08 + R - A],  # north of post 1, facing east
            [0.6, -0.5 - R - A],  # south of the box
            [1.0 - R - A, 0.0],  # at the east wall
        ]
    )
    heads = np.array([0.0, 0.0, 0.0, 0.0])
    scattered, scattered_heads = scattered_robots(21, (1.8, 1.3), np.random.default_rng(4))
    pos = np.vstack([pressed, scattered])
    head = np.concatenate([heads, scattered_heads])
    resolve_contacts(pos, head, R, A, WALLS, CIRCLES, BOXES, 200)
    return pos, head


def test_walls_and_obstacles_are_drawn_dark_where_they_stand() -> None:
    cam = camera(distortion=(0.0,) * 5)
    plain = CameraRenderer(cam).render(np.empty((0, 2)), np.empty(0))
    img = CameraRenderer(cam, walls=WALLS, circles=CIRCLES, boxes=BOXES).render(
        np.empty((0, 2)), np.empty(0)
    )
    for x, y, z in [(0.3, 0.2, 0.1), (-0.5, -0.3, 0.1), (0.6, -0.4, 0.1), (1.025, 0.0, 0.1)]:
        u, v = np.rint(cam.project(np.array([x, y, z]))).astype(int)
        assert img[v, u] < 80 and plain[v, u] > 100  # the top of a post, the box, a wall
    u, v = np.rint(cam.project(np.array([0.0, 0.0, 0.0]))).astype(int)
    assert img[v, u] == plain[v, u]  # the floor between them as before


def test_the_tracker_finds_every_robot_among_walls_and_obstacles() -> None:
    cam = camera()
    renderer = CameraRenderer(
        cam, walls=WALLS, circles=CIRCLES, boxes=BOXES, noise_sigma=2.0, blur_sigma=0.7, rng=0
    )
    positions, headings = robots()
    found = detect_markers(renderer.render(positions, headings))
    assert found.ids.tolist() == list(range(len(positions)))  # every robot, once, nothing else
    calibration = Calibration(cam.K, cam.dist, cam.rvec, cam.tvec, cam.size)
    p, _, _ = marker_poses(found.ids, found.corners, calibration)
    error = np.linalg.norm(p - positions[found.ids], axis=1)
    assert np.sqrt(np.mean(error**2)) <= 0.002  # the 25-robot accuracy without obstacles

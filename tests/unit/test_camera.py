"""The pinhole camera (aes_ros.camera), the marker convention (aes_ros.markers) and the
simulated overhead camera (sim_bridge.camera_render): conventions and contracts."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo

from aes_ros.camera import PinholeCamera, covering_height, overhead_camera
from aes_ros.markers import (
    N_IDS,
    ReferenceMarker,
    RobotMarker,
    base_positions,
    dictionary,
    marker_centres,
    marker_corners,
    reference_ids,
)
from sim_bridge.camera_render import CameraRenderer
from sim_bridge.mona import MonaGeometry

W, H = 640, 480
MILD = (-0.08, 0.02, 0.0005, -0.0005, 0.0)


def level_camera(distortion=(0.0,) * 5, **kwargs) -> PinholeCamera:
    return overhead_camera((0.2, -0.1), 1.5, W, H, 70.0, distortion, **kwargs)


def test_a_level_camera_shows_the_arena_like_a_map() -> None:
    cam = level_camera()
    cx, cy = (W - 1) / 2, (H - 1) / 2
    np.testing.assert_allclose(cam.project(np.array([0.2, -0.1, 0.0])), [cx, cy], atol=1e-9)
    east, north = cam.project(np.array([[0.5, -0.1, 0.0], [0.2, 0.2, 0.0]]))
    assert east[0] > cx and east[1] == pytest.approx(cy)  # east: right
    assert north[1] < cy and north[0] == pytest.approx(cx)  # north: up
    np.testing.assert_allclose(cam.center, [0.2, -0.1, 1.5], atol=1e-12)
    # a raised point is seen further from the image centre than the floor under it
    low, high = cam.project(np.array([[0.8, 0.3, 0.0], [0.8, 0.3, 0.038]]))
    assert np.linalg.norm(high - [cx, cy]) > np.linalg.norm(low - [cx, cy]) + 1.0


@pytest.mark.parametrize("distortion", [(0.0,) * 5, MILD, (0.1, -0.05, -0.001, 0.002, 0.01)])
def test_project_is_opencvs_model_and_image_to_plane_inverts_it(distortion) -> None:
    cam = level_camera(distortion, tilt_deg=(2.0, -3.0), roll_deg=5.0)
    rng = np.random.default_rng(0)
    for z in (0.0, 0.038):
        pts = np.c_[rng.uniform(-0.6, 1.0, (50, 2)), np.full(50, z)]
        px = cam.project(pts)
        expected, _ = cv2.projectPoints(pts, cam.rvec, cam.tvec, cam.K, cam.dist)
        np.testing.assert_allclose(px, expected.reshape(-1, 2), atol=1e-9)
        np.testing.assert_allclose(cam.image_to_plane(px, z), pts[:, :2], atol=1e-7)
    assert cam.project(np.zeros((2, 5, 3))).shape == (2, 5, 2)


def test_camera_validates_and_is_read_only() -> None:
    cam = level_camera()
    with pytest.raises(ValueError, match="dist"):
        dataclasses.replace(cam, dist=np.zeros(4))
    with pytest.raises(ValueError, match="K"):
        dataclasses.replace(cam, K=np.full((3, 3), np.nan))
    with pytest.raises(ValueError):
        cam.K[0, 0] = 1.0


def test_camera_info_builds_the_message() -> None:
    cam = level_camera(MILD)
    info = cam.camera_info()
    msg = CameraInfo(**dataclasses.asdict(info))
    assert (msg.width, msg.height, msg.distortion_model) == (W, H, "plumb_bob")
    np.testing.assert_allclose(np.reshape(msg.k, (3, 3)), cam.K)
    np.testing.assert_allclose(info.camera_matrix, cam.K)
    np.testing.assert_allclose(info.distortion, MILD)
    np.testing.assert_allclose(np.reshape(msg.p, (3, 4))[:, :3], cam.K)


def test_covering_height_sees_the_whole_rectangle() -> None:
    h = covering_height((2.2, 1.7), W, H, 70.0)
    cam = overhead_camera((0.0, 0.0), h, W, H, 70.0)
    corners = np.array([[-1.1, -0.85, 0.0], [1.1, 0.85, 0.0]])
    px = cam.project(corners)
    assert np.all(px >= -0.5 - 1e-6) and np.all(px <= [W - 0.5 + 1e-6, H - 0.5 + 1e-6])
    # 2.2 / 1.7 is narrower than 4 / 3: the depth fills the image, the width does not
    np.testing.assert_allclose(px[:, 1], [H - 0.5, -0.5], atol=1e-6)
    assert px[0, 0] > 0.0


def test_marker_corners_in_opencv_order_turn_with_the_heading() -> None:
    c = marker_corners(1.0, 2.0, 0.0, 0.038, 0.05)
    np.testing.assert_allclose(
        c[:, :2], [[0.975, 2.025], [1.025, 2.025], [1.025, 1.975], [0.975, 1.975]]
    )
    assert np.all(c[:, 2] == 0.038)
    north = marker_corners(0.0, 0.0, np.pi / 2, 0.0, 2.0)[:, :2]
    # heading north: the marker's top-left (back-left of the robot) is south-west
    np.testing.assert_allclose(north, [[-1, -1], [-1, 1], [1, 1], [1, -1]], atol=1e-12)
    batch = marker_corners(np.zeros((3, 2)), 0.0, np.linspace(0, 1, 6).reshape(3, 2), 0.0, 0.1)
    assert batch.shape == (3, 2, 4, 3)


def test_the_marker_sits_on_the_body_axis_ahead_of_base_link() -> None:
    g, m = MonaGeometry(), RobotMarker()
    assert m.height == pytest.approx(g.ground_clearance + g.body_height)
    assert m.offset == pytest.approx(g.axle_offset)
    assert m.sticker_diameter <= 2 * g.body_radius
    rng = np.random.default_rng(1)
    pos, head = rng.normal(size=(7, 2)), rng.uniform(-np.pi, np.pi, 7)
    centres = marker_centres(pos, head, m.offset)
    np.testing.assert_allclose(np.linalg.norm(centres - pos, axis=1), m.offset)
    np.testing.assert_allclose(base_positions(centres, head, m.offset), pos, atol=1e-12)
    assert reference_ids(3) == (249, 248, 247) and N_IDS == 250
    assert dictionary().bytesList.shape[0] == N_IDS
    with pytest.raises(ValueError, match="sticker_diameter"):
        RobotMarker(sticker_diameter=0.06)


def test_rendering_is_reproducible_and_looks_like_a_camera_frame() -> None:
    cam = level_camera(MILD)
    refs = [ReferenceMarker(249, -0.3, -0.5, 0.08)]
    pos, head = np.array([[0.2, -0.1], [0.6, 0.2]]), np.array([0.3, -2.0])
    frames = [
        CameraRenderer(cam, references=refs, noise_sigma=2.0, blur_sigma=0.7, rng=5).render(
            pos, head
        )
        for _ in range(2)
    ]
    assert frames[0].shape == (H, W) and frames[0].dtype == np.uint8
    np.testing.assert_array_equal(frames[0], frames[1])
    other = CameraRenderer(cam, references=refs, noise_sigma=2.0, blur_sigma=0.7, rng=6)
    assert np.any(other.render(pos, head) != frames[0])
    floor = frames[0][:60, -120:].astype(float)  # an empty corner of the floor
    assert floor.mean() == pytest.approx(128.0, abs=0.3)
    assert floor.std() == pytest.approx(2.0, abs=0.3)
    # fresh noise per frame gives the same statistics
    fresh = CameraRenderer(cam, noise_sigma=2.0, rng=1, fresh_noise=True).render(pos, head)
    assert fresh[:60, -120:].std() == pytest.approx(2.0, abs=0.3)
    with pytest.raises(ValueError, match="ids"):
        CameraRenderer(cam).render(pos, head, ids=[0, N_IDS])


def test_a_level_camera_sees_the_marker_as_printed() -> None:
    cam = level_camera()
    img = CameraRenderer(cam).render(np.array([[0.2, -0.1]]), np.array([0.0]))
    found, ids, _ = cv2.aruco.ArucoDetector(dictionary()).detectMarkers(img)
    assert ids.ravel().tolist() == [0]
    tl, tr, _, bl = found[0].reshape(4, 2)
    assert tl[0] < tr[0] and tl[1] < bl[1]  # top-left is up and left: not mirrored

"""The tracker's core (aes_ros.tracking.detection, .calibration, .pose) against the simulated
camera (sim_bridge.camera_render): detection, accuracy, calibration and its refusals."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from aes_ros.arena_layout import ArenaLayout, CalibrationError, load_layout
from aes_ros.camera import covering_height, overhead_camera
from aes_ros.markers import (
    ReferenceMarker,
    RobotMarker,
    marker_centres,
    reference_ids,
    scattered_robots,
)
from aes_ros.model import wrap_angle
from aes_ros.tracking.calibration import Calibration, calibrate
from aes_ros.tracking.detection import detect_markers
from aes_ros.tracking.pose import marker_poses
from sim_bridge.camera_render import CameraRenderer

MILD = (-0.08, 0.02, 0.0005, -0.0005, 0.0)
VIEW_MARGIN = 0.2  #: [m] seen around the arena; the reference markers lie in it


def corner_references(arena: tuple[float, float], size: float = 0.08) -> list[ReferenceMarker]:
    """Four reference markers on the floor just outside the arena's corners."""
    x, y = arena[0] / 2 + 0.1, arena[1] / 2 + 0.1
    places = [(-x, -y), (x, -y), (x, y), (-x, y)]
    return [
        ReferenceMarker(i, px, py, size)
        for i, (px, py) in zip(reference_ids(4), places, strict=True)
    ]


def setup(arena, width, height, distortion=MILD, **kwargs):
    extent = (arena[0] + 2 * VIEW_MARGIN, arena[1] + 2 * VIEW_MARGIN)
    h = covering_height(extent, width, height, 70.0)
    cam = overhead_camera((0.0, 0.0), h, width, height, 70.0, distortion)
    kwargs = {"noise_sigma": 2.0, "blur_sigma": 0.7, "rng": 0} | kwargs
    return cam, CameraRenderer(cam, **kwargs)


def true_calibration(cam) -> Calibration:
    return Calibration(cam.K, cam.dist, cam.rvec, cam.tvec, cam.size)


@pytest.mark.parametrize(
    ("n", "arena", "size", "position_mm", "heading_deg"),
    [(25, (2.0, 1.5), (1280, 960), 2.0, 1.0), (100, (4.0, 3.0), (2048, 1536), 4.0, 2.0)],
)
def test_round_trip_finds_every_robot_within_the_accuracy_bounds(
    n, arena, size, position_mm, heading_deg
) -> None:
    cam, renderer = setup(arena, *size)
    calibration = true_calibration(cam)
    rng = np.random.default_rng(7)
    pos_err, head_err = [], []
    for _ in range(2):
        positions, headings = scattered_robots(n, arena, rng)
        found = detect_markers(renderer.render(positions, headings))
        assert found.ids.tolist() == list(range(n))  # all, once each
        assert found.duplicates == () and found.at_border == ()
        p, h, reprojection = marker_poses(found.ids, found.corners, calibration)
        pos_err.append(np.linalg.norm(p - positions[found.ids], axis=1))
        head_err.append(wrap_angle(h - headings[found.ids]))
        assert reprojection < 0.3
    pos_rms = 1e3 * np.sqrt(np.mean(np.concatenate(pos_err) ** 2))
    head_rms = math.degrees(np.sqrt(np.mean(np.concatenate(head_err) ** 2)))
    assert pos_rms <= position_mm
    assert head_rms <= heading_deg


def test_calibration_from_reference_markers_recovers_the_camera() -> None:
    arena = (2.0, 1.5)
    refs = corner_references(arena)
    cam, renderer = setup(arena, 1280, 960, references=refs)
    layout = ArenaLayout(tuple(refs))
    rng = np.random.default_rng(3)
    positions, headings = scattered_robots(25, arena, rng)
    image = renderer.render(positions, headings)
    calibration, residuals = calibrate(image, cam.K, cam.dist, layout)
    assert residuals.ids.tolist() == sorted(r.marker_id for r in refs)
    assert residuals.missing == ()
    assert residuals.reprojection_px.max() < 0.3 and residuals.arena_mm.max() < 1.0
    assert "4 reference markers" in str(residuals)
    assert np.linalg.norm(calibration.camera.center - cam.center) < 0.003
    assert calibration.image_size == (1280, 960)
    # the robots' markers, mapped to their plane through the recovered camera
    found = detect_markers(image)
    robots = found.ids < 25
    seen = calibration.image_to_arena(found.corners[robots].reshape(-1, 2))
    centres = seen.reshape(-1, 4, 2).mean(axis=1)
    true = marker_centres(positions, headings, RobotMarker().offset)[found.ids[robots]]
    assert np.abs(centres - true).max() < 0.002
    # and on the floor: the parallax of 38 mm is not small
    floor = calibration.image_to_arena(found.corners[robots].reshape(-1, 2), 0.0)
    assert np.abs(floor.reshape(-1, 4, 2).mean(axis=1) - true).max() > 0.01


def test_calibration_refuses_too_few_references_and_names_the_missing() -> None:
    arena = (2.0, 1.5)
    refs = corner_references(arena)
    cam, renderer = setup(arena, 1280, 960, references=refs[:2])  # two of four on the floor
    image = renderer.render(np.zeros((0, 2)), np.zeros(0))
    with pytest.raises(CalibrationError, match=r"found 2 of the 4.*missing ids \[246, 247\]"):
        calibrate(image, cam.K, cam.dist, ArenaLayout(tuple(refs)))


def test_calibration_refuses_references_on_one_line() -> None:
    refs = [ReferenceMarker(249 - k, -0.8 + 0.8 * k, 0.3 + 0.01 * k, 0.08) for k in range(3)]
    cam, renderer = setup((2.0, 1.5), 1280, 960, references=refs)
    image = renderer.render(np.zeros((0, 2)), np.zeros(0))
    with pytest.raises(CalibrationError, match="nearly on one line"):
        calibrate(image, cam.K, cam.dist, ArenaLayout(tuple(refs)))


def test_calibration_saves_and_loads(tmp_path: Path) -> None:
    cam, _ = setup((2.0, 1.5), 1280, 960)
    calibration = Calibration(cam.K, cam.dist, cam.rvec, cam.tvec, cam.size, 0.04)
    path = tmp_path / "calibration.yaml"
    calibration.save(path)
    loaded = Calibration.load(path)
    for name in ("K", "dist", "rvec", "tvec"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(calibration, name))
    assert (loaded.image_size, loaded.marker_height) == ((1280, 960), 0.04)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("K", [[1.0, 0.0], [0.0, 1.0]], "K: expected a 3x3 list of lists"),
        ("dist", [0.0, 0.0, 0.0, float("nan"), 0.0], "dist: expected a list of 5 finite numbers"),
        ("tvec", None, "tvec: missing"),
        ("image_size", [1280.5, 960], "image_size: expected"),
        ("marker_height", -0.01, "marker_height: expected a finite number > 0"),
    ],
)
def test_a_broken_calibration_file_names_its_field(tmp_path: Path, field, value, message) -> None:
    cam, _ = setup((2.0, 1.5), 1280, 960)
    data = Calibration(cam.K, cam.dist, cam.rvec, cam.tvec, cam.size).to_dict()
    if value is None:
        del data[field]
    else:
        data[field] = value
    path = tmp_path / "calibration.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(CalibrationError, match=message):
        Calibration.load(path)


def test_layout_loads_and_a_wrong_field_is_named(tmp_path: Path) -> None:
    refs = [{"id": 249 - k, "x": float(k), "y": float(k % 2), "size": 0.1} for k in range(3)]
    good = {"marker_height": 0.04, "arena": [-1, 1, -0.75, 0.75], "references": refs}
    path = tmp_path / "arena.yaml"
    path.write_text(yaml.safe_dump(good))
    layout = load_layout(path)
    assert layout.ids == (249, 248, 247) and layout.marker_height == 0.04
    assert layout.arena == (-1.0, 1.0, -0.75, 0.75)
    assert layout.reference(248).x == 1.0
    bad = [
        ({"references": refs[:2]}, "at least 3"),
        ({"references": [*refs[:2], {**refs[2], "size": -0.1}]}, r"references\[2\]\.size"),
        ({"references": [*refs[:2], {"x": 0, "y": 0, "size": 0.1}]}, r"references\[2\]\.id"),
        ({"references": [*refs[:2], {**refs[2], "y": "north"}]}, r"references\[2\]\.y"),
        ({"references": [*refs[:2], {**refs[2], "id": 249}]}, "more than once"),
        ({"arena": [1, -1, 0, 1], "references": refs}, "arena"),
    ]
    for data, message in bad:
        path.write_text(yaml.safe_dump(data))
        with pytest.raises(CalibrationError, match=message):
            load_layout(path)


def test_a_duplicated_id_is_dropped_and_reported() -> None:
    _, renderer = setup((2.0, 1.5), 1280, 960)
    positions = np.array([[-0.5, 0.0], [0.5, 0.0], [0.0, 0.4]])
    found = detect_markers(renderer.render(positions, np.zeros(3), ids=[5, 5, 6]))
    assert found.ids.tolist() == [6]
    assert found.duplicates == (5,)


def test_a_marker_cut_by_the_image_border_gives_no_pose() -> None:
    cam, renderer = setup((2.0, 1.5), 1280, 960, distortion=(0.0,) * 5)
    # the marker's centre on the image's left edge: half of it is outside
    edge = cam.image_to_plane(np.array([[0.0, 479.5]]), RobotMarker().height)[0]
    cut = edge - [RobotMarker().offset, 0.0]
    # and one whole marker a few pixels from the border (kept) as a check
    near = cam.image_to_plane(np.array([[20.0, 300.0]]), RobotMarker().height)[0]
    positions = np.array([cut, near - [RobotMarker().offset, 0.0], [0.0, 0.0]])
    found = detect_markers(renderer.render(positions, np.zeros(3)))
    assert 0 not in found.ids
    assert found.ids.tolist() == [1, 2]
    p, h, _ = marker_poses(found.ids, found.corners, true_calibration(cam))
    assert p.shape == (2, 2) and h.shape == (2,)
    # with a wide border margin the near one is dropped too, and reported
    wide = detect_markers(renderer.render(positions, np.zeros(3)), border_px=25.0)
    assert wide.ids.tolist() == [2] and wide.at_border == (1,)


def test_no_markers_no_poses() -> None:
    cam, renderer = setup((2.0, 1.5), 640, 480)
    found = detect_markers(renderer.render(np.zeros((0, 2)), np.zeros(0)))
    assert len(found) == 0 and found.corners.shape == (0, 4, 2)
    p, h, err = marker_poses(found.ids, found.corners, true_calibration(cam))
    assert p.shape == (0, 2) and h.shape == (0,) and math.isnan(err)

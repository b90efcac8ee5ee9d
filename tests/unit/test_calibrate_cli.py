"""``aes-swarm calibrate`` as a lab runs it: a frame of the reference markers, the arena
layout and the camera's camera_info YAML in, calibration.yaml and residuals out; a
frame or a file it cannot use is refused with what is wrong, and nothing is written."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from aes_ros.arena_layout import corner_layout, save_layout
from aes_ros.cli import main
from aes_ros.tracking.calibration import Calibration
from aes_ros.tracking.camera_info import load_camera_info, save_camera_info
from sim_bridge.camera_node import arena_camera
from sim_bridge.camera_render import CameraRenderer

ARENA = (-1.0, 1.0, -0.75, 0.75)


@pytest.fixture
def lab(tmp_path: Path) -> dict[str, Path]:
    """A frame of 9 robots and the 4 corner references, the layout, the camera_info."""
    camera = arena_camera(list(ARENA), 1280, 960, 60.0, distortion=[-0.05, 0.01, 0, 0, 0])
    layout = corner_layout(ARENA)
    renderer = CameraRenderer(camera, references=layout.references, noise_sigma=2.0, rng=1)
    rng = np.random.default_rng(0)
    frame = renderer.render(rng.uniform(-0.6, 0.6, (9, 2)), rng.uniform(-np.pi, np.pi, 9))
    cv2.imwrite(str(tmp_path / "frame.png"), frame)
    return {
        "frame": tmp_path / "frame.png",
        "layout": save_layout(layout, tmp_path / "arena.yaml"),
        "info": save_camera_info(camera.camera_info(), tmp_path / "camera.yaml"),
        "out": tmp_path / "lab" / "calibration.yaml",  # --out tmp_path/lab
        "camera": camera,  # type: ignore[dict-item]
    }


def calibrate(lab: dict, **change: Path) -> int:
    paths = {**lab, **change}
    return main(["calibrate", "--image", str(paths["frame"]),
                 "--arena-layout", str(paths["layout"]),
                 "--camera-info", str(paths["info"]),
                 "--out", str(paths["out"].parent)])  # fmt: skip


def test_a_frame_of_the_references_gives_the_cameras_pose(lab, capsys) -> None:
    assert calibrate(lab) == 0
    out = capsys.readouterr().out
    assert "4 reference markers" in out and out.count("  marker ") == 4
    calibration = Calibration.load(lab["out"])
    camera = lab["camera"]
    assert np.linalg.norm(calibration.camera.center - camera.center) < 0.005
    # the calibration maps the floor as the true camera sees it: 1 mm or better
    floor = np.array([[0.3, -0.2, 0.038], [-0.7, 0.5, 0.038], [0.0, 0.0, 0.038]])
    back = calibration.image_to_arena(camera.project(floor))
    assert np.abs(back - floor[:, :2]).max() < 0.001


def test_camera_info_round_trip(lab) -> None:
    K, dist, size = load_camera_info(lab["info"])
    info = lab["camera"].camera_info()
    assert size == (1280, 960) and np.allclose(K, info.camera_matrix)
    assert np.allclose(dist, info.distortion)


def test_too_few_references_are_refused_naming_the_missing(lab, tmp_path, capsys) -> None:
    frame = cv2.imread(str(lab["frame"]), cv2.IMREAD_GRAYSCALE)
    frame[:, : frame.shape[1] // 2] = 128  # the west half: two references gone
    cv2.imwrite(str(tmp_path / "half.png"), frame)
    assert calibrate(lab, frame=tmp_path / "half.png") == 2
    err = capsys.readouterr().err
    assert "found 2 of the 4 reference markers" in err and "missing ids" in err
    assert "249" in err and "246" in err
    assert not lab["out"].exists()


@pytest.mark.parametrize(
    ("edit", "named"),
    [
        (lambda d: d["camera_matrix"]["data"].__setitem__(0, 0.0), "camera_matrix"),
        (lambda d: d.pop("image_width"), "image_width"),
        (lambda d: d.__setitem__("distortion_model", "equidistant"), "distortion_model"),
        (lambda d: d["camera_matrix"].__setitem__("data", [1, 2]), "camera_matrix"),
    ],
)
def test_a_bad_camera_info_is_refused_naming_the_field(lab, tmp_path, capsys, edit, named):
    data = yaml.safe_load(lab["info"].read_text())
    edit(data)
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    assert calibrate(lab, info=bad) == 2
    assert named in capsys.readouterr().err and not lab["out"].exists()


def test_a_file_that_is_no_image_or_of_another_size_is_refused(lab, tmp_path, capsys) -> None:
    (tmp_path / "noise.png").write_bytes(b"not a png")
    assert calibrate(lab, frame=tmp_path / "noise.png") == 2
    assert "not an image" in capsys.readouterr().err
    small = cv2.resize(cv2.imread(str(lab["frame"])), (640, 480))
    cv2.imwrite(str(tmp_path / "small.png"), small)
    assert calibrate(lab, frame=tmp_path / "small.png") == 2
    assert "640x480" in capsys.readouterr().err and not lab["out"].exists()


def test_the_camera_info_of_the_simulated_camera_is_the_camera_infos_fields() -> None:
    info = arena_camera(list(ARENA), 64, 48, 60.0).camera_info()
    from sensor_msgs.msg import CameraInfo

    msg = CameraInfo(**dataclasses.asdict(info))
    assert msg.width == 64 and msg.k[0] > 0 and msg.distortion_model == "plumb_bob"

"""The README's tracking picture: a simulated overhead camera frame with the markers the
tracker found drawn on it, beside the true and the tracked positions.

    .venv/bin/python scripts/tracking_picture.py --out docs/tracking    # DIR/tracking.png

25 robots of the combined scenario over a 2.0 × 1.5 m arena, 1280 × 960 px, σ = 2 grey
levels of noise, 0.6 px blur, mild barrel distortion; the camera is calibrated from the
four reference markers of the frame, as the tracker does at the start of a launch.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from aes_ros import scenario
from aes_ros.arena_layout import corner_layout
from aes_ros.markers import RobotMarker
from aes_ros.tracking.calibration import calibrate
from aes_ros.tracking.detection import detect_markers
from aes_ros.tracking.pose import marker_poses
from sim_bridge.camera_node import arena_camera
from sim_bridge.camera_render import CameraRenderer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out", type=Path, default=Path("out/tracking"), metavar="DIR",
        help="the directory this command writes tracking.png to (default out/tracking; "
        "the README's: docs/tracking)",
    )  # fmt: skip
    args = parser.parse_args()
    arena = [-1.0, 1.0, -0.75, 0.75]
    camera = arena_camera(arena, 1280, 960, 60.0, distortion=[-0.05, 0.01, 0.0, 0.0, 0.0])
    layout = corner_layout(arena)
    renderer = CameraRenderer(
        camera, references=layout.references, noise_sigma=2.0, blur_sigma=0.6, rng=0
    )
    positions, headings = scenario.load("combined").with_robots(25).initial_state(0)
    frame = renderer.render(positions, headings)
    calibration, residuals = calibrate(frame, camera.K, camera.dist, layout)
    found = detect_markers(frame)
    robots = found.ids < 25
    xy, yaw, _ = marker_poses(found.ids[robots], found.corners[robots], calibration, RobotMarker())
    error_mm = 1000 * np.linalg.norm(xy - positions[found.ids[robots]], axis=1)

    shown = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    cv2.aruco.drawDetectedMarkers(shown, list(found.corners[:, None]), found.ids[:, None])
    fig, (left, right) = plt.subplots(1, 2, figsize=(14, 5.4), width_ratios=[1.7, 1])
    left.imshow(shown[:, :, ::-1])
    left.set_title(
        f"camera frame, 1280 × 960: {int(robots.sum())} of 25 robots found (+ 4 references)"
    )
    left.axis("off")
    right.plot(*positions.T, "o", ms=11, mfc="none", mec="0.5", label="true (bridge)")
    right.plot(*xy.T, "+", ms=9, color="C3", label="tracked")
    for (x, y), t in zip(xy, yaw, strict=True):
        right.arrow(x, y, 0.06 * np.cos(t), 0.06 * np.sin(t), width=0.004, color="C3")
    right.set_aspect("equal")
    right.set_xlabel("x [m]")
    right.set_ylabel("y [m]")
    right.set_title(
        f"position error RMS {np.sqrt(np.mean(error_mm**2)):.2f} mm, "
        f"calibration {np.sqrt(np.mean(residuals.arena_mm**2)):.2f} mm"
    )
    right.legend(loc="lower right")
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    picture = args.out / "tracking.png"
    fig.savefig(picture, dpi=80)
    rms = np.sqrt(np.mean(error_mm**2))
    print(f"wrote {picture}: {int(robots.sum())}/25 robots, RMS {rms:.3f} mm")


if __name__ == "__main__":
    main()

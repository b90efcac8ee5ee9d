"""``aes-swarm calibrate``: the overhead camera's pose from one frame of reference markers.

Examples::

    aes-swarm calibrate --image frame.png --arena-layout arena.yaml --camera-info camera.yaml \
        --out lab          # writes lab/calibration.yaml

``--arena-layout`` says where the reference markers lie on the floor (and the robots' marker
height); ``--camera-info`` gives the camera's intrinsics in the ROS camera_info YAML
layout (what ``camera_calibration`` writes). The calibration maps image points to the
arena at the markers' height (:mod:`aes_ros.tracking.calibration`); its residuals are
printed, one line per reference marker. A frame that shows too few reference markers,
or markers on one line, is refused with what is missing, and nothing is written; so is
a calibration already in ``--out``, unless ``--overwrite``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from aes_ros.cli.deprecated import add_deprecated
from aes_ros.params import ParameterError
from aes_ros.previous_run import add_overwrite_option, refuse, remove

#: What ``--out DIR`` gets.
CALIBRATION_FILE = "calibration.yaml"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--image", type=Path, required=True, help="a frame (PNG, JPEG, …)")
    p.add_argument(
        "--arena-layout", type=Path, default=None, metavar="FILE",
        help="arena.yaml: where the reference markers lie on the floor (required)",
    )  # fmt: skip
    add_deprecated(p, "--layout", "--arena-layout")
    p.add_argument(
        "--camera-info", type=Path, required=True, metavar="FILE",
        help="the camera's intrinsics (ROS camera_info YAML)",
    )  # fmt: skip
    p.add_argument(
        "--out", type=Path, required=True, metavar="DIR",
        help=f"the directory this command writes: DIR/{CALIBRATION_FILE} (an existing one is "
        "refused unless --overwrite)",
    )  # fmt: skip
    add_overwrite_option(p, "calibration at --out")


def run(args: argparse.Namespace) -> int:
    import cv2

    from aes_ros.arena_layout import CalibrationError, load_layout
    from aes_ros.tracking.calibration import calibrate
    from aes_ros.tracking.camera_info import load_camera_info

    if args.arena_layout is None:  # not argparse's required=: the old --layout gives it too
        raise ParameterError("--arena-layout FILE is required")
    target = args.out / CALIBRATION_FILE
    if args.out.suffix in (".yaml", ".yml"):  # the old spelling: the file itself
        print(
            f"aes-swarm calibrate: --out FILE.yaml is deprecated; use --out DIR "
            f"(writes DIR/{CALIBRATION_FILE})",
            file=sys.stderr,
        )
        target = args.out
    found = [target] if os.path.lexists(target) else []
    refuse(found, f"--out {target}", args.overwrite, "an earlier calibration")
    try:
        layout = load_layout(args.arena_layout)
        K, dist, size = load_camera_info(args.camera_info)
        image = cv2.imread(str(args.image), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise CalibrationError(f"{args.image}: not an image OpenCV can read")
        if (image.shape[1], image.shape[0]) != size:
            raise CalibrationError(
                f"{args.image}: {image.shape[1]}x{image.shape[0]} px, but the camera_info is "
                f"for {size[0]}x{size[1]}"
            )
        calibration, residuals = calibrate(image, K, dist, layout)
    except CalibrationError as exc:
        print(f"aes-swarm calibrate: error: {exc}", file=sys.stderr)
        return 2
    remove(found)  # with --overwrite (a link is replaced, not what it points to)
    target.parent.mkdir(parents=True, exist_ok=True)
    calibration.save(target)
    print(f"calibrated: {residuals}")
    for i, px, mm in zip(residuals.ids, residuals.reprojection_px, residuals.arena_mm, strict=True):
        print(f"  marker {int(i)}: reprojection {px:.3f} px, on the floor {mm:.2f} mm")
    x, y, z = calibration.camera.center
    print(f"camera at ({x:.3f}, {y:.3f}) m, {z:.3f} m above the floor; wrote {target}")
    return 0

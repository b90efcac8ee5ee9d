"""The simulated overhead camera: the projective renderer against pybullet's camera (issue #21).

For each configuration (robots, arena, resolution) it measures, side by side in
one run:

- ``renderer``: :class:`sim_bridge.camera_render.CameraRenderer`, with every
  option a real camera has on (mild lens distortion, 0.7 px blur, σ = 2 grey
  levels of noise), new random poses each frame;
- ``pybullet``: ``getCameraImage`` with ``ER_TINY_RENDERER`` in a DIRECT
  server at the same resolution, of a plane and N cylinders of the Mona's
  size (no markers, no noise: the cheapest scene pybullet could render), a
  few frames.

and prints one line per configuration,
``RESULT robots=… resolution=WxH renderer_ms=… pybullet_ms=… speedup=…``.

``--accuracy`` adds, for 100 robots over 4 × 3 m at several resolutions, the
tracker's side: markers found, position and heading RMS against the truth
(through the true camera), and detection time per frame, one
``RESULT accuracy …`` line each. ``--dictionaries`` compares DICT_4X4_250 with
DICT_APRILTAG_36h11 (markers found, corner RMS) at the same resolutions.

Usage: ``python bench/bench_camera_render.py [--frames 50] [--accuracy] [--dictionaries]``
"""

from __future__ import annotations

import argparse
import math
import time

import cv2
import numpy as np
import pybullet as pb

from aes_ros.camera import covering_height, overhead_camera
from aes_ros.markers import (
    DICTIONARY,
    RobotMarker,
    dictionary,
    marker_centres,
    marker_corners,
    scattered_robots,
)
from aes_ros.model import wrap_angle
from aes_ros.tracking.calibration import Calibration
from aes_ros.tracking.detection import detect_markers, detector_parameters, refine_corners
from aes_ros.tracking.pose import marker_poses
from sim_bridge.camera_render import CameraRenderer
from sim_bridge.mona import MonaGeometry

MILD = (-0.08, 0.02, 0.0005, -0.0005, 0.0)
HFOV = 70.0
MARGIN = 0.2  #: [m] seen around the arena
#: (robots, arena [m], resolution [px])
CONFIGS = [(25, (2.0, 1.5), (1280, 960)), (100, (4.0, 3.0), (2048, 1536))]
#: resolutions of the accuracy sweep, 100 robots over 4 x 3 m
SWEEP = [(1600, 1200), (1800, 1350), (2048, 1536), (2592, 1944)]


def camera_for(arena, size, distortion=MILD):
    extent = (arena[0] + 2 * MARGIN, arena[1] + 2 * MARGIN)
    height = covering_height(extent, *size, HFOV)
    return overhead_camera((0.0, 0.0), height, *size, HFOV, distortion)


def time_renderer(n, arena, size, frames: int) -> float:
    """Median ms per frame of the projective renderer."""
    cam = camera_for(arena, size)
    renderer = CameraRenderer(cam, noise_sigma=2.0, blur_sigma=0.7, rng=0)
    rng = np.random.default_rng(1)
    scenes = [scattered_robots(n, arena, rng) for _ in range(min(frames, 10))]
    renderer.render(*scenes[0])  # builds the markers' patches
    times = []
    for k in range(frames):
        positions, headings = scenes[k % len(scenes)]
        start = time.perf_counter()
        renderer.render(positions, headings)
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def time_pybullet(n, arena, size, frames: int) -> float:
    """Median ms per frame of pybullet's TinyRenderer: a plane and ``n`` cylinders."""
    g = MonaGeometry()
    client = pb.connect(pb.DIRECT)
    try:
        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=client)
        pb.createMultiBody(0, plane, physicsClientId=client)
        shape = pb.createVisualShape(
            pb.GEOM_CYLINDER,
            radius=g.body_radius,
            length=g.body_height,
            rgbaColor=(0.2, 0.2, 0.2, 1),
            physicsClientId=client,
        )
        rng = np.random.default_rng(1)
        positions, _ = scattered_robots(n, arena, rng)
        bodies = [
            pb.createMultiBody(0, -1, shape, (x, y, g.body_z), physicsClientId=client)
            for x, y in positions
        ]
        cam = camera_for(arena, size)
        w, h = size
        height = float(cam.center[2])
        view = pb.computeViewMatrix((0, 0, height), (0, 0, 0), (0, 1, 0), physicsClientId=client)
        vfov = 2.0 * math.degrees(math.atan(0.5 * h / cam.K[1, 1]))
        proj = pb.computeProjectionMatrixFOV(vfov, w / h, 0.1, height + 1.0, physicsClientId=client)
        times = []
        for _ in range(frames):
            for b in bodies:
                x, y = rng.uniform(-0.5, 0.5, 2) * np.array(arena)
                pb.resetBasePositionAndOrientation(
                    b, (x, y, g.body_z), (0, 0, 0, 1), physicsClientId=client
                )
            start = time.perf_counter()
            pb.getCameraImage(
                w, h, view, proj, renderer=pb.ER_TINY_RENDERER, physicsClientId=client
            )
            times.append(time.perf_counter() - start)
        return 1e3 * float(np.median(times))
    finally:
        pb.disconnect(client)


def accuracy(size, frames: int, n: int = 100, arena=(4.0, 3.0)) -> dict:
    """Markers found and pose errors of the tracker, through the true camera."""
    cam = camera_for(arena, size)
    renderer = CameraRenderer(cam, noise_sigma=2.0, blur_sigma=0.7, rng=0)
    calibration = Calibration(cam.K, cam.dist, cam.rvec, cam.tvec, cam.size)
    rng = np.random.default_rng(2)
    found = 0
    pos_err, head_err, times = [], [], []
    for _ in range(frames):
        positions, headings = scattered_robots(n, arena, rng)
        image = renderer.render(positions, headings)
        start = time.perf_counter()
        seen = detect_markers(image)
        times.append(time.perf_counter() - start)
        robots = seen.ids < n
        ids = seen.ids[robots]
        found += len(ids)
        p, h, _ = marker_poses(ids, seen.corners[robots], calibration)
        pos_err.append(np.linalg.norm(p - positions[ids], axis=1))
        head_err.append(wrap_angle(h - headings[ids]))
    pos = np.concatenate(pos_err)
    head = np.concatenate(head_err)
    return {
        "found": found,
        "expected": n * frames,
        "pos_rms_mm": 1e3 * float(np.sqrt(np.mean(pos**2))),
        "pos_max_mm": 1e3 * float(pos.max()),
        "head_rms_deg": math.degrees(float(np.sqrt(np.mean(head**2)))),
        "detect_ms": 1e3 * float(np.median(times)),
        "mm_per_px": 1e3 * float(cam.center[2]) / float(cam.K[0, 0]),
    }


def dictionary_accuracy(size, dictionary_id: int, frames: int, n=100, arena=(4.0, 3.0)) -> dict:
    """Markers found and corner RMS [px] with another dictionary (same side, 50 mm)."""
    cam = camera_for(arena, size)
    renderer = CameraRenderer(
        cam, noise_sigma=2.0, blur_sigma=0.7, rng=0, dictionary_id=dictionary_id
    )
    d = dictionary(dictionary_id)
    detector = cv2.aruco.ArucoDetector(d, detector_parameters(image_size=size))
    marker = RobotMarker()
    rng = np.random.default_rng(2)
    found, errors = 0, []
    for _ in range(frames):
        positions, headings = scattered_robots(n, arena, rng)
        image = renderer.render(positions, headings)
        corners, ids, _ = detector.detectMarkers(image)
        if ids is None:
            continue
        ids = ids.ravel()
        keep = ids < n
        ids, corners = ids[keep], np.asarray(corners, float).reshape(-1, 4, 2)[keep]
        corners = refine_corners(image, corners, cells=d.markerSize + 2)
        centres = marker_centres(positions[ids], headings[ids], marker.offset)
        truth = cam.project(
            marker_corners(centres[:, 0], centres[:, 1], headings[ids], marker.height, marker.size)
        )
        found += len(np.unique(ids))
        errors.append(np.linalg.norm(corners - truth, axis=-1).ravel())
    err = np.concatenate(errors) if errors else np.array([np.nan])
    return {
        "found": found,
        "expected": n * frames,
        "corner_rms_px": float(np.sqrt(np.mean(err**2))),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=50, help="renderer frames per config")
    parser.add_argument("--pybullet-frames", type=int, default=3)
    parser.add_argument("--accuracy", action="store_true", help="the tracker's side too")
    parser.add_argument("--dictionaries", action="store_true", help="4x4_250 vs apriltag 36h11")
    parser.add_argument("--accuracy-frames", type=int, default=5)
    args = parser.parse_args()

    print(f"{'robots':>6} {'resolution':>11} {'renderer ms':>12} {'pybullet ms':>12}")
    for n, arena, size in CONFIGS:
        ours = time_renderer(n, arena, size, args.frames)
        theirs = time_pybullet(n, arena, size, args.pybullet_frames)
        res = f"{size[0]}x{size[1]}"
        print(f"{n:>6} {res:>11} {ours:>12.2f} {theirs:>12.1f}")
        print(
            f"RESULT robots={n} resolution={res} renderer_ms={ours:.2f} "
            f"pybullet_ms={theirs:.1f} speedup={theirs / ours:.0f}"
        )
    if args.accuracy:
        for size in SWEEP:
            a = accuracy(size, args.accuracy_frames)
            print(
                f"RESULT accuracy robots=100 arena=4x3 resolution={size[0]}x{size[1]} "
                f"mm_per_px={a['mm_per_px']:.2f} found={a['found']}/{a['expected']} "
                f"pos_rms_mm={a['pos_rms_mm']:.3f} pos_max_mm={a['pos_max_mm']:.3f} "
                f"head_rms_deg={a['head_rms_deg']:.3f} detect_ms={a['detect_ms']:.1f}"
            )
    if args.dictionaries:
        names = {DICTIONARY: "4X4_250", cv2.aruco.DICT_APRILTAG_36h11: "APRILTAG_36h11"}
        for size in SWEEP[:3]:
            for dictionary_id, name in names.items():
                a = dictionary_accuracy(size, dictionary_id, args.accuracy_frames)
                print(
                    f"RESULT dictionary={name} resolution={size[0]}x{size[1]} "
                    f"found={a['found']}/{a['expected']} corner_rms_px={a['corner_rms_px']:.3f}"
                )


if __name__ == "__main__":
    main()

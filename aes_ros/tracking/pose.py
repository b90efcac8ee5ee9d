"""Robot poses from their markers' corners (docs/design.md#tracking).

:func:`marker_poses` maps each marker's 4 image corners onto the marker plane
(the calibration's ``marker_height``, so the parallax of the raised marker is
removed), takes their centre and the direction of the marker's x axis (the
robot's heading), and steps back from the marker centre (on the body's axis)
to ``base_link`` (the axle midpoint ``/swarm/poses`` reports): ``offset``
behind along the heading (:class:`aes_ros.markers.RobotMarker`).
"""

from __future__ import annotations

import math

import numpy as np

from aes_ros.markers import RobotMarker, base_positions, marker_corners
from aes_ros.tracking.calibration import Calibration


def marker_frames(
    corners: np.ndarray, calibration: Calibration, marker_height: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Centres ``(M, 2)`` [m; arena] and x-axis directions ``(M,)`` [rad] of markers.

    Parameters
    ----------
    corners : (M, 4, 2) [px], OpenCV's order (top-left, top-right,
        bottom-right, bottom-left of the marker image).
    calibration : the camera.
    marker_height : the markers' plane [m]; default ``calibration.marker_height``.

    Notes
    -----
    The centre is the mean of the 4 corners on the plane (exact for a square).
    The x axis is the mean of all 4 edges turned onto it: the two along x
    (top-left→top-right, bottom-left→bottom-right) and the two along y
    (bottom-left→top-left, bottom-right→top-right) turned by −90°. Using all
    four averages twice the edge length of the two along x alone, so its
    error from corner noise is about 1/√2 as large.
    """
    c = np.asarray(corners, dtype=float).reshape(-1, 4, 2)
    if len(c) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    flat = calibration.image_to_arena(c.reshape(-1, 2), marker_height)
    p = flat.reshape(-1, 4, 2)
    centres = p.mean(axis=1)
    along_x = (p[:, 1] - p[:, 0]) + (p[:, 2] - p[:, 3])
    along_y = (p[:, 0] - p[:, 3]) + (p[:, 1] - p[:, 2])
    x_axis = along_x + np.stack([along_y[:, 1], -along_y[:, 0]], axis=-1)  # y turned by −90°
    return centres, np.arctan2(x_axis[:, 1], x_axis[:, 0])


def reprojection_errors(
    corners: np.ndarray,
    centres: np.ndarray,
    headings: np.ndarray,
    calibration: Calibration,
    size: float,
    marker_height: float | None = None,
) -> np.ndarray:
    """Per marker, the RMS over its corners of |detected − projected ideal square| [px], (M,).

    The ideal square has side ``size`` [m] and lies at the pose found for it;
    a large error means a wrong size or height, a bent marker, or a misdetection.
    """
    c = np.asarray(corners, dtype=float).reshape(-1, 4, 2)
    if len(c) == 0:
        return np.zeros(0)
    z = calibration.marker_height if marker_height is None else float(marker_height)
    ideal = marker_corners(centres[:, 0], centres[:, 1], headings, z, size)
    projected = calibration.camera.project(ideal)
    return np.sqrt(np.mean(np.sum((projected - c) ** 2, axis=-1), axis=-1))


def marker_poses(
    ids: np.ndarray,
    corners: np.ndarray,
    calibration: Calibration,
    marker: RobotMarker | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Robot poses from their markers: ``base_link`` positions, headings, and the fit.

    Parameters
    ----------
    ids : (M,) marker ids (carried through: row i of the results is ``ids[i]``).
    corners : (M, 4, 2) [px] from :func:`aes_ros.tracking.detection.detect_markers`.
    calibration : the camera; its ``marker_height`` is the markers' plane.
    marker : how the robots wear their markers (its ``size`` for the
        reprojection error, ``offset`` from the marker centre back to
        ``base_link``); default :class:`~aes_ros.markers.RobotMarker`.

    Returns
    -------
    positions : (M, 2) [m; arena frame] of ``base_link``.
    headings : (M,) [rad, in (-π, π]].
    reprojection_px : RMS over all markers and corners of :func:`reprojection_errors`
        [px], NaN when M = 0.

    Every id is taken for a robot's marker at the marker height; reference
    markers (on the floor) come out displaced and must be ignored by id.
    """
    ids = np.asarray(ids).reshape(-1)
    c = np.asarray(corners, dtype=float).reshape(-1, 4, 2)
    if len(ids) != len(c):
        raise ValueError(f"ids, corners: expected the same length, got {len(ids)} and {len(c)}")
    marker = marker or RobotMarker()
    centres, headings = marker_frames(c, calibration)
    if len(c) == 0:
        return np.zeros((0, 2)), np.zeros(0), math.nan
    errors = reprojection_errors(c, centres, headings, calibration, marker.size)
    positions = base_positions(centres, headings, marker.offset)
    return positions, headings, float(np.sqrt(np.mean(errors**2)))

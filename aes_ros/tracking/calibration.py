"""The camera's pose over the arena, from reference markers on the floor (docs/design.md#tracking).

- :func:`aes_ros.arena_layout.load_layout` reads ``arena.yaml``: the reference markers (id, centre,
  side, optional yaw) lying on the floor, the robots' marker height and
  optionally the arena rectangle.
- :func:`calibrate` finds the reference markers in one image, and from all 4
  corners of each (``cv2.solvePnP`` with the planar IPPE solver, then
  Levenberg–Marquardt) the camera's pose, given its intrinsics K and
  distortion (the camera's ``camera_info``).
- :class:`Calibration` is the result: it maps image points to the arena plane
  at any height (:meth:`Calibration.image_to_arena`, the markers' height
  removes their parallax), and saves to / loads from YAML.

Every file read is validated field by field: a missing, mis-shaped or
non-finite field raises :class:`CalibrationError` naming the field and what
it should be.

``arena.yaml`` is the layout's file (:mod:`aes_ros.arena_layout`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from aes_ros.arena_layout import (
    MIN_REFERENCES,
    ArenaLayout,
    CalibrationError,
    read_yaml,
    yaml_array,
    yaml_mapping,
    yaml_number,
)
from aes_ros.camera import PinholeCamera
from aes_ros.markers import RobotMarker
from aes_ros.tracking.detection import Detections, detect_markers

#: The seen references' spread across their best-fit line, relative to their
#: spread along it, below which they count as (nearly) on one line.
MIN_SPREAD_RATIO = 0.1


@dataclass(frozen=True, eq=False)
class Calibration:
    """A calibrated overhead camera: intrinsics, pose over the arena, the markers' plane.

    K : (3, 3) camera matrix [px]. dist : (5,) plumb_bob ``k1 k2 p1 p2 k3``.
    rvec, tvec : (3,) world→camera rotation (Rodrigues) and translation [m].
    image_size : (width, height) [px]. marker_height : the robots' marker plane [m].
    """

    K: np.ndarray
    dist: np.ndarray
    rvec: np.ndarray
    tvec: np.ndarray
    image_size: tuple[int, int]
    marker_height: float = RobotMarker().height
    camera: PinholeCamera = field(init=False, repr=False)

    def __post_init__(self) -> None:
        w, h = (int(v) for v in self.image_size)
        object.__setattr__(self, "image_size", (w, h))
        object.__setattr__(self, "marker_height", float(self.marker_height))
        try:
            cam = PinholeCamera(w, h, self.K, self.dist, self.rvec, self.tvec)
        except ValueError as exc:
            raise CalibrationError(str(exc)) from None
        object.__setattr__(self, "camera", cam)
        for name in ("K", "dist", "rvec", "tvec"):
            object.__setattr__(self, name, getattr(cam, name))

    def image_to_arena(self, points_px: np.ndarray, z: float | None = None) -> np.ndarray:
        """Arena points ``(M, 2)`` [m] seen at pixels ``(M, 2)`` on the plane at height ``z``.

        ``z`` [m] defaults to :attr:`marker_height` (a robot's marker); 0 is the
        floor. Undistorts, then intersects the pixel's ray with the plane, so
        the parallax of a raised marker is removed.
        """
        height = self.marker_height if z is None else float(z)
        return self.camera.image_to_plane(np.asarray(points_px, float).reshape(-1, 2), height)

    def to_dict(self) -> dict[str, Any]:
        """Plain YAML-able fields (the inverse of :meth:`from_dict`)."""
        return {
            "image_size": list(self.image_size),
            "K": self.K.tolist(),
            "dist": self.dist.tolist(),
            "rvec": self.rvec.tolist(),
            "tvec": self.tvec.tolist(),
            "marker_height": self.marker_height,
        }

    @classmethod
    def from_dict(cls, data: Any) -> Calibration:
        """A calibration from parsed YAML, validated field by field."""
        data = yaml_mapping(data, "calibration")
        size = yaml_array(data, "image_size", (2,))
        if np.any(size < 1) or np.any(size != np.round(size)):
            raise CalibrationError(
                f"image_size: expected [width, height] in whole pixels >= 1, got {size.tolist()}"
            )
        K = yaml_array(data, "K", (3, 3))
        if K[0, 0] <= 0.0 or K[1, 1] <= 0.0:
            raise CalibrationError(f"K: expected positive focal lengths, got {K.tolist()}")
        return cls(
            K=K,
            dist=yaml_array(data, "dist", (5,)),
            rvec=yaml_array(data, "rvec", (3,)),
            tvec=yaml_array(data, "tvec", (3,)),
            image_size=(int(size[0]), int(size[1])),
            marker_height=yaml_number(data, "marker_height", "", positive=True),
        )

    def save(self, path: Path | str) -> None:
        """Write the calibration to the YAML file ``path``."""
        with open(path, "w", encoding="utf-8") as f:
            f.write("# aes-swarm overhead camera calibration (aes_ros.tracking.calibration)\n")
            yaml.safe_dump(self.to_dict(), f, sort_keys=False)

    @classmethod
    def load(cls, path: Path | str) -> Calibration:
        """The calibration in the YAML file ``path``; :class:`CalibrationError` naming the
        field if one is missing, mis-shaped or not finite."""
        try:
            return cls.from_dict(read_yaml(path))
        except CalibrationError as exc:
            raise CalibrationError(f"{path}: {exc}") from None


@dataclass(frozen=True, eq=False)
class Residuals:
    """How well a calibration fits its reference markers, per marker seen.

    ids : (K,) the reference markers used. reprojection_px : (K,) RMS over the
    4 corners of |projected − detected| [px]. arena_mm : (K,) RMS over the 4
    corners of |detected corner mapped to the floor − its known place| [mm].
    missing : reference ids of the layout not found in the image.
    """

    ids: np.ndarray
    reprojection_px: np.ndarray
    arena_mm: np.ndarray
    missing: tuple[int, ...] = ()

    def __str__(self) -> str:
        text = (
            f"{len(self.ids)} reference markers, reprojection RMS "
            f"{_rms(self.reprojection_px):.3f} px (max {self.reprojection_px.max():.3f}), "
            f"arena RMS {_rms(self.arena_mm):.2f} mm (max {self.arena_mm.max():.2f})"
        )
        return text + (f", missing ids {list(self.missing)}" if self.missing else "")


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values)))) if len(values) else math.nan


def _check_spread(ids: Sequence[int], centres: np.ndarray) -> None:
    """Refuse references that lie (nearly) on one line: the pose about it is then ill-posed."""
    centred = centres - centres.mean(axis=0)
    along, across = np.sqrt(np.linalg.svd(centred, compute_uv=False) ** 2 / len(centres))
    if across < MIN_SPREAD_RATIO * along:
        raise CalibrationError(
            f"the reference markers found (ids {list(ids)}) lie nearly on one line: their "
            f"spread across it is {across:.3f} m against {along:.3f} m along it (need at "
            f"least {MIN_SPREAD_RATIO:.0%}); place or uncover one away from that line"
        )


def calibrate(
    image: np.ndarray,
    K: np.ndarray,
    dist: np.ndarray,
    layout: ArenaLayout,
    *,
    detections: Detections | None = None,
) -> tuple[Calibration, Residuals]:
    """The camera's pose from the reference markers in one image.

    Parameters
    ----------
    image : (H, W) mono8 frame showing the reference markers.
    K : (3, 3) camera matrix [px]; dist : (5,) plumb_bob distortion (camera_info).
    layout : the reference markers' known places.
    detections : markers already detected in ``image`` (default: detect them).

    Returns
    -------
    The calibration and the per-marker :class:`Residuals`.

    Raises
    ------
    CalibrationError
        fewer than :data:`MIN_REFERENCES` reference markers found (the message
        lists the missing ids), the ones found lie nearly on one line, or no
        pose fits them.
    """
    img = np.asarray(image)
    if img.ndim != 2:
        raise CalibrationError(f"image: expected a mono8 (H, W) array, got shape {img.shape}")
    size = (img.shape[1], img.shape[0])
    found = detect_markers(img) if detections is None else detections
    wanted = set(layout.ids)
    seen = [i for i in found.ids.tolist() if i in wanted]
    missing = tuple(sorted(wanted - set(seen)))
    if len(seen) < MIN_REFERENCES:
        raise CalibrationError(
            f"found {len(seen)} of the {len(wanted)} reference markers (ids {sorted(seen)}), "
            f"need at least {MIN_REFERENCES}; missing ids {list(missing)}"
            + (f" (seen twice: {list(found.duplicates)})" if found.duplicates else "")
            + (f" (cut by the image border: {list(found.at_border)})" if found.at_border else "")
        )
    refs = [layout.reference(i) for i in seen]
    _check_spread(seen, np.array([(r.x, r.y) for r in refs]))
    object_pts = np.concatenate([r.corners() for r in refs])  # (4K, 3), z = 0
    rows = [int(np.flatnonzero(found.ids == i)[0]) for i in seen]
    image_pts = found.corners[rows].reshape(-1, 2)
    K = np.asarray(K, dtype=float)
    dist = np.asarray(dist, dtype=float).reshape(-1)
    ok, rvec, tvec = cv2.solvePnP(object_pts, image_pts, K, dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise CalibrationError(f"no camera pose fits the reference markers {seen}")
    rvec, tvec = cv2.solvePnPRefineLM(object_pts, image_pts, K, dist, rvec, tvec)
    calibration = Calibration(
        K, dist, rvec.ravel(), tvec.ravel(), size, marker_height=layout.marker_height
    )
    if calibration.camera.center[2] <= 0.0:
        raise CalibrationError(
            f"the camera pose fitted to the reference markers {seen} is below the floor"
        )
    projected = calibration.camera.project(object_pts)
    reprojection = np.linalg.norm(projected - image_pts, axis=-1).reshape(-1, 4)
    on_floor = calibration.image_to_arena(image_pts, 0.0)
    arena = np.linalg.norm(on_floor - object_pts[:, :2], axis=-1).reshape(-1, 4)
    residuals = Residuals(
        ids=np.array(seen),
        reprojection_px=np.sqrt(np.mean(reprojection**2, axis=1)),
        arena_mm=1e3 * np.sqrt(np.mean(arena**2, axis=1)),
        missing=missing,
    )
    return calibration, residuals

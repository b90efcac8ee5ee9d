"""The camera's pose over the arena, from reference markers on the floor (SPEC §8).

- :func:`load_layout` reads ``arena.yaml``: the reference markers (id, centre,
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

``arena.yaml``::

    marker_height: 0.038          # [m] the robots' marker plane (optional, 0.038)
    arena: [-1.0, 1.0, -0.75, 0.75]   # [m] x_min x_max y_min y_max (optional)
    references:                   # at least 3, not on one line
      - {id: 249, x: -0.95, y: -0.70, size: 0.10}      # [m]; yaw [rad] optional
      - {id: 248, x: 0.95, y: -0.70, size: 0.10}
      - {id: 247, x: 0.95, y: 0.70, size: 0.10, yaw: 0.0}
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from aes_ros.arena import arena_or_none
from aes_ros.camera import PinholeCamera
from aes_ros.markers import N_IDS, ReferenceMarker, RobotMarker, reference_ids
from aes_ros.params import ParameterError
from tracker_node.detection import Detections, detect_markers

#: The fewest reference markers a calibration accepts.
MIN_REFERENCES = 3
#: The seen references' spread across their best-fit line, relative to their
#: spread along it, below which they count as (nearly) on one line.
MIN_SPREAD_RATIO = 0.1


class CalibrationError(ValueError):
    """A calibration or layout that cannot be used; the message says what is wrong."""


# --- validation --------------------------------------------------------------------------


def _number(data: Mapping[str, Any], key: str, where: str, *, positive: bool = False) -> float:
    if key not in data:
        raise CalibrationError(f"{where}{key}: missing (expected a number)")
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CalibrationError(f"{where}{key}: expected a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or (positive and value <= 0.0):
        kind = "a finite number > 0" if positive else "a finite number"
        raise CalibrationError(f"{where}{key}: expected {kind}, got {value!r}")
    return value


def _array(
    data: Mapping[str, Any], key: str, shape: tuple[int, ...], where: str = ""
) -> np.ndarray:
    if len(shape) == 1:
        what = f"a list of {shape[0]} finite numbers"
    else:
        what = f"a {shape[0]}x{shape[1]} list of lists of finite numbers"
    if key not in data:
        raise CalibrationError(f"{where}{key}: missing (expected {what})")
    value = data[key]
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise CalibrationError(f"{where}{key}: expected {what}, got {value!r}") from None
    if arr.shape != shape or not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{where}{key}: expected {what}, got {value!r}")
    return arr


def _mapping(data: Any, what: str) -> Mapping[str, Any]:
    if not isinstance(data, Mapping):
        raise CalibrationError(f"{what}: expected a mapping of fields, got {type(data).__name__}")
    return data


def _read_yaml(path: Path | str) -> Any:
    try:
        with open(path, encoding="utf-8") as f:
            return yaml.safe_load(f)
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot read ({exc.strerror})") from exc
    except yaml.YAMLError as exc:
        raise CalibrationError(f"{path}: not YAML ({exc})") from exc


# --- the layout --------------------------------------------------------------------------


@dataclass(frozen=True)
class ArenaLayout:
    """What is known of the arena: reference markers, the robots' marker height, its extent.

    references : the reference markers lying on the floor.
    marker_height : height of the robots' marker plane [m].
    arena : (x_min, x_max, y_min, y_max) [m] or None.
    """

    references: tuple[ReferenceMarker, ...]
    marker_height: float = RobotMarker().height
    arena: tuple[float, float, float, float] | None = None

    def reference(self, marker_id: int) -> ReferenceMarker:
        """The reference marker with id ``marker_id`` (KeyError if none)."""
        for ref in self.references:
            if ref.marker_id == marker_id:
                return ref
        raise KeyError(marker_id)

    @property
    def ids(self) -> tuple[int, ...]:
        """The reference markers' ids."""
        return tuple(r.marker_id for r in self.references)


def parse_layout(data: Any, source: str = "layout") -> ArenaLayout:
    """An :class:`ArenaLayout` from parsed YAML, validated field by field."""
    data = _mapping(data, source)
    height = _number(data, "marker_height", "", positive=True) if "marker_height" in data else None
    arena = None
    if data.get("arena") is not None:
        box = _array(data, "arena", (4,))
        try:  # the rule of the supervisor's arena (aes_ros.params)
            arena = arena_or_none(box.tolist()).bounds
        except ParameterError as exc:
            raise CalibrationError(str(exc)) from None
    refs = data.get("references")
    if not isinstance(refs, Sequence) or isinstance(refs, str):
        raise CalibrationError(
            "references: missing (expected a list of {id, x, y, size[, yaw]} mappings)"
        )
    if len(refs) < MIN_REFERENCES:
        raise CalibrationError(
            f"references: expected at least {MIN_REFERENCES} reference markers, got {len(refs)}"
        )
    markers = []
    for k, item in enumerate(refs):
        where = f"references[{k}]."
        item = _mapping(item, f"references[{k}]")
        if "id" not in item:
            raise CalibrationError(f"{where}id: missing (expected a marker id 0 … {N_IDS - 1})")
        marker_id = item["id"]
        if isinstance(marker_id, bool) or not isinstance(marker_id, int):
            raise CalibrationError(f"{where}id: expected an integer, got {marker_id!r}")
        if not 0 <= marker_id < N_IDS:
            raise CalibrationError(f"{where}id: expected 0 … {N_IDS - 1}, got {marker_id}")
        yaw = _number(item, "yaw", where) if "yaw" in item else 0.0
        markers.append(
            ReferenceMarker(
                marker_id,
                _number(item, "x", where),
                _number(item, "y", where),
                _number(item, "size", where, positive=True),
                yaw,
            )
        )
    ids = [m.marker_id for m in markers]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise CalibrationError(f"references: ids {twice} appear more than once")
    kwargs = {} if height is None else {"marker_height": height}
    return ArenaLayout(tuple(markers), arena=arena, **kwargs)


def corner_layout(
    arena: Sequence[float], size: float = 0.06, outset: float = 0.05, **kwargs: Any
) -> ArenaLayout:
    """A layout with a reference marker of side ``size`` [m] off each corner of
    ``arena`` ``(x_min, x_max, y_min, y_max)`` [m], ``outset`` [m] outside it in x
    and y (where no robot drives over it), ids from :func:`reference_ids`; what the
    launch gives the simulated camera and the tracker (``kwargs``: marker_height)."""
    x0, x1, y0, y1 = (float(v) for v in arena)
    places = [(x0 - outset, y0 - outset), (x1 + outset, y0 - outset),
              (x1 + outset, y1 + outset), (x0 - outset, y1 + outset)]  # fmt: skip
    refs = tuple(
        ReferenceMarker(i, x, y, size) for i, (x, y) in zip(reference_ids(4), places, strict=True)
    )
    return ArenaLayout(refs, arena=(x0, x1, y0, y1), **kwargs)


def save_layout(layout: ArenaLayout, path: Path | str) -> Path:
    """Write ``layout`` as an ``arena.yaml`` that :func:`load_layout` reads back."""
    data: dict[str, Any] = {
        "marker_height": float(layout.marker_height),
        "references": [
            {
                "id": r.marker_id,
                "x": float(r.x),
                "y": float(r.y),
                "size": float(r.size),
                "yaw": float(r.yaw),
            }
            for r in layout.references
        ],
    }
    if layout.arena is not None:
        data["arena"] = [float(v) for v in layout.arena]
    path = Path(path)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def load_layout(path: Path | str) -> ArenaLayout:
    """The arena layout in the YAML file ``path`` (see the module docstring)."""
    try:
        return parse_layout(_read_yaml(path), str(path))
    except CalibrationError as exc:
        raise CalibrationError(f"{path}: {exc}") from None


# --- the calibration ---------------------------------------------------------------------


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
        data = _mapping(data, "calibration")
        size = _array(data, "image_size", (2,))
        if np.any(size < 1) or np.any(size != np.round(size)):
            raise CalibrationError(
                f"image_size: expected [width, height] in whole pixels >= 1, got {size.tolist()}"
            )
        K = _array(data, "K", (3, 3))
        if K[0, 0] <= 0.0 or K[1, 1] <= 0.0:
            raise CalibrationError(f"K: expected positive focal lengths, got {K.tolist()}")
        return cls(
            K=K,
            dist=_array(data, "dist", (5,)),
            rvec=_array(data, "rvec", (3,)),
            tvec=_array(data, "tvec", (3,)),
            image_size=(int(size[0]), int(size[1])),
            marker_height=_number(data, "marker_height", "", positive=True),
        )

    def save(self, path: Path | str) -> None:
        """Write the calibration to the YAML file ``path``."""
        with open(path, "w", encoding="utf-8") as f:
            f.write("# aes-swarm overhead camera calibration (tracker_node.calibration)\n")
            yaml.safe_dump(self.to_dict(), f, sort_keys=False)

    @classmethod
    def load(cls, path: Path | str) -> Calibration:
        """The calibration in the YAML file ``path``; :class:`CalibrationError` naming the
        field if one is missing, mis-shaped or not finite."""
        try:
            return cls.from_dict(_read_yaml(path))
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

"""A camera's intrinsics in the YAML layout ROS camera drivers read and write.

This is the file ``camera_calibration`` (the ROS checkerboard calibrator) saves and
``camera_info_manager`` loads (``image_width``, ``image_height``, ``camera_name``,
``camera_matrix``, ``distortion_model``, ``distortion_coefficients``, ...), so a lab
can hand ``aes-swarm calibrate`` and ``aes-tracker --source`` the file it already has
for its camera. Only the plumb_bob model is read (OpenCV's ``k1 k2 p1 p2 k3``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from aes_ros.arena_layout import CalibrationError, read_yaml, yaml_mapping
from aes_ros.camera import CameraInfo


def save_camera_info(info: CameraInfo, path: Path | str, name: str = "arena_camera") -> Path:
    """Write ``info`` as a ROS camera_info YAML file."""

    def matrix(rows: int, cols: int, data: Any) -> dict[str, Any]:
        return {"rows": rows, "cols": cols, "data": [float(v) for v in data]}

    data = {
        "image_width": int(info.width),
        "image_height": int(info.height),
        "camera_name": name,
        "camera_matrix": matrix(3, 3, info.k),
        "distortion_model": info.distortion_model,
        "distortion_coefficients": matrix(1, len(info.d), info.d),
        "rectification_matrix": matrix(3, 3, info.r),
        "projection_matrix": matrix(3, 4, info.p),
    }
    path = Path(path)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def intrinsics(k: Sequence[float], d: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """K (3, 3) [px] and the plumb_bob distortion (5,) (zeros where ``d`` is shorter)
    of a camera_info's ``k`` (9, row-major) and ``d``; CalibrationError for non-finite
    values or a focal length that is not > 0 (what no tracker can map through)."""
    K = np.asarray(k, dtype=float).reshape(3, 3)
    dist = np.zeros(5)
    dist[: min(5, len(d))] = np.asarray(d, dtype=float)[:5]
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(dist))):
        raise CalibrationError("non-finite intrinsics or distortion")
    if K[0, 0] <= 0.0 or K[1, 1] <= 0.0:
        raise CalibrationError(f"focal length {K[0, 0]:g}, {K[1, 1]:g} px; need > 0")
    return K, dist


def load_camera_info(path: Path | str) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """(K (3, 3) [px], dist (5,), (width, height) [px]) of a ROS camera_info YAML file.

    Raises CalibrationError naming the field for a missing, mis-shaped, non-finite or
    impossible value (a focal length <= 0, a model other than plumb_bob).
    """
    data = yaml_mapping(read_yaml(path), f"{path}")

    def field(name: str, size: int) -> np.ndarray:
        value = data.get(name)
        values = value.get("data") if isinstance(value, dict) else None
        try:
            out = np.asarray(values, dtype=float).ravel()
        except (TypeError, ValueError):
            out = np.zeros(0)
        if values is None or len(out) != size or not np.all(np.isfinite(out)):
            raise CalibrationError(
                f"{path}: {name}: expected {{rows, cols, data: [{size} finite numbers]}}"
            )
        return out

    size = []
    for name in ("image_width", "image_height"):
        value = data.get(name)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise CalibrationError(f"{path}: {name}: expected a whole number of pixels >= 1")
        size.append(value)
    model = data.get("distortion_model", "plumb_bob")
    if model != "plumb_bob":
        raise CalibrationError(f"{path}: distortion_model: {model!r}; only plumb_bob is read")
    coefficients = data.get("distortion_coefficients", {"data": [0.0] * 5})
    count = len(coefficients.get("data") or []) if isinstance(coefficients, dict) else 0
    d = field("distortion_coefficients", count) if count else ()
    try:
        K, dist = intrinsics(field("camera_matrix", 9), d)
    except CalibrationError as exc:
        raise CalibrationError(f"{path}: camera_matrix: {exc}") from None
    return K, dist, (size[0], size[1])

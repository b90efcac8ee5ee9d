"""Pinhole camera geometry shared by the simulated overhead camera and the tracker.

See docs/design.md#tracking.

One model, OpenCV's: a world point ``X`` [m; arena frame] is seen at
``x_c = R X + t`` in the camera frame (x right, y down in the image, z along
the optical axis), then at the normalised point ``(x_c / z_c, y_c / z_c)``,
distorted by the ``plumb_bob`` model ``(k1, k2, p1, p2, k3)`` and mapped by
``K`` to pixels. Pixel centres are at integer coordinates, so the centre of a
``W × H`` image is ``((W - 1) / 2, (H - 1) / 2)``.

The arena frame is REP-103: x east, y north, z up. A camera built by
:func:`overhead_camera` looks straight down and shows the arena like a map:
image right = arena +x, image up = arena +y; its y axis points to arena −y
and its optical axis to arena −z.

:class:`PinholeCamera` projects (:meth:`~PinholeCamera.project`) and back-projects
onto a horizontal plane (:meth:`~PinholeCamera.image_to_plane`, which the
tracker uses with the plane of the markers); :class:`CameraInfo` is the plain
form of its intrinsics that a node turns into ``sensor_msgs/CameraInfo``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

#: undistortPoints iterates to convergence (its default is 5 fixed iterations, which
#: leaves a visible error towards the corners of a distorted image).
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9)


def _frozen_array(value: object, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.array(value, dtype=float).reshape(-1) if len(shape) == 1 else np.array(value, float)
    if arr.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {np.shape(value)}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: must be finite, got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class CameraInfo:
    """A camera's intrinsics in the fields of ``sensor_msgs/CameraInfo``.

    ``sensor_msgs.msg.CameraInfo(**dataclasses.asdict(info))`` builds the message
    (the header is the node's to fill). ``k`` (9) and ``p`` (12) are row-major;
    ``r`` is the identity (a monocular camera).
    """

    width: int
    height: int
    distortion_model: str
    d: tuple[float, ...]
    k: tuple[float, ...]
    r: tuple[float, ...]
    p: tuple[float, ...]

    @property
    def camera_matrix(self) -> np.ndarray:
        """K (3, 3) [px]."""
        return np.array(self.k, dtype=float).reshape(3, 3)

    @property
    def distortion(self) -> np.ndarray:
        """D (5,): ``k1 k2 p1 p2 k3``."""
        return np.array(self.d, dtype=float)


@dataclass(frozen=True, eq=False)
class PinholeCamera:
    """A calibrated camera: intrinsics and its pose in the arena.

    Parameters
    ----------
    width, height : image size [px].
    K : (3, 3) camera matrix [px].
    dist : (5,) plumb_bob distortion ``k1 k2 p1 p2 k3`` (OpenCV's order).
    rvec, tvec : (3,) world→camera rotation (Rodrigues vector) and translation
        [m]: ``x_cam = R(rvec) X_world + tvec``.

    The arrays are stored read-only, so the camera can be shared freely.
    """

    width: int
    height: int
    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))
    rvec: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tvec: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        if int(self.width) < 1 or int(self.height) < 1:
            raise ValueError(f"image size: expected positive, got {self.width} x {self.height}")
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))
        object.__setattr__(self, "K", _frozen_array(self.K, (3, 3), "K"))
        object.__setattr__(self, "dist", _frozen_array(self.dist, (5,), "dist"))
        object.__setattr__(self, "rvec", _frozen_array(self.rvec, (3,), "rvec"))
        object.__setattr__(self, "tvec", _frozen_array(self.tvec, (3,), "tvec"))

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` [px], OpenCV's order."""
        return self.width, self.height

    @property
    def rotation(self) -> np.ndarray:
        """R (3, 3): the world→camera rotation matrix."""
        return cv2.Rodrigues(self.rvec)[0]

    @property
    def center(self) -> np.ndarray:
        """The camera's optical centre (3,) [m; arena frame]."""
        return -self.rotation.T @ self.tvec

    @property
    def distorted(self) -> bool:
        """True when any distortion coefficient is non-zero."""
        return bool(np.any(self.dist != 0.0))

    def undistorted(self) -> PinholeCamera:
        """The same camera with its distortion coefficients set to zero."""
        return replace(self, dist=np.zeros(5))

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels ``(..., 2)`` [px] of arena points ``(..., 3)`` [m], distortion included.

        OpenCV's model (:func:`cv2.projectPoints`, which the tests compare it
        with) written in numpy: ``cv2.projectPoints`` also fills its Jacobian,
        which costs 3 ms for the 5000 points of 100 robots' outlines, this 0.2 ms.
        Points must lie in front of the camera (an overhead camera sees the
        whole floor in front of it).
        """
        pts = np.asarray(points, dtype=float)
        cam = pts @ self.rotation.T + self.tvec
        x = cam[..., 0] / cam[..., 2]
        y = cam[..., 1] / cam[..., 2]
        if self.distorted:
            k1, k2, p1, p2, k3 = self.dist
            r2 = x * x + y * y
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            x, y = (
                x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
            )
        K = self.K
        return np.stack([K[0, 0] * x + K[0, 1] * y + K[0, 2], K[1, 1] * y + K[1, 2]], axis=-1)

    def normalized_rays(self, points_px: np.ndarray) -> np.ndarray:
        """Directions ``(M, 3)`` [arena frame, not unit] of the rays through pixels ``(M, 2)``.

        Undistorts with OpenCV's iterative inverse, run to convergence.
        """
        px = np.asarray(points_px, dtype=float).reshape(-1, 1, 2)
        if len(px) == 0:
            return np.zeros((0, 3))
        xy = cv2.undistortPoints(px, self.K, self.dist, criteria=_UNDISTORT_CRITERIA)
        rays_cam = np.concatenate([xy.reshape(-1, 2), np.ones((len(px), 1))], axis=1)
        return rays_cam @ self.rotation  # = (R^T @ ray)^T for each ray

    def image_to_plane(self, points_px: np.ndarray, z: float = 0.0) -> np.ndarray:
        """Arena points ``(M, 2)`` [m] seen at pixels ``(M, 2)``, on the horizontal plane at ``z``.

        The inverse of :meth:`project` for points known to lie at height ``z`` [m]:
        undistort, then intersect the pixel's ray from :attr:`center` with the
        plane. ``z`` is the height of what is seen (0 for the floor, the marker
        height for a robot's marker), so the parallax of raised markers is
        removed. A ray parallel to the plane gives NaN.
        """
        rays = self.normalized_rays(points_px)
        c = self.center
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (float(z) - c[2]) / rays[:, 2]
        s = np.where(np.isfinite(s) & (s > 0.0), s, np.nan)
        return c[:2] + s[:, None] * rays[:, :2]

    def camera_info(self) -> CameraInfo:
        """The intrinsics as :class:`CameraInfo` (``plumb_bob``, P = [K | 0])."""
        p = np.zeros((3, 4))
        p[:, :3] = self.K
        return CameraInfo(
            width=self.width,
            height=self.height,
            distortion_model="plumb_bob",
            d=tuple(float(v) for v in self.dist),
            k=tuple(float(v) for v in self.K.ravel()),
            r=tuple(float(v) for v in np.eye(3).ravel()),
            p=tuple(float(v) for v in p.ravel()),
        )


def intrinsics(width_px: int, height_px: int, hfov_deg: float) -> np.ndarray:
    """Camera matrix (3, 3) of square pixels, horizontal field of view ``hfov_deg``,
    principal point at the image centre ``((W - 1) / 2, (H - 1) / 2)``."""
    if not 0.0 < hfov_deg < 180.0:
        raise ValueError(f"hfov_deg: expected in (0, 180), got {hfov_deg}")
    f = 0.5 * width_px / math.tan(math.radians(0.5 * hfov_deg))
    return np.array([[f, 0.0, 0.5 * (width_px - 1)], [0.0, f, 0.5 * (height_px - 1)], [0, 0, 1]])


def overhead_camera(
    center_xy: Sequence[float],
    height_m: float,
    width_px: int,
    height_px: int,
    hfov_deg: float,
    distortion: Sequence[float] = (0.0,) * 5,
    *,
    tilt_deg: Sequence[float] = (0.0, 0.0),
    roll_deg: float = 0.0,
) -> PinholeCamera:
    """A camera ``height_m`` [m] above the floor point ``center_xy`` [m], looking down.

    Untilted, image right = arena +x and image up = arena +y. ``tilt_deg`` turns
    the camera about its own x then y axis [deg] (a mount that is not quite
    level), ``roll_deg`` about its optical axis [deg]; the optical centre stays
    where it is. ``distortion`` is the plumb_bob ``(k1, k2, p1, p2, k3)``.

    Notes
    -----
    The world→camera rotation of the level camera is ``diag(1, -1, -1)``; the
    tilts are applied in the camera frame, ``R = R_z(roll) R_y(ty) R_x(tx) diag(1, -1, -1)``.
    """
    level = np.diag([1.0, -1.0, -1.0])
    tx, ty = (math.radians(float(a)) for a in tilt_deg)
    rz = math.radians(float(roll_deg))
    turn = (
        cv2.Rodrigues(np.array([0.0, 0.0, rz]))[0]
        @ cv2.Rodrigues(np.array([0.0, ty, 0.0]))[0]
        @ cv2.Rodrigues(np.array([tx, 0.0, 0.0]))[0]
    )
    R = turn @ level
    center = np.array([float(center_xy[0]), float(center_xy[1]), float(height_m)])
    return PinholeCamera(
        width=width_px,
        height=height_px,
        K=intrinsics(width_px, height_px, hfov_deg),
        dist=np.asarray(distortion, dtype=float),
        rvec=cv2.Rodrigues(R)[0].ravel(),
        tvec=-R @ center,
    )


def covering_height(
    extent_m: Sequence[float], width_px: int, height_px: int, hfov_deg: float
) -> float:
    """Height [m] at which a level :func:`overhead_camera` just sees a floor rectangle.

    ``extent_m`` is its (width, depth) [m] along arena x and y (add a margin to
    keep the robots at the edge whole); the tighter of the two directions sets it.
    """
    K = intrinsics(width_px, height_px, hfov_deg)
    f = K[0, 0]
    return max(f * float(extent_m[0]) / width_px, f * float(extent_m[1]) / height_px)

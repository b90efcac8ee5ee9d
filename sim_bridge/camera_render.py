"""The simulated overhead camera: mono8 images of the robots' markers (docs/design.md#tracking).

What a real camera above the arena would see, drawn through the camera model
of :mod:`aes_ros.camera` (so the tracker is tested against the geometry it
assumes, height parallax included): a mid-grey floor, the scenario's walls and
obstacles as dark solids without a marker (:mod:`sim_bridge.arena`; nothing a tracker
takes for a robot), the fixed reference markers (drawn over them: a lab puts its
references where the camera sees them), and each robot as a dark Ø 80 mm cylinder
with its marker on top (:mod:`aes_ros.markers`). The imperfections a real camera has
are options: lens distortion (the camera's ``dist``), Gaussian blur and Gaussian pixel
noise, the noise drawn from a ``numpy.random.Generator``.

How it is fast (``bench/bench_camera_render.py`` measures it against
pybullet's own camera):

- the floor, the reference markers, walls and obstacles never move: drawn once;
- each robot's top (body, white sticker, marker) is a pre-rendered patch per
  id (:mod:`sim_bridge.camera_patches`), warped by its homography into only its bounding box
  (``cv2.warpPerspective`` on the ROI) and alpha-blended there;
- the robots are drawn on an undistorted canvas, then distorted by
  ``cv2.remap`` through a map computed at construction, again only around each
  robot: the rest of the frame is the background, distorted once (a full-frame
  remap costs 13 ms at 2048 × 1536, measured; 100 robots' boxes 2-3 ms);
- the noise is drawn at construction: two frames' worth of ``rng`` samples,
  from which each frame takes a window at a random offset (one
  ``rng.standard_normal`` per frame costs 20-60 ms at these sizes, more than
  everything else together). ``fresh_noise=True`` draws every frame anew.

Drawing order: the floor, walls and obstacles, the references, every robot's body silhouette
(the hull of its projected top and bottom circles), then every robot's top,
the highest surface, so a neighbour's side never covers a marker.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from aes_ros.camera import PinholeCamera
from aes_ros.contacts import contact_geometry
from aes_ros.markers import (
    DICTIONARY,
    N_IDS,
    ReferenceMarker,
    RobotMarker,
    marker_centres,
    marker_corners,
    marker_image,
)
from sim_bridge.arena import solid_outlines
from sim_bridge.camera_patches import SHIFT, Patch, Shades, reference_patch, robot_patch
from sim_bridge.mona import MonaGeometry

#: Points per circle of a body's silhouette.
_CIRCLE_POINTS = 24
#: Patch texels per image pixel. With one texel per pixel, the bilinear warp of a
#: sharp patch moved edges by up to 0.07 px with their sub-pixel phase (measured);
#: three, pre-filtered by a pixel's footprint, leave ~0.01 px.
_OVERSAMPLE = 3


def _coarse_distortion_map(camera: PinholeCamera, step: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """For every pixel of ``camera`` the undistorted pixel it sees (float32 maps (H, W)).

    ``cv2.undistortPoints`` on a grid every ``step`` px (one grid point beyond
    each edge), resized to full resolution: the map is smooth, so this costs a
    64th of undistorting every pixel for ~1e-3 px of error at mild distortion.
    """
    w, h = camera.size
    gx = (np.arange(-1, math.ceil(w / step) + 1) + 0.5) * step - 0.5
    gy = (np.arange(-1, math.ceil(h / step) + 1) + 0.5) * step - 0.5
    u, v = np.meshgrid(gx, gy)
    pts = np.stack([u.ravel(), v.ravel()], axis=-1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9)
    ideal = cv2.undistortPoints(pts, camera.K, camera.dist, P=camera.K, criteria=crit)
    ideal = ideal.reshape(len(gy), len(gx), 2).astype(np.float32)
    size = (len(gx) * step, len(gy) * step)
    full = cv2.resize(ideal, size, interpolation=cv2.INTER_LINEAR)
    full = full[step : step + h, step : step + w]
    return np.ascontiguousarray(full[..., 0]), np.ascontiguousarray(full[..., 1])


class CameraRenderer:
    """Renders what an overhead camera sees of the robots (mono8, (H, W) uint8).

    Parameters
    ----------
    camera : the camera (size, intrinsics, distortion, pose in the arena).
    references : reference markers lying on the floor (drawn in every frame).
    marker : how the robots wear their markers (size, height, offset);
        default :class:`~aes_ros.markers.RobotMarker`.
    geometry : the robot's body (radius, height, ground clearance); default
        :class:`~sim_bridge.mona.MonaGeometry`.
    noise_sigma : Gaussian pixel noise [grey levels], 0 for none.
    blur_sigma : Gaussian blur [px] (focus, motion), 0 for none.
    rng : the noise's source: None, an int seed or a ``numpy.random.Generator``.
    fresh_noise : draw the noise anew every frame instead of a window into
        noise drawn once (exact, but 20-60 ms per frame).
    shades : grey levels of floor, body, white and black.
    dictionary_id : the ArUco dictionary (the convention's by default).
    walls, circles, boxes : the arena's walls (4,) or None, circles (M, 3) and boxes
        (L, 4) [m], as :func:`aes_ros.contacts.resolve_contacts` takes them.
    """

    def __init__(
        self,
        camera: PinholeCamera,
        *,
        references: Sequence[ReferenceMarker] = (),
        marker: RobotMarker | None = None,
        geometry: MonaGeometry | None = None,
        noise_sigma: float = 0.0,
        blur_sigma: float = 0.0,
        rng: np.random.Generator | int | None = None,
        fresh_noise: bool = False,
        shades: Shades = Shades(),
        dictionary_id: int = DICTIONARY,
        walls: np.ndarray | None = None,
        circles: np.ndarray | None = None,
        boxes: np.ndarray | None = None,
    ) -> None:
        if not (noise_sigma >= 0.0 and blur_sigma >= 0.0):
            raise ValueError("noise_sigma, blur_sigma: expected >= 0")
        self.camera = camera
        self.marker = marker = marker or RobotMarker()
        self.geometry = geometry = geometry or MonaGeometry()
        self.noise_sigma = float(noise_sigma)
        self.blur_sigma = float(blur_sigma)
        self.fresh_noise = fresh_noise
        self.shades = shades
        self.dictionary_id = dictionary_id
        self.rng = np.random.default_rng(rng)
        self._cells = marker_image(0, 1, dictionary_id).shape[0]
        self._n_ids = cv2.aruco.getPredefinedDictionary(dictionary_id).bytesList.shape[0]

        if camera.distorted:
            mx, my = _coarse_distortion_map(camera)
            ox = max(0, math.ceil(-float(mx.min())) + 2)
            oy = max(0, math.ceil(-float(my.min())) + 2)
            cw = math.ceil(float(mx.max())) + ox + 3
            ch = math.ceil(float(my.max())) + oy + 3
            K = camera.K.copy()
            K[0, 2] += ox
            K[1, 2] += oy
            self._ideal = PinholeCamera(cw, ch, K, np.zeros(5), camera.rvec, camera.tvec)
            # float32 maps: measured faster here than convertMaps' CV_16SC2 (2.2 vs 3.9 ms
            # for a full 1280 x 960 frame)
            self._map = (mx + ox, my + oy)
        else:
            self._ideal = camera
            self._map = None

        self._robot_patches: dict[int, Patch] = {}
        self._texels = self._texels_per_cell(marker.size, marker.height)
        # the silhouette: circles at the bottom and the top of the body, around its axis
        a = np.linspace(0.0, 2.0 * math.pi, _CIRCLE_POINTS, endpoint=False)
        ring = geometry.body_radius * np.stack([np.cos(a), np.sin(a)], axis=-1)
        bottom, top = geometry.ground_clearance, geometry.ground_clearance + geometry.body_height
        self._ring = np.concatenate(
            [np.c_[ring, np.full(len(a), bottom)], np.c_[ring, np.full(len(a), top)]]
        )

        self._ideal_background = np.full(
            (self._ideal.height, self._ideal.width), shades.floor, np.uint8
        )
        self._draw_solids(*contact_geometry(walls, circles, boxes))
        for ref in references:
            if not 0 <= ref.marker_id < self._n_ids:
                raise ValueError(f"reference marker_id: expected 0 … {self._n_ids - 1}")
            texels, per_px = self._texels_per_cell(ref.size, 0.0)
            patch = reference_patch(ref.marker_id, texels, ref.size, per_px, shades, dictionary_id)
            corners = self._ideal.project(marker_corners(ref.x, ref.y, ref.yaw, 0.0, patch.side))
            self._blend(self._ideal_background, patch, corners)
        self._background = self._ideal_background
        if self._map is not None:
            self._background = cv2.remap(self._ideal_background, *self._map, cv2.INTER_LINEAR)

        self._noise: tuple[np.ndarray, np.ndarray] | None = None
        if self.noise_sigma > 0.0 and not fresh_noise:
            self._noise = self._draw_noise(2 * camera.width * camera.height)

    def _draw_solids(self, walls: np.ndarray, circles: np.ndarray, boxes: np.ndarray) -> None:
        """Walls and obstacles into the background: each the hull of its projected outlines."""
        big = float(1 << SHIFT)
        for outline in solid_outlines(walls, circles, boxes):
            px = self._ideal.project(outline)
            if not np.isfinite(px).all():
                continue  # reaches behind the camera: not drawn
            hull = cv2.convexHull(np.rint(px * big).astype(np.int32))
            cv2.fillConvexPoly(
                self._ideal_background, hull, self.shades.obstacle, cv2.LINE_AA, SHIFT
            )

    def _texels_per_cell(self, size: float, z: float) -> tuple[int, float]:
        """Patch texels per marker cell (about ``_OVERSAMPLE`` per image pixel at the image
        centre) and the texels per pixel that gives."""
        depth = float(self._ideal.center[2]) - z
        px_per_cell = self._ideal.K[0, 0] * size / self._cells / max(depth, 1e-9)
        texels = max(2, round(_OVERSAMPLE * px_per_cell))
        return texels, texels / px_per_cell

    def _draw_noise(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``n`` samples of rounded Gaussian noise as (positive part, negative part) uint8."""
        noise = np.rint(self.rng.standard_normal(n, dtype=np.float32) * self.noise_sigma)
        noise = np.clip(noise, -255, 255)
        return np.maximum(noise, 0).astype(np.uint8), np.maximum(-noise, 0).astype(np.uint8)

    def _patch(self, marker_id: int) -> Patch:
        patch = self._robot_patches.get(marker_id)
        if patch is None:
            patch = robot_patch(
                marker_id,
                self.marker,
                self.geometry.body_radius,
                *self._texels,
                self.shades,
                self.dictionary_id,
            )
            self._robot_patches[marker_id] = patch
        return patch

    @staticmethod
    def _blend(canvas: np.ndarray, patch: Patch, corners_px: np.ndarray) -> None:
        """Warp ``patch`` so its corners land on ``corners_px (4, 2)`` and blend it in."""
        h, w = canvas.shape
        x0 = max(math.floor(float(corners_px[:, 0].min())) - 1, 0)
        y0 = max(math.floor(float(corners_px[:, 1].min())) - 1, 0)
        x1 = min(math.ceil(float(corners_px[:, 0].max())) + 2, w)
        y1 = min(math.ceil(float(corners_px[:, 1].max())) + 2, h)
        if x1 <= x0 or y1 <= y0:
            return
        n = patch.image.shape[0]
        src = np.array([[-0.5, -0.5], [n - 0.5, -0.5], [n - 0.5, n - 0.5], [-0.5, n - 0.5]])
        dst = corners_px - (x0, y0)
        H = cv2.getPerspectiveTransform(src.astype(np.float32), dst.astype(np.float32))
        warped = cv2.warpPerspective(
            patch.image, H, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR, borderValue=0
        )
        value, alpha = cv2.split(warped)
        roi = canvas[y0:y1, x0:x1]
        # roi <- roi (1 - alpha) + premultiplied value, in saturating uint8 arithmetic
        cv2.subtract(roi, cv2.multiply(roi, alpha, scale=1.0 / 255.0), dst=roi)
        cv2.add(roi, value, dst=roi)

    def render(
        self, positions: np.ndarray, headings: np.ndarray, ids: np.ndarray | None = None
    ) -> np.ndarray:
        """One frame, mono8 ``(H, W)`` uint8.

        Parameters
        ----------
        positions : (N, 2) ``base_link`` positions [m; arena frame] (what
            ``/sim/ground_truth/poses`` carries; the marker is drawn
            ``marker.offset`` ahead, on the body's axis).
        headings : (N,) [rad].
        ids : (N,) marker ids, default ``0 … N-1`` (robot i wears id i).
        """
        positions = np.asarray(positions, dtype=float).reshape(-1, 2)
        headings = np.asarray(headings, dtype=float).reshape(-1)
        n = len(positions)
        if len(headings) != n:
            raise ValueError(f"headings: expected ({n},), got {headings.shape}")
        ids = np.arange(n) if ids is None else np.asarray(ids, dtype=int).reshape(-1)
        if len(ids) != n:
            raise ValueError(f"ids: expected ({n},), got {ids.shape}")
        if n and (ids.min() < 0 or ids.max() >= min(self._n_ids, N_IDS)):
            raise ValueError(f"ids: expected 0 … {self._n_ids - 1}, got {ids.tolist()}")
        if n == 0:
            frame = self._background.copy()
        elif self._map is None:
            frame = self._background.copy()
            self._draw_robots(frame, positions, headings, ids)
        else:
            frame = self._distorted_frame(positions, headings, ids)
        if self.blur_sigma > 0.0:
            frame = cv2.GaussianBlur(frame, (0, 0), self.blur_sigma)
        if self.noise_sigma > 0.0:
            self._add_noise(frame)
        return frame

    def _distorted_frame(
        self, positions: np.ndarray, headings: np.ndarray, ids: np.ndarray
    ) -> np.ndarray:
        """The robots drawn undistorted, then remapped around each robot only: the rest of
        the distorted frame is the background, distorted once at construction."""
        ideal = self._ideal_background.copy()
        centres = self._draw_robots(ideal, positions, headings, ids)
        frame = self._background.copy()
        outlines = self.camera.project(self._outlines(centres))  # (N, 2 * points, 2)
        lo = np.floor(outlines.min(axis=1)).astype(int) - 2
        hi = np.ceil(outlines.max(axis=1)).astype(int) + 3
        lo = np.maximum(lo, 0)
        hi = np.minimum(hi, (self.camera.width, self.camera.height))
        mx, my = self._map
        for (x0, y0), (x1, y1) in zip(lo.tolist(), hi.tolist(), strict=True):
            if x1 > x0 and y1 > y0:
                frame[y0:y1, x0:x1] = cv2.remap(
                    ideal, mx[y0:y1, x0:x1], my[y0:y1, x0:x1], cv2.INTER_LINEAR
                )
        return frame

    def _outlines(self, centres: np.ndarray) -> np.ndarray:
        """Points (N, 2 * points, 3) [m] of the bottom and top circles of the bodies."""
        return self._ring[None, :, :] + np.c_[centres, np.zeros(len(centres))][:, None, :]

    def _draw_robots(
        self, canvas: np.ndarray, positions: np.ndarray, headings: np.ndarray, ids: np.ndarray
    ) -> np.ndarray:
        """Draw the robots on an undistorted canvas; returns their marker centres (N, 2) [m]."""
        centres = marker_centres(positions, headings, self.marker.offset)
        side = self._patch(int(ids[0])).side
        corners = marker_corners(
            centres[:, 0], centres[:, 1], headings, self.marker.height, side
        )  # (N, 4, 3)
        px = self._ideal.project(np.concatenate([corners, self._outlines(centres)], axis=1))
        big = float(1 << SHIFT)
        for outline in px[:, 4:]:
            hull = cv2.convexHull(np.rint(outline * big).astype(np.int32))
            cv2.fillConvexPoly(canvas, hull, self.shades.body, cv2.LINE_AA, SHIFT)
        for marker_id, quad in zip(ids.tolist(), px[:, :4], strict=True):
            self._blend(canvas, self._patch(marker_id), quad)
        return centres

    def _add_noise(self, canvas: np.ndarray) -> None:
        size = canvas.size
        if self._noise is None:
            pos, neg = self._draw_noise(size)
        else:
            start = int(self.rng.integers(0, len(self._noise[0]) - size + 1))
            pos, neg = (part[start : start + size] for part in self._noise)
        cv2.add(canvas, pos.reshape(canvas.shape), dst=canvas)
        cv2.subtract(canvas, neg.reshape(canvas.shape), dst=canvas)

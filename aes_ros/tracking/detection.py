"""Finding the markers in a camera image: ids and sub-pixel corners (docs/design.md#tracking).

:func:`detect_markers` runs OpenCV's ArUco detector (dictionary and corner
order of :mod:`aes_ros.markers`) with parameters for small markers, refines
every corner by :func:`refine_corners`, and drops what must not become a pose:

- an id seen twice in one frame: both are dropped (a misread code, or two
  robots wearing one id; either way neither can be trusted), and listed in
  ``duplicates`` so the node can warn;
- a marker with a corner on or near the image border: a marker cut by the
  border is not seen whole (ArUco finds none, or a wrong quadrilateral), so
  it never yields a pose; listed in ``at_border``.

Corner accuracy (measured on the simulated camera, 0.7 px blur, σ = 2 grey
levels, ``tests/unit/test_tracker_core.py`` and ``bench/bench_camera_render.py``):
ArUco's own refinements leave 0.5-0.8 px RMS per corner on 20-30 px markers
(``CORNER_REFINE_SUBPIX`` is pulled by the marker's inner cells within its
window; ``CONTOUR`` fits pixel contours), :func:`refine_corners` 0.03-0.05 px.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from aes_ros.markers import DICTIONARY, MARKER_CELLS, dictionary


@dataclass(frozen=True, eq=False)
class Detections:
    """The markers found in one image.

    ids : (M,) int, each at most once. corners : (M, 4, 2) [px], OpenCV's order
    (top-left, top-right, bottom-right, bottom-left of the marker image).
    duplicates : ids seen more than once (sorted; not in ``ids``).
    at_border : ids of markers dropped for touching the image border (sorted).
    """

    ids: np.ndarray
    corners: np.ndarray
    duplicates: tuple[int, ...] = ()
    at_border: tuple[int, ...] = ()

    def __len__(self) -> int:
        return len(self.ids)


def detector_parameters(
    *, min_marker_px: float = 12.0, image_size: tuple[int, int] = (2048, 1536)
) -> cv2.aruco.DetectorParameters:
    """ArUco parameters for small markers (a 4×4 marker of 16-30 px, 3-5 px per cell).

    min_marker_px : the smallest marker side to look for [px]; sets
        ``minMarkerPerimeterRate`` for an image of ``image_size`` (W, H).

    Measured on 100 robots over 4 × 3 m (5 frames, 0.7 px blur, σ = 2): at
    1600 × 1200 (3.2 px per cell) the defaults find 460 of 500 markers, these
    497 (489 in ``bench/bench_camera_render.py --accuracy``'s frames); at
    1800 × 1350 492 and 500. What matters is reading the bits:
    ``perspectiveRemovePixelPerCell`` 8 (default 4) and
    ``perspectiveRemoveIgnoredMarginPerCell`` 0.25 (0.13) read each cell from
    its blurred centre only; ``adaptiveThreshWinSize`` 3 and 13 (two passes
    instead of 3, 13, 23) fit cells of 3-5 px. No bit is corrected
    (``errorCorrectionRate`` stays 0.6, i.e. 0 bits of DICT_4X4_250's 1),
    which would find 3 more at 1600 px for a higher risk of a misread id.
    OpenCV's corner refinement is off: :func:`refine_corners` replaces it.
    """
    p = cv2.aruco.DetectorParameters()
    p.minMarkerPerimeterRate = 4.0 * min_marker_px / max(image_size)
    p.adaptiveThreshWinSizeMin = 3
    p.adaptiveThreshWinSizeMax = 13
    p.adaptiveThreshWinSizeStep = 10
    p.perspectiveRemovePixelPerCell = 8
    p.perspectiveRemoveIgnoredMarginPerCell = 0.25
    p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE
    return p


@lru_cache(maxsize=8)
def make_detector(
    min_marker_px: float = 12.0,
    image_size: tuple[int, int] = (2048, 1536),
    dictionary_id: int = DICTIONARY,
) -> cv2.aruco.ArucoDetector:
    """An ``ArucoDetector`` with :func:`detector_parameters` (cached per arguments)."""
    params = detector_parameters(min_marker_px=min_marker_px, image_size=image_size)
    return cv2.aruco.ArucoDetector(dictionary(dictionary_id), params)


def refine_corners(
    image: np.ndarray,
    corners: np.ndarray,
    *,
    samples: int = 12,
    span: tuple[float, float] = (0.15, 0.85),
    profile_points: int = 17,
    iterations: int = 4,
    min_contrast: float = 20.0,
    cells: int = MARKER_CELLS,
) -> np.ndarray:
    """Sub-pixel corners ``(M, 4, 2)`` [px] from straight-line fits to the marker's edges.

    Parameters
    ----------
    image : (H, W) grey image.
    corners : (M, 4, 2) [px], approximate (within about half a cell).
    samples : points measured per edge, spread over ``span`` (fractions of
        the edge from its first corner; the ends are left out, where the
        neighbouring edge and the narrow quiet zone at a corner interfere).
    profile_points : samples per profile across the edge.
    iterations : re-centrings of the measuring window on the edge.
    min_contrast : grey levels between black border and white quiet zone
        below which an edge point is not trusted.
    cells : cells across the marker, border included.

    Returns
    -------
    The refined corners; a corner whose two edges could not both be measured,
    or that would move by more than half a cell (at least 1.5 px), keeps its
    input value.

    Notes
    -----
    Each edge point is measured on an intensity profile across the edge,
    sampled (bilinearly) from the middle of the black border cell to as far
    out into the white: with the black and white levels ``B``, ``W`` read at
    the two ends (medians along the edge), the edge lies at
    ``s_out - ∫ (I - B) / (W - B) ds``, the length of black the profile holds.
    Unlike the 50 % crossing or the gradient peak this integral does not
    depend on where the edge falls between two pixel centres (it is exact for
    a straight edge integrated over square pixels) nor on a symmetric blur.
    The points of an edge are fitted by a line (total least squares); the
    corners are the intersections of neighbouring lines.
    """
    c = np.asarray(corners, dtype=float).reshape(-1, 4, 2)
    if len(c) == 0:
        return c.copy()
    img = np.asarray(image)
    if img.dtype != np.float32:
        img = img.astype(np.float32)
    start, end = c, np.roll(c, -1, axis=1)  # edge k runs from corner k to corner k + 1
    length = np.linalg.norm(end - start, axis=-1)  # (M, 4)
    along = (end - start) / np.maximum(length, 1e-9)[..., None]
    normal = np.stack([along[..., 1], -along[..., 0]], axis=-1)
    middle = 0.5 * (start + end) - c.mean(axis=1, keepdims=True)
    normal *= np.where((middle * normal).sum(-1, keepdims=True) < 0.0, -1.0, 1.0)  # outwards
    half = np.clip(0.5 * length.mean(axis=1) / cells, 1.0, 4.0)[:, None, None]  # (M, 1, 1)
    t = np.linspace(span[0], span[1], samples)
    base = start[:, :, None, :] + (end - start)[:, :, None, :] * t[None, None, :, None]
    u = np.linspace(-1.0, 1.0, profile_points, dtype=np.float32)  # in units of ``half``
    du = (u[1] - u[0]) * half
    offset = np.zeros(base.shape[:3])  # (M, 4, S) along the normal [px]
    base32, normal32 = base.astype(np.float32), normal.astype(np.float32)[:, :, None, None, :]
    for _ in range(iterations):
        s = offset.astype(np.float32)[..., None] + half.astype(np.float32)[..., None] * u
        pts = base32[..., None, :] + s[..., None] * normal32  # (M, 4, S, P, 2)
        flat = pts.reshape(-1, len(u), 2)
        prof = cv2.remap(
            img, flat[..., 0], flat[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        ).reshape(s.shape)
        black = np.median(prof[..., 0], axis=2, keepdims=True)  # (M, 4, 1), per edge
        white = np.median(prof[..., -1], axis=2, keepdims=True)
        contrast = white - black
        # the trapezoid rule's integral of the white fraction over the window
        total = prof.sum(axis=-1) - 0.5 * (prof[..., 0] + prof[..., -1])
        area = (total - (len(u) - 1) * black) / np.where(contrast > 0.0, contrast, 1.0) * du
        step = half - area  # the edge, relative to the window's centre
        ok = contrast > min_contrast
        # an edge outside the window reads as +-half: move by that much and look again
        offset = np.where(ok, offset + np.clip(step, -half, half), offset)
    # trusted: enough contrast and converged (the last move small against the window)
    valid = ok & (np.abs(step) < 0.25 * half)
    points = base + offset[..., None] * normal[:, :, None, :]
    weight = valid.astype(float)[..., None]
    count = valid.sum(axis=2)  # (M, 4)
    mean = (points * weight).sum(axis=2) / np.maximum(count, 1)[..., None]
    centred = (points - mean[:, :, None, :]) * weight
    scatter = np.einsum("mksi,mksj->mkij", centred, centred)
    direction = np.linalg.eigh(scatter)[1][..., :, 1]  # (M, 4, 2), the principal axis
    # corner k is where edge k - 1 meets edge k
    p1, d1 = np.roll(mean, 1, axis=1), np.roll(direction, 1, axis=1)
    system = np.stack([d1, -direction], axis=-1)  # p1 + a d1 = mean + b direction
    good = (np.abs(np.linalg.det(system)) > 1e-3) & (count >= 3) & (np.roll(count, 1, axis=1) >= 3)
    safe = np.where(good[..., None, None], system, np.eye(2))
    ab = np.linalg.solve(safe, (mean - p1)[..., None])[..., 0]
    refined = p1 + ab[..., 0:1] * d1
    # a fit that went astray (an edge point on a neighbour's edge) moves a corner far
    good &= np.linalg.norm(refined - c, axis=-1) <= np.maximum(2.0 * half[..., 0], 1.5)
    return np.where(good[..., None], refined, c)


def detect_markers(
    image: np.ndarray,
    detector: cv2.aruco.ArucoDetector | None = None,
    *,
    border_px: float = 3.0,
    refine: bool = True,
) -> Detections:
    """The markers in a mono8 ``image (H, W)``: ids and corners, each id at most once.

    Parameters
    ----------
    image : (H, W) uint8.
    detector : default :func:`make_detector` for the image's size.
    border_px : a marker with a corner closer than this to the image border
        [px] is dropped (its id goes to ``at_border``).
    refine : refine the corners by :func:`refine_corners`.
    """
    img = np.asarray(image)
    if img.ndim != 2:
        raise ValueError(f"image: expected a mono8 (H, W) array, got shape {img.shape}")
    h, w = img.shape
    if detector is None:
        detector = make_detector(image_size=(w, h))
    found, ids, _ = detector.detectMarkers(img)
    if ids is None or len(ids) == 0:
        return Detections(np.zeros(0, dtype=int), np.zeros((0, 4, 2)))
    ids = ids.reshape(-1).astype(int)
    corners = np.asarray(found, dtype=float).reshape(-1, 4, 2)
    unique, counts = np.unique(ids, return_counts=True)
    duplicates = unique[counts > 1]
    keep = ~np.isin(ids, duplicates)
    x, y = corners[..., 0], corners[..., 1]
    inside = (
        (x.min(axis=1) >= border_px)
        & (y.min(axis=1) >= border_px)
        & (x.max(axis=1) <= w - 1 - border_px)
        & (y.max(axis=1) <= h - 1 - border_px)
    )
    at_border = np.unique(ids[keep & ~inside])
    keep &= inside
    ids, corners = ids[keep], corners[keep]
    if refine and len(ids):
        corners = refine_corners(img, corners)
    order = np.argsort(ids, kind="stable")
    return Detections(
        ids[order],
        corners[order],
        tuple(int(i) for i in duplicates),
        tuple(int(i) for i in at_border),
    )

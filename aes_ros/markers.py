"""The fiducial markers the overhead camera sees: which, where, and how worn.

See docs/design.md#tracking.

Shared by the simulated camera (:mod:`sim_bridge.camera_render`), which draws
them, and the tracker (:mod:`aes_ros.tracking`), which finds them; kept here, in the
ROS-free core, so both read the one convention.

Convention
----------
- Dictionary: ArUco ``DICT_4X4_250``. A 4×4 marker is 6 cells across with its
  black border, the fewest of any dictionary, so for a given printed side its
  cells are the largest: 8.3 mm on a 50 mm marker, 3.8 px at the 2.2 mm/px of
  a 2048-px camera over a 4 m arena and its margin, where the 8 cells of
  ``DICT_APRILTAG_36h11`` get 2.8 px. 250 ids cover 100+ robots plus the
  reference markers. The price is a small Hamming distance between codes
  (OpenCV corrects no bit of it at the default ``errorCorrectionRate``, 36h11
  corrects 5), so the tracker must treat an id seen twice as suspect: it drops
  both (:mod:`aes_ros.tracking.detection`). The two dictionaries side by side:
  docs/real_robots.md#what-a-lab-needs.
- Ids: robot ``i`` wears id ``i``; reference markers take the ids from the top
  down (249, 248, …: :func:`reference_ids`), so robots and references never
  collide while fewer than ``250 - #references`` robots run.
- A robot's marker (:class:`RobotMarker`) lies on the Mona's top, 38 mm above
  the floor (35 mm body + 3 mm clearance, docs/design.md#mona), centred on the body's axis,
  which is ``offset`` = 18 mm ahead of ``base_link`` (the axle midpoint that
  ``/swarm/poses`` reports). Its black square is 50 mm, printed on a round
  white sticker that covers the Ø 80 mm top. The white around the square is
  its quiet zone: 15 mm at the middle of an edge, 11 mm where the tracker
  fits the edges (15 % of the side from a corner), 4.6 mm at a corner. A
  narrower one costs accuracy with any detector: a blurred thin white strip
  between the black border and the dark body never reaches full white, which
  moves every measured edge inwards.
- Orientation: the marker's x axis ("right" in the marker image) is the
  robot's heading, its y axis ("up") the robot's left, so a level overhead
  camera (image right = arena +x) sees the marker image as printed.
- Corners: OpenCV's order, top-left, top-right, bottom-right, bottom-left of
  the marker image (:func:`marker_corners`), i.e. with the marker's frame
  ``(-s/2, +s/2), (+s/2, +s/2), (+s/2, -s/2), (-s/2, -s/2)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

#: The ArUco dictionary of every marker (robots and references).
DICTIONARY: int = cv2.aruco.DICT_4X4_250
#: Number of ids in :data:`DICTIONARY`.
N_IDS: int = 250
#: Cells across a marker, black border included (4 data bits + 2 border cells).
MARKER_CELLS: int = 6

#: A marker's corners in its own frame, in units of its side: OpenCV's order
#: (top-left, top-right, bottom-right, bottom-left), x = "right", y = "up".
UNIT_CORNERS: np.ndarray = np.array([[-0.5, 0.5], [0.5, 0.5], [0.5, -0.5], [-0.5, -0.5]])
UNIT_CORNERS.setflags(write=False)


@lru_cache(maxsize=4)
def dictionary(dictionary_id: int = DICTIONARY) -> cv2.aruco.Dictionary:
    """The OpenCV dictionary object (cached)."""
    return cv2.aruco.getPredefinedDictionary(dictionary_id)


@dataclass(frozen=True)
class RobotMarker:
    """How a Mona wears its marker (the defaults are the Mona's, docs/design.md#mona).

    size : side of the black square [m].
    sticker_diameter : the round white sticker the marker is printed on [m]
        (at most the top's Ø 80 mm); the white around the square is the
        marker's quiet zone.
    height : marker plane above the floor [m]: body 35 mm + clearance 3 mm.
    offset : marker centre ahead of ``base_link`` along the heading [m]: the
        body axis is the axle's 18 mm offset ahead of the axle midpoint.
    """

    size: float = 0.050
    sticker_diameter: float = 0.080
    height: float = 0.038
    offset: float = 0.018

    def __post_init__(self) -> None:
        for name in ("size", "sticker_diameter", "height"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0) or (name == "size" and value == 0):
                raise ValueError(f"{name}: expected a finite length >= 0 [m], got {value}")
        if self.sticker_diameter < math.sqrt(2.0) * self.size:
            raise ValueError(
                f"sticker_diameter: expected >= the marker's diagonal "
                f"{math.sqrt(2.0) * self.size:.4f} m, got {self.sticker_diameter}"
            )
        if not np.isfinite(self.offset):
            raise ValueError(f"offset: expected a finite length [m], got {self.offset}")


@dataclass(frozen=True)
class ReferenceMarker:
    """A fixed marker lying flat on the floor at a known place (for calibration).

    marker_id : its id (by convention from the top down: :func:`reference_ids`).
    x, y : centre [m; arena frame]. size : side of the black square [m].
    yaw : direction of its x axis [rad, counter-clockwise from arena +x].
    It is printed with a white margin of one cell around the black square.
    """

    marker_id: int
    x: float
    y: float
    size: float
    yaw: float = 0.0

    def corners(self) -> np.ndarray:
        """Its corners (4, 3) [m; arena frame, z = 0] in OpenCV's order."""
        return marker_corners(self.x, self.y, self.yaw, 0.0, self.size)


def reference_ids(count: int) -> tuple[int, ...]:
    """The ids of ``count`` reference markers: from the top of the dictionary down."""
    if not 0 <= count <= N_IDS:
        raise ValueError(f"count: expected 0 … {N_IDS}, got {count}")
    return tuple(range(N_IDS - 1, N_IDS - 1 - count, -1))


def marker_corners(
    x: np.ndarray, y: np.ndarray, theta: np.ndarray, z: np.ndarray, size: np.ndarray
) -> np.ndarray:
    """Corners ``(..., 4, 3)`` [m; arena frame] of square markers lying flat.

    Parameters
    ----------
    x, y : marker centre [m]; theta : direction of the marker's x axis [rad,
    counter-clockwise from arena +x]; z : height of the marker plane [m];
    size : side [m]. All broadcast together to the leading shape ``(...)``.

    Returns
    -------
    The 4 corners in OpenCV's ArUco order (top-left, top-right, bottom-right,
    bottom-left of the marker image; see the module docstring).
    """
    x, y, theta, z, size = np.broadcast_arrays(
        *(np.asarray(a, float) for a in (x, y, theta, z, size))
    )
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    u = UNIT_CORNERS[:, 0] * size[..., None]
    v = UNIT_CORNERS[:, 1] * size[..., None]
    out = np.empty((*x.shape, 4, 3))
    out[..., 0] = x[..., None] + c * u - s * v
    out[..., 1] = y[..., None] + s * u + c * v
    out[..., 2] = z[..., None]
    return out


def marker_centres(positions: np.ndarray, headings: np.ndarray, offset: float) -> np.ndarray:
    """Marker centres ``(..., 2)`` [m] of robots at ``base_link`` poses.

    ``positions (..., 2)`` [m], ``headings (...)`` [rad]; the centre is ``offset``
    [m] ahead along the heading (:attr:`RobotMarker.offset`).
    """
    h = np.asarray(headings, dtype=float)
    return np.asarray(positions, float) + offset * np.stack([np.cos(h), np.sin(h)], axis=-1)


def base_positions(centres: np.ndarray, headings: np.ndarray, offset: float) -> np.ndarray:
    """The inverse of :func:`marker_centres`: ``base_link`` positions ``(..., 2)`` [m]."""
    return marker_centres(centres, headings, -offset)


def marker_image(marker_id: int, cell_px: int, dictionary_id: int = DICTIONARY) -> np.ndarray:
    """The marker ``marker_id`` as a uint8 image, ``cell_px`` pixels per cell, black border
    included (no white margin): shape ``(cells·cell_px, cells·cell_px)``, 0 = black, 255 = white."""
    d = dictionary(dictionary_id)
    cells = d.markerSize + 2
    if not 0 <= marker_id < d.bytesList.shape[0]:
        raise ValueError(f"marker_id: expected 0 … {d.bytesList.shape[0] - 1}, got {marker_id}")
    return cv2.aruco.generateImageMarker(d, int(marker_id), cells * int(cell_px), borderBits=1)


def scattered_robots(
    n: int, extent: tuple[float, float], rng: np.random.Generator, radius: float = 0.040
) -> tuple[np.ndarray, np.ndarray]:
    """``base_link`` poses of ``n`` robots scattered over a floor of ``extent`` (width,
    depth) [m] centred on the origin, bodies (``radius`` [m], Ø 80 mm) inside it and
    3 mm apart at least: scenes for the camera's tests and benchmarks.

    Returns positions (n, 2) [m] and headings (n,) [rad].
    """
    half = np.asarray(extent, dtype=float) / 2 - radius
    centres: list[np.ndarray] = []
    while len(centres) < n:
        c = rng.uniform(-half, half)
        if all(np.hypot(*(c - o)) > 2 * radius + 0.003 for o in centres):
            centres.append(c)
    headings = rng.uniform(-np.pi, np.pi, n)
    return base_positions(np.array(centres), headings, RobotMarker().offset), headings

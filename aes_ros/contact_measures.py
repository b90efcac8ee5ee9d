"""Contacts measured in a state, nothing moved (docs/model.md#contacts-walls-and-obstacles).

The counts and smallest centre distances that ``metrics.csv``, ``/sim/stats``, the dashboard
and the simulator report: bodies overlapping or touching (within a tolerance) one another, a
wall or an obstacle, with the shapes and units of :mod:`aes_ros.contacts`, whose rule
resolves them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from aes_ros.contacts import CLOSE, NO_BOXES, NO_CIRCLES, NO_WALLS, _closest, body_centres
from aes_ros.numba_cache import depend_on
from aes_ros.pair_list import near_pairs


@njit(cache=True)
def measure_contacts(
    positions: np.ndarray,
    headings: np.ndarray,
    radius: float,
    axle_offset: float,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
    tolerance: float,
) -> tuple[int, float]:
    """Contacts in a state, nothing moved: robot pairs, robot-wall and robot-obstacle
    pairs whose bodies overlap or are within ``tolerance`` [m] of touching, and the
    smallest robot-robot centre distance [m] if below CLOSE radii (else inf).

    Shapes and units as :func:`aes_ros.contacts.resolve_contacts`. After a step with
    contacts on, bodies pressed together sit at touching distance, so with a tolerance of
    a micrometre this counts what :func:`aes_ros.contacts.resolve_contacts` resolved.
    """
    n = positions.shape[0]
    cx, cy = body_centres(positions, headings, axle_offset)
    if n == 0:
        return 0, np.inf
    reach = 2.0 * radius + tolerance
    close = CLOSE * radius
    pairs = near_pairs(cx, cy, max(reach, close))
    best = _closest(cx, cy, pairs)
    found = 0
    for e in range(pairs.shape[0]):
        dx = cx[pairs[e, 1]] - cx[pairs[e, 0]]
        dy = cy[pairs[e, 1]] - cy[pairs[e, 0]]
        if dx * dx + dy * dy <= reach * reach:
            found += 1
    for i in range(n):
        for c in range(circles.shape[0]):
            if math.hypot(cx[i] - circles[c, 0], cy[i] - circles[c, 1]) <= (
                circles[c, 2] + radius + tolerance
            ):
                found += 1
        for k in range(boxes.shape[0]):
            px = min(max(cx[i], boxes[k, 0]), boxes[k, 1])
            py = min(max(cy[i], boxes[k, 2]), boxes[k, 3])
            if math.hypot(cx[i] - px, cy[i] - py) <= radius + tolerance:
                found += 1
        if walls.shape[0] == 4:
            lo_x = walls[0] + radius + tolerance
            hi_x = walls[1] - radius - tolerance
            lo_y = walls[2] + radius + tolerance
            hi_y = walls[3] - radius - tolerance
            if cx[i] <= lo_x or cx[i] >= hi_x or cy[i] <= lo_y or cy[i] >= hi_y:
                found += 1
    return found, (math.sqrt(best) if best < close * close else np.inf)


#: Gap [m] within which :func:`contacts_over_time` counts bodies as touching.
TOUCH_TOLERANCE = 1e-6


def contacts_over_time(
    positions: np.ndarray,
    headings: np.ndarray,
    radius: float,
    axle_offset: float,
    walls: np.ndarray = NO_WALLS,
    circles: np.ndarray = NO_CIRCLES,
    boxes: np.ndarray = NO_BOXES,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`measure_contacts` of every state: positions (..., N, 2) [m], headings
    (..., N) [rad] give contacts (...) and the smallest centre distance (...) [m]."""
    lead = headings.shape[:-1]
    pos = np.ascontiguousarray(positions, dtype=float).reshape(-1, *positions.shape[-2:])
    head = np.ascontiguousarray(headings, dtype=float).reshape(-1, headings.shape[-1])
    count = np.empty(len(head), np.int64)
    closest = np.empty(len(head))
    for s in range(len(head)):
        count[s], closest[s] = measure_contacts(
            pos[s], head[s], radius, axle_offset, walls, circles, boxes, TOUCH_TOLERANCE
        )
    return count.reshape(lead), closest.reshape(lead)


# Numba's cache checks this file only: an edit of the grid or of the distance loop compiled
# in from these modules must compile it again.
depend_on(measure_contacts, "aes_ros.contacts", "aes_ros.pair_list")

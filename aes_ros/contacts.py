"""Contacts between robot bodies, walls and obstacles (docs/model.md#contacts-walls-and-obstacles).

One rule for the offline simulator (numba kernel and numpy stepper) and the kinematic
pybullet bridge, so that offline and lockstep ROS runs stay bit-equal. A body is a disc of
radius r centred ``axle_offset`` ahead of the robot's pose point (the axle midpoint):
``centre = position + axle_offset (cos θ, sin θ)``. After each Euler step,
:func:`resolve_contacts` separates overlapping bodies by moving their centres (the heading
is kept): position-based separation, a few Gauss-Seidel sweeps over the pairs that a
spatial grid of cells 2r finds, each sweep ending with the walls and obstacles.

Every loop runs in index order, so the result is bit-reproducible; positions without an
overlap are not written to.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Depth [m] below which two shapes count as touching, not overlapping: a pair just
#: separated sits at 2r up to rounding and must not count again.
SLOP = 1e-9

#: Default number of Gauss-Seidel sweeps per step.
ITERATIONS = 8

NO_WALLS = np.empty(0)
NO_CIRCLES = np.empty((0, 3))
NO_BOXES = np.empty((0, 4))


@njit(cache=True)
def _build_grid(
    cx: np.ndarray, cy: np.ndarray, cell: float, gx: np.ndarray, gy: np.ndarray
) -> tuple[np.ndarray, np.ndarray, int]:
    """Hash the centres into cells of side ``cell``: each robot's cell (gx, gy, out) and a
    counting sort by hash bucket, start (H+1,) and order (N,), stable in robot index."""
    n = cx.shape[0]
    size = 1
    while size < 2 * n:
        size *= 2
    mask = size - 1
    count = np.zeros(size + 1, np.int64)
    bucket = np.empty(n, np.int64)
    for i in range(n):
        gx[i] = math.floor(cx[i] / cell)
        gy[i] = math.floor(cy[i] / cell)
        h = _hash(gx[i], gy[i], mask)
        bucket[i] = h
        count[h + 1] += 1
    for h in range(size):
        count[h + 1] += count[h]
    fill = count[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        order[fill[bucket[i]]] = i
        fill[bucket[i]] += 1
    return count, order, mask


@njit(inline="always")
def _hash(ix: int, iy: int, mask: int) -> int:
    return ((ix * 73856093) ^ (iy * 19349663)) & mask


@njit(cache=True)
def _separate_pairs(
    positions: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    radius: float,
    gx: np.ndarray,
    gy: np.ndarray,
    start: np.ndarray,
    order: np.ndarray,
    mask: int,
) -> int:
    """One Gauss-Seidel sweep over overlapping pairs (i < j, in index order): each body
    moves half the depth along the line of centres. Returns the overlaps found."""
    n = cx.shape[0]
    touch = 2.0 * radius
    found = 0
    for i in range(n):
        for ox in range(-1, 2):
            for oy in range(-1, 2):
                kx = gx[i] + ox
                ky = gy[i] + oy
                h = _hash(kx, ky, mask)
                for slot in range(start[h], start[h + 1]):
                    j = order[slot]
                    if j <= i or gx[j] != kx or gy[j] != ky:
                        continue
                    dx = cx[j] - cx[i]
                    dy = cy[j] - cy[i]
                    d2 = dx * dx + dy * dy
                    if d2 >= (touch - SLOP) * (touch - SLOP):
                        continue
                    found += 1
                    d = math.sqrt(d2)
                    if d > 0.0:
                        nx = dx / d
                        ny = dy / d
                    else:  # coincident centres: split along x, lower index to -x
                        nx = 1.0
                        ny = 0.0
                    half = 0.5 * (touch - d)
                    cx[i] -= half * nx
                    cy[i] -= half * ny
                    cx[j] += half * nx
                    cy[j] += half * ny
                    positions[i, 0] -= half * nx
                    positions[i, 1] -= half * ny
                    positions[j, 0] += half * nx
                    positions[j, 1] += half * ny
    return found


@njit(cache=True)
def _push_out(
    positions: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    radius: float,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
) -> int:
    """Move every body out of the obstacles and inside the walls (walls last).
    Returns the overlaps found."""
    n = cx.shape[0]
    found = 0
    for i in range(n):
        for c in range(circles.shape[0]):
            dx = cx[i] - circles[c, 0]
            dy = cy[i] - circles[c, 1]
            reach = circles[c, 2] + radius
            d2 = dx * dx + dy * dy
            if d2 >= (reach - SLOP) * (reach - SLOP):
                continue
            found += 1
            d = math.sqrt(d2)
            if d > 0.0:
                mx = dx / d * (reach - d)
                my = dy / d * (reach - d)
            else:
                mx = reach
                my = 0.0
            _move(positions, cx, cy, i, mx, my)
        for k in range(boxes.shape[0]):
            x0, x1, y0, y1 = boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3]
            px = min(max(cx[i], x0), x1)  # nearest point of the box
            py = min(max(cy[i], y0), y1)
            dx = cx[i] - px
            dy = cy[i] - py
            d2 = dx * dx + dy * dy
            if d2 > 0.0:  # centre outside the box
                if d2 >= (radius - SLOP) * (radius - SLOP):
                    continue
                d = math.sqrt(d2)
                mx = dx / d * (radius - d)
                my = dy / d * (radius - d)
            else:  # centre inside: out through the nearest face
                left = cx[i] - x0
                right = x1 - cx[i]
                down = cy[i] - y0
                up = y1 - cy[i]
                least = min(left, right, down, up)
                mx = 0.0
                my = 0.0
                if least == left:
                    mx = -(left + radius)
                elif least == right:
                    mx = right + radius
                elif least == down:
                    my = -(down + radius)
                else:
                    my = up + radius
            found += 1
            _move(positions, cx, cy, i, mx, my)
        if walls.shape[0] == 4:
            lo_x = walls[0] + radius
            hi_x = walls[1] - radius
            lo_y = walls[2] + radius
            hi_y = walls[3] - radius
            mx = 0.0
            my = 0.0
            if cx[i] < lo_x - SLOP:
                mx = lo_x - cx[i]
            elif cx[i] > hi_x + SLOP:
                mx = hi_x - cx[i]
            if cy[i] < lo_y - SLOP:
                my = lo_y - cy[i]
            elif cy[i] > hi_y + SLOP:
                my = hi_y - cy[i]
            if mx != 0.0 or my != 0.0:
                found += 1
                _move(positions, cx, cy, i, mx, my)
    return found


@njit(inline="always")
def _move(
    positions: np.ndarray, cx: np.ndarray, cy: np.ndarray, i: int, mx: float, my: float
) -> None:
    cx[i] += mx
    cy[i] += my
    positions[i, 0] += mx
    positions[i, 1] += my


@njit(cache=True)
def _min_distance(cx: np.ndarray, cy: np.ndarray) -> float:
    """Smallest centre distance [m] (inf for fewer than two): a sweep along x."""
    n = cx.shape[0]
    order = np.argsort(cx, kind="mergesort")
    best = np.inf
    for a in range(n):
        i = order[a]
        for b in range(a + 1, n):
            j = order[b]
            dx = cx[j] - cx[i]
            if dx * dx >= best:
                break
            dy = cy[j] - cy[i]
            d2 = dx * dx + dy * dy
            if d2 < best:
                best = d2
    return math.sqrt(best)


@njit(cache=True)
def resolve_contacts(
    positions: np.ndarray,
    headings: np.ndarray,
    radius: float,
    axle_offset: float,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
    iterations: int,
) -> tuple[int, float]:
    """Separate overlapping bodies in place; call once after each Euler step.

    Parameters
    ----------
    positions : (N, 2) [m] pose points (axle midpoints), moved in place by each body's
        correction; rows without an overlap are not written.
    headings : (N,) [rad], kept.
    radius : body radius r [m]. axle_offset : body centre ahead of the pose point [m].
    walls : (4,) x_min, x_max, y_min, y_max [m] of the arena that holds the bodies, or (0,).
    circles : (M, 3) x, y, radius [m]. boxes : (L, 4) x_min, x_max, y_min, y_max [m].
    iterations : Gauss-Seidel sweeps at most (each: all pairs, then walls and obstacles);
        the sweeps stop early once one finds no overlap.

    Returns
    -------
    contacts : overlapping robot pairs plus robot-wall and robot-obstacle overlaps
        found before resolution.
    min_centre_distance : smallest robot-robot centre distance [m] after resolution
        (inf for one robot).
    """
    n = positions.shape[0]
    cx = np.empty(n)
    cy = np.empty(n)
    for i in range(n):
        cx[i] = positions[i, 0] + axle_offset * math.cos(headings[i])
        cy[i] = positions[i, 1] + axle_offset * math.sin(headings[i])
    gx = np.empty(n, np.int64)
    gy = np.empty(n, np.int64)
    cell = 2.0 * radius
    contacts = 0
    for sweep in range(iterations):
        start, order, mask = _build_grid(cx, cy, cell, gx, gy)
        found = _separate_pairs(positions, cx, cy, radius, gx, gy, start, order, mask)
        found += _push_out(positions, cx, cy, radius, walls, circles, boxes)
        if sweep == 0:
            contacts = found
        if found == 0:
            break
    return contacts, _min_distance(cx, cy)


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
    smallest robot-robot centre distance [m] (inf for one robot).

    Shapes and units as :func:`resolve_contacts`. After a step with contacts on,
    bodies pressed together sit at touching distance, so with a tolerance of a
    micrometre this counts what :func:`resolve_contacts` resolved.
    """
    n = positions.shape[0]
    cx = np.empty(n)
    cy = np.empty(n)
    for i in range(n):
        cx[i] = positions[i, 0] + axle_offset * math.cos(headings[i])
        cy[i] = positions[i, 1] + axle_offset * math.sin(headings[i])
    gx = np.empty(n, np.int64)
    gy = np.empty(n, np.int64)
    reach = 2.0 * radius + tolerance
    start, order, mask = _build_grid(cx, cy, reach, gx, gy)
    found = 0
    for i in range(n):
        for ox in range(-1, 2):
            for oy in range(-1, 2):
                kx = gx[i] + ox
                ky = gy[i] + oy
                h = _hash(kx, ky, mask)
                for slot in range(start[h], start[h + 1]):
                    j = order[slot]
                    if j <= i or gx[j] != kx or gy[j] != ky:
                        continue
                    dx = cx[j] - cx[i]
                    dy = cy[j] - cy[i]
                    if dx * dx + dy * dy <= reach * reach:
                        found += 1
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
    return found, _min_distance(cx, cy)


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


def contact_geometry(
    walls: object = None, circles: object = None, boxes: object = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Walls (4,) or (0,), circles (M, 3) and boxes (L, 4) as the float64 arrays that
    :func:`resolve_contacts` takes; None or empty means none."""
    w = NO_WALLS if walls is None else np.ascontiguousarray(walls, dtype=float).reshape(-1)
    c = NO_CIRCLES if circles is None else np.ascontiguousarray(circles, dtype=float)
    b = NO_BOXES if boxes is None else np.ascontiguousarray(boxes, dtype=float)
    if w.shape not in ((0,), (4,)):
        raise ValueError(f"walls: need x_min, x_max, y_min, y_max or nothing, got {w.shape}")
    return w, c.reshape(-1, 3), b.reshape(-1, 4)

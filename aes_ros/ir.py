"""The Mona's five infrared proximity sensors, simulated by ray casting (pure: numpy + numba).

Sensor k sits on the rim of the body disc (radius ``body_radius``, centred ``axle_offset``
ahead of the pose point) at ``IR_ANGLES[k]`` from ahead, counter-clockwise, in the order of
the Mona's TELEMETRY (0°, +37°, −37°, +67°, −67°; Arvin et al., "Mona: an affordable
open-source mobile robot for education and research", J. Intell. Robot. Syst. 94, 2019, and
MonaRobot's published design), and looks straight outwards. Its reading is the distance
[m] along that ray to the nearest other robot's body disc, wall (a rectangle the robots are
inside) or obstacle (circles and boxes), ``max_range`` when nothing is that close, 0 from
inside one. :mod:`aes_ros.ir_readings` turns those distances into readings (noise and the
sensor's response curve) and is the numpy entry point (:func:`aes_ros.ir_readings.ir_ranges`).

:func:`ray_distances`, :func:`cast_rays` and :func:`cast_rays_listed` are numba kernels
that numba code (the offline simulator's) can call. docs/model.md, "IR proximity sensors".
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from aes_ros.mona.messages import IR_BEARINGS_DEG

#: Mounting angles [rad] of sensors 0…4, CCW from ahead, in TELEMETRY's order.
IR_ANGLES = np.radians(IR_BEARINGS_DEG)
#: An empty (0,) or (0, k) array: no walls, circles or boxes.
NO_WALLS = np.zeros(0)
#: Relative looseness of the test that skips a body behind a robot (no ray reaches it).
_FRAME_SLACK = 1e-6


@njit(inline="always")
def _disc_hit(sx: float, sy: float, ux: float, uy: float, cx: float, cy: float, r: float) -> float:
    """Distance along the ray (s, u) to a disc (c, r); 0 from inside, inf for a miss."""
    qx, qy = sx - cx, sy - cy
    c = qx * qx + qy * qy - r * r
    if c <= 0.0:
        return 0.0
    b = qx * ux + qy * uy
    disc = b * b - c
    if b >= 0.0 or disc < 0.0:  # the disc is behind, or beside the ray
        return math.inf
    return -b - math.sqrt(disc)  # |s + t u - c| = r, the nearer root


@njit(inline="always")
def _box_hit(
    sx: float, sy: float, ux: float, uy: float, x0: float, x1: float, y0: float, y1: float
) -> float:
    """Distance along the ray (s, u) to a box (slab method); 0 from inside, inf for a miss."""
    near, far = 0.0, math.inf
    for s, u, lo, hi in ((sx, ux, x0, x1), (sy, uy, y0, y1)):
        if u == 0.0:
            if s < lo or s > hi:
                return math.inf
        else:
            t0, t1 = (lo - s) / u, (hi - s) / u
            near, far = max(near, min(t0, t1)), min(far, max(t0, t1))
    return near if near <= far else math.inf


@njit(inline="always")
def _cell_grid(
    centres: np.ndarray, cell: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """Bodies sorted by square cell of side ``cell`` (wider when they are spread over more
    than about 8 N cells): (order, start of each cell in order, each body's cell, nx, ny).
    A body whose centre is NaN is in no cell (its cell is -1)."""
    n = len(centres)
    x0, y0, x1, y1 = math.inf, math.inf, -math.inf, -math.inf
    for i in range(n):
        if centres[i, 0] == centres[i, 0]:  # not NaN (_cast_static made non-finite ones NaN)
            x0, x1 = min(x0, centres[i, 0]), max(x1, centres[i, 0])
            y0, y1 = min(y0, centres[i, 1]), max(y1, centres[i, 1])
    w, h = max(x1 - x0, 0.0), max(y1 - y0, 0.0)  # 0 when none is finite
    side = max(cell, math.sqrt(w * h / (4.0 * n + 16.0)), (w + h) / (4.0 * n + 16.0))
    nx, ny = int(w / side) + 1, int(h / side) + 1
    of = np.full(n, -1, dtype=np.int64)
    start = np.zeros(nx * ny + 1, dtype=np.int64)
    for i in range(n):
        if centres[i, 0] == centres[i, 0]:
            of[i] = int((centres[i, 0] - x0) / side) * ny + int((centres[i, 1] - y0) / side)
            start[of[i] + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        if of[i] >= 0:
            order[fill[of[i]]] = i
            fill[of[i]] += 1
    return order, start, of, nx, ny


@njit(cache=True)
def ray_distances(
    positions: np.ndarray,
    headings: np.ndarray,
    body_radius: float,
    axle_offset: float,
    angles: np.ndarray,
    max_range: float,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
    out: np.ndarray,
) -> None:
    """Fill ``out`` (N, K) with each sensor's distance [m] to the nearest thing it sees.

    positions : (N, 2) pose points [m; odom]; headings : (N,) [rad]; angles : (K,) mounting
    angles [rad]; walls : (4,) x_min, x_max, y_min, y_max or (0,); circles : (M, 3) x, y, r;
    boxes : (L, 4) x_min, x_max, y_min, y_max. A distance is in [0, max_range]. A robot
    whose pose is not finite (a simulated run that diverged) reads max_range on every sensor
    and is seen by no other robot.
    """
    n = len(headings)
    cos_h, sin_h = np.empty(n), np.empty(n)
    for i in range(n):
        cos_h[i], sin_h[i] = math.cos(headings[i]), math.sin(headings[i])
    cast_rays(
        positions, cos_h, sin_h, body_radius, axle_offset, mounting(angles), max_range, walls,
        circles, boxes, out,
    )  # fmt: skip


@njit(cache=True)
def mounting(angles: np.ndarray) -> np.ndarray:
    """The sensors' directions (K, 2) in the robot's frame: cos and sin of ``angles`` (K,)
    [rad], which must be finite."""
    mount = np.empty((len(angles), 2))
    for a in range(len(angles)):
        if not math.isfinite(angles[a]):
            raise ValueError("ray_distances: the mounting angles must be finite")
        mount[a, 0], mount[a, 1] = math.cos(angles[a]), math.sin(angles[a])
    return mount


@njit(cache=True)
def cast_rays(
    positions: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    body_radius: float,
    axle_offset: float,
    mount: np.ndarray,
    max_range: float,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`ray_distances` from the headings' cosines and sines ``cos_h``, ``sin_h`` (N,)
    and the sensors' directions ``mount`` (K, 2) (:func:`mounting`; the offline kernel has
    them all from its step and its constants; the same floats give the same bits)."""
    n = len(cos_h)
    if n == 0:
        return
    centres = np.empty((n, 2))
    _cast_static(
        positions, cos_h, sin_h, body_radius, axle_offset, mount, max_range, walls, circles,
        boxes, out, centres,
    )  # fmt: skip
    # Another body can only be seen if its centre is this close to this one's.
    reach = 2.0 * body_radius + max_range
    reach2 = reach * reach
    behind = _blind_behind(mount, body_radius)
    order, start, of, nx, ny = _cell_grid(centres, reach)  # neighbours within 3 x 3 cells
    for i in range(n):
        if of[i] < 0:  # not finite: sees nothing
            continue
        cx, cy = centres[i, 0], centres[i, 1]
        ci, cj = of[i] // ny, of[i] % ny
        lo, hi = max(cj - 1, 0), min(cj + 1, ny - 1)
        # the 3 x 3 cells as three runs of consecutive cells (one per column of the grid)
        for gx in range(max(ci - 1, 0), min(ci + 2, nx)):
            for m in range(start[gx * ny + lo], start[gx * ny + hi + 1]):
                j = order[m]
                dx, dy = centres[j, 0] - cx, centres[j, 1] - cy
                if j == i or dx * dx + dy * dy >= reach2:
                    continue
                _see_robot(i, j, centres, cos_h, sin_h, mount, body_radius, behind, out)


@njit(inline="always")
def _ray(
    i: int,
    a: int,
    centres: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    mount: np.ndarray,
    body_radius: float,
) -> tuple[float, float, float, float]:
    """Robot i's sensor a: its point (sx, sy) [m] on the rim and direction (ux, uy), the
    direction of heading + angle by the sum formulas (no trigonometry per ray)."""
    ch, sh = cos_h[i], sin_h[i]
    ux, uy = ch * mount[a, 0] - sh * mount[a, 1], sh * mount[a, 0] + ch * mount[a, 1]
    return centres[i, 0] + body_radius * ux, centres[i, 1] + body_radius * uy, ux, uy


@njit(inline="always")
def _blind_behind(mount: np.ndarray, body_radius: float) -> float:
    """How far behind a robot's centre [m, negative] another body's centre must lie for
    none of the sensors ``mount`` (K, 2) to see it: every point of a ray is at least
    body_radius · min cos(angle) ahead, so with all sensors on the front half a disc whose
    front edge is further back is out of sight (-inf if a sensor looks back or sideways)."""
    least = np.inf
    for a in range(mount.shape[0]):
        least = min(least, mount[a, 0])
    if not least > 0.0:
        return -np.inf
    return body_radius * (least - 1.0) - _FRAME_SLACK * body_radius


@njit(inline="always")
def _see_robot(
    i: int,
    j: int,
    centres: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    mount: np.ndarray,
    body_radius: float,
    behind: float,
    out: np.ndarray,
) -> None:
    """Robot i's rays against robot j's body disc, into ``out[i]`` (the minimum).

    :func:`_disc_hit` in each ray's frame, where j's centre lies ``along`` the ray from
    i's centre and ``off_line`` beside it, and the sensor body_radius along: from the
    offsets in i's frame that every ray shares, for all rays without a branch (cheaper
    than picking the rays that can hit, which mispredicts); none if j's centre lies
    ``behind`` [m] (:func:`_blind_behind`) or further back."""
    dx, dy = centres[j, 0] - centres[i, 0], centres[j, 1] - centres[i, 1]
    ch, sh = cos_h[i], sin_h[i]
    ahead = dx * ch + dy * sh
    if ahead < behind:
        return
    left = dy * ch - dx * sh
    r2 = body_radius * body_radius
    for a in range(mount.shape[0]):
        ca, sa = mount[a, 0], mount[a, 1]
        along = ahead * ca + left * sa
        off2 = (left * ca - ahead * sa) ** 2
        b = body_radius - along  # (sensor - centre) . ray
        c = b * b + off2 - r2  # |sensor - centre|^2 - r^2
        t = -b - math.sqrt(max(r2 - off2, 0.0))  # the nearer root, when there is one
        hit = math.inf if (b >= 0.0) | (off2 > r2) else t  # behind the sensor, or beside
        hit = 0.0 if c <= 0.0 else hit  # from inside
        out[i, a] = min(out[i, a], hit)


@njit(cache=True)
def _cast_static(
    positions: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    body_radius: float,
    axle_offset: float,
    mount: np.ndarray,
    max_range: float,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
    out: np.ndarray,
    centres: np.ndarray,
) -> None:
    """The body centres into ``centres`` (N, 2), and each ray's distance to the walls,
    circles and boxes into ``out`` (N, K) (max_range where there are none)."""
    n, k = len(cos_h), len(mount)
    nan_if_not_finite = 0.0  # 0 · ±inf and 0 · NaN are NaN: one test after the loop
    for i in range(n):
        centres[i, 0] = positions[i, 0] + axle_offset * cos_h[i]
        centres[i, 1] = positions[i, 1] + axle_offset * sin_h[i]
        nan_if_not_finite += 0.0 * centres[i, 0] + 0.0 * centres[i, 1]
    out[:, :] = max_range
    if nan_if_not_finite != 0.0:  # a run that diverged: its lost robots become NaN centres,
        for i in range(n):  # which every distance test skips (they see and are seen by none)
            if not (math.isfinite(centres[i, 0]) and math.isfinite(centres[i, 1])):
                centres[i, 0] = math.nan
                centres[i, 1] = math.nan
    if not (len(walls) == 4 or len(circles) > 0 or len(boxes) > 0):
        return
    for i in range(n):
        if centres[i, 0] != centres[i, 0]:  # NaN: not finite, reads nothing
            continue
        for a in range(k):
            sx, sy, ux, uy = _ray(i, a, centres, cos_h, sin_h, mount, body_radius)
            best = max_range
            if len(walls) == 4:
                x0, x1, y0, y1 = walls[0], walls[1], walls[2], walls[3]
                if sx <= x0 or sx >= x1 or sy <= y0 or sy >= y1:
                    best = 0.0
                else:
                    if ux > 0.0:
                        best = min(best, (x1 - sx) / ux)
                    elif ux < 0.0:
                        best = min(best, (x0 - sx) / ux)
                    if uy > 0.0:
                        best = min(best, (y1 - sy) / uy)
                    elif uy < 0.0:
                        best = min(best, (y0 - sy) / uy)
            for m in range(len(circles)):
                best = min(
                    best, _disc_hit(sx, sy, ux, uy, circles[m, 0], circles[m, 1], circles[m, 2])
                )
            for m in range(len(boxes)):
                best = min(
                    best,
                    _box_hit(sx, sy, ux, uy, boxes[m, 0], boxes[m, 1], boxes[m, 2], boxes[m, 3]),
                )
            out[i, a] = best


@njit(cache=True)
def cast_rays_listed(
    positions: np.ndarray,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    body_radius: float,
    axle_offset: float,
    mount: np.ndarray,
    max_range: float,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
    pairs: np.ndarray,
    out: np.ndarray,
    centres: np.ndarray,
) -> None:
    """:func:`cast_rays` with the robots' candidate pairs given: ``pairs`` (P, 2) int64
    must hold every pair whose body centres are closer than 2 body_radius + max_range
    (the offline kernel's contact list, kept longer for this:
    :func:`aes_ros.pair_list.kept_pairs`). Each pair is met once for both robots' rays;
    the distances are those of :func:`cast_rays` to the bit (a minimum over the same hits).
    ``centres`` (N, 2) is scratch space.
    """
    _cast_static(
        positions, cos_h, sin_h, body_radius, axle_offset, mount, max_range, walls, circles,
        boxes, out, centres,
    )  # fmt: skip
    reach = 2.0 * body_radius + max_range
    reach2 = reach * reach
    behind = _blind_behind(mount, body_radius)
    for e in range(pairs.shape[0]):
        i, j = np.uint64(pairs[e, 0]), np.uint64(pairs[e, 1])  # no wrap (contacts._separate_listed)
        dx, dy = centres[j, 0] - centres[i, 0], centres[j, 1] - centres[i, 1]
        if not dx * dx + dy * dy < reach2:  # also a NaN centre
            continue
        _see_robot(i, j, centres, cos_h, sin_h, mount, body_radius, behind, out)
        _see_robot(j, i, centres, cos_h, sin_h, mount, body_radius, behind, out)

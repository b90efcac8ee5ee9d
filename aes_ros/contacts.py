"""Contacts between robot bodies, walls and obstacles (docs/model.md#contacts-walls-and-obstacles).

One rule for the offline simulator (numba kernel and numpy stepper) and the kinematic
pybullet bridge, so that offline and lockstep ROS runs stay bit-equal. A body is a disc of
radius r centred ``axle_offset`` ahead of the robot's pose point (the axle midpoint):
``centre = position + axle_offset (cos θ, sin θ)``. After each Euler step,
:func:`resolve_contacts` separates overlapping bodies by moving their centres (the heading
is kept): position-based separation, a few Gauss-Seidel sweeps over the overlapping
pairs in lexicographic order, each sweep ending with the walls and obstacles. Candidate
pairs come from a spatial grid (:func:`aes_ros.pair_list.near_pairs`); the simulator's
kernel keeps its list (of pairs closer than 5r) over steps until a body has moved r from
where the list saw it (:func:`resolve_listed`, :func:`aes_ros.pair_list.kept_pairs`), which gives
the same bits as a list made afresh.

Every loop runs in a fixed order (ties in robot index order), so the result is
bit-reproducible; positions without an overlap are not written to.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from aes_ros.numba_cache import depend_on
from aes_ros.pair_list import kept_pairs, near_pairs

#: Depth [m] below which two shapes count as touching, not overlapping: a pair just
#: separated sits at 2r up to rounding and must not count again.
SLOP = 1e-9

#: Default number of Gauss-Seidel sweeps per step.
ITERATIONS = 8

#: Pairs whose centres are closer than NEAR body radii are listed as candidates (a
#: Verlet list); the smallest centre distance is reported when below CLOSE radii (else
#: inf), and a list is rebuilt once a body has moved (NEAR - CLOSE) / 2 radii since it
#: was made, so that no pair left out of it can be closer than CLOSE radii.
NEAR, CLOSE = 4.0, 3.0

NO_WALLS = np.empty(0)
NO_CIRCLES = np.empty((0, 3))
NO_BOXES = np.empty((0, 4))


@njit(inline="always")
def _move(
    positions: np.ndarray, cx: np.ndarray, cy: np.ndarray, i: int, mx: float, my: float
) -> None:
    cx[i] += mx
    cy[i] += my
    positions[i, 0] += mx
    positions[i, 1] += my


@njit(cache=True)
def _separate_listed(
    positions: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    radius: float,
    pairs: np.ndarray,
    reach: float,
    within: np.ndarray,
) -> tuple[int, float, int]:
    """One Gauss-Seidel sweep over ``pairs`` in order: each overlapping pair is separated
    in turn, each body moving half the depth along the line of centres, to 2r apart.
    Returns the overlaps found, the smallest squared centre distance [m²] met (that of
    the state after the sweep when it found none) and how many pairs it wrote to the
    first rows of ``within`` (at least as many rows as ``pairs``): those whose centres
    were closer than ``reach`` [m] when the sweep met them (none for reach 0)."""
    touch = 2.0 * radius
    limit2 = (touch - SLOP) * (touch - SLOP)
    reach2 = reach * reach
    found = 0
    kept = 0
    best = np.inf
    for e in range(pairs.shape[0]):
        # unsigned: numba indexes with them without its negative-index wrap (a fifth of
        # the sweep's time); the list holds no negative index
        i = np.uint64(pairs[e, 0])
        j = np.uint64(pairs[e, 1])
        dx = cx[j] - cx[i]
        dy = cy[j] - cy[i]
        d2 = dx * dx + dy * dy
        if d2 < best:  # not a NaN
            best = d2
        within[kept, 0] = i  # written always, kept if near: no branch to mispredict
        within[kept, 1] = j
        kept += d2 < reach2
        if not d2 < limit2:  # also a NaN
            continue
        found += 1
        d = math.sqrt(d2)
        if d > 0.0:
            ux = dx / d
            uy = dy / d
        else:  # coincident centres: split along x, the lower index to -x
            ux = 1.0
            uy = 0.0
        half = 0.5 * (touch - d)
        _move(positions, cx, cy, i, -half * ux, -half * uy)
        _move(positions, cx, cy, j, half * ux, half * uy)
    return found, best, kept


@njit(cache=True)
def _closest(cx: np.ndarray, cy: np.ndarray, pairs: np.ndarray) -> float:
    """The smallest squared centre distance [m²] of ``pairs`` (inf for none; NaN skipped)."""
    best = np.inf
    for e in range(pairs.shape[0]):
        dx = cx[pairs[e, 1]] - cx[pairs[e, 0]]
        dy = cy[pairs[e, 1]] - cy[pairs[e, 0]]
        d2 = dx * dx + dy * dy
        if d2 < best:
            best = d2
    return best


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
    Returns the overlaps found; a body with a non-finite centre is left as it is."""
    n = cx.shape[0]
    found = 0
    if walls.shape[0] != 4 and circles.shape[0] == 0 and boxes.shape[0] == 0:
        return found
    for i in range(n):
        if not (math.isfinite(cx[i]) and math.isfinite(cy[i])):
            continue
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


@njit(cache=True)
def resolve_listed(
    positions: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    radius: float,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
    iterations: int,
    pairs: np.ndarray,
    x_ref: np.ndarray,
    y_ref: np.ndarray,
    near: float,
    skin: float,
    reach: float,
    within: np.ndarray,
) -> tuple[int, float, np.ndarray, np.ndarray, int]:
    """:func:`resolve_contacts` from the body centres cx, cy (N,) [m] (moved in place with
    the positions) and a candidate list ``pairs`` kept by :func:`kept_pairs` (made at
    ``near``, remade once a centre has moved ``skin`` from x_ref, y_ref; near - 2 skin
    must be at least CLOSE radii and ``reach``).

    A sweep resolves the overlapping pairs in lexicographic order; every list that holds
    all pairs that can overlap gives the same sweep, so a list kept over steps (the
    simulator's kernel), or one made with a longer reach, gives the bits of a fresh one
    (:func:`resolve_contacts`).

    Returns the contacts and the smallest centre distance (as :func:`resolve_contacts`),
    the list to use next (valid for the centres it leaves), and, in the first rows of
    ``within`` (P, 2) int64 (the array given, or a larger one when the list outgrew it),
    the pairs of that list whose centres are closer than ``reach`` [m] when it is done:
    as many rows as the last of the five values says, -1 when no sweep met the final
    state (the last one moved bodies). The IR rays of the offline kernel take their
    candidates from these, so that a step goes over its list once.
    """
    n = positions.shape[0]
    if n == 0:
        return 0, np.inf, pairs, within, 0
    contacts = 0
    best = np.inf
    kept = -1
    settled = False  # a sweep found nothing to move: its distances are the final ones
    for sweep in range(iterations + 1):
        pairs = kept_pairs(cx, cy, pairs, x_ref, y_ref, near, skin)
        if sweep == iterations:
            break  # the last pass only checks the list for the distances below
        if within.shape[0] < pairs.shape[0]:
            within = np.empty((pairs.shape[0] + pairs.shape[0] // 2, 2), np.int64)
        found, best, kept = _separate_listed(positions, cx, cy, radius, pairs, reach, within)
        found += _push_out(positions, cx, cy, radius, walls, circles, boxes)
        if sweep == 0:
            contacts = found
        if found == 0:
            settled = True
            break
    if not settled:
        best = _closest(cx, cy, pairs)
        kept = -1
    close = CLOSE * radius
    return contacts, (math.sqrt(best) if best < close * close else np.inf), pairs, within, kept


@njit(cache=True)
def resolve_centres(
    positions: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
    radius: float,
    walls: np.ndarray,
    circles: np.ndarray,
    boxes: np.ndarray,
    iterations: int,
) -> tuple[int, float]:
    """:func:`resolve_listed` with a list made now."""
    if positions.shape[0] == 0:
        return 0, np.inf
    pairs = near_pairs(cx, cy, NEAR * radius)
    found, closest, _, _, _ = resolve_listed(
        positions, cx, cy, radius, walls, circles, boxes, iterations, pairs, cx.copy(), cy.copy(),
        NEAR * radius, 0.5 * (NEAR - CLOSE) * radius, 0.0, np.empty_like(pairs),
    )  # fmt: skip
    return found, closest


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
    min_centre_distance : smallest robot-robot centre distance [m] after resolution;
        inf for one robot and when no two centres are within CLOSE = 3 radii (nothing
        near a contact).
    """
    cx, cy = body_centres(positions, headings, axle_offset)
    return resolve_centres(positions, cx, cy, radius, walls, circles, boxes, iterations)


@njit(cache=True)
def body_centres(
    positions: np.ndarray, headings: np.ndarray, axle_offset: float
) -> tuple[np.ndarray, np.ndarray]:
    """The body centres cx, cy (N,) [m] of pose points ``positions`` (N, 2) [m] and
    ``headings`` (N,) [rad]: ``axle_offset`` [m] ahead of each pose point."""
    n = positions.shape[0]
    cx = np.empty(n)
    cy = np.empty(n)
    fill_body_centres(positions, headings, axle_offset, np.empty(n), np.empty(n), cx, cy)
    return cx, cy


@njit(cache=True)
def fill_body_centres(
    positions: np.ndarray,
    headings: np.ndarray,
    axle_offset: float,
    cos_h: np.ndarray,
    sin_h: np.ndarray,
    cx: np.ndarray,
    cy: np.ndarray,
) -> None:
    """:func:`body_centres` into the (N,) arrays cx, cy given, and the headings' cos and
    sin into cos_h, sin_h (the offline kernel keeps them for its next step)."""
    for i in range(headings.shape[0]):
        # cos and sin of one local: LLVM then makes them one sincos call (stored as they
        # are computed, they stayed two calls, 0.7 µs more per step of 100 robots)
        th = headings[i]
        c = math.cos(th)
        s = math.sin(th)
        cos_h[i] = c
        sin_h[i] = s
        cx[i] = positions[i, 0] + axle_offset * c
        cy[i] = positions[i, 1] + axle_offset * s


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


# Numba's cache checks this file only: an edit of the candidate lists compiled in from
# aes_ros.pair_list must compile these again.
for _compiled in (resolve_listed, resolve_centres, resolve_contacts):
    depend_on(_compiled, "aes_ros.pair_list")

"""Candidate pairs of nearby robots: a spatial grid and a list kept over steps (pure numba).

:func:`near_pairs` finds the pairs of centres closer than a cutoff in a grid of cells of
that side; :func:`kept_pairs` keeps such a list over steps (a Verlet list) while no centre
has moved more than a skin from where it was made (or from where a rigid motion of the
swarm has carried that point). The contact rule (:mod:`aes_ros.contacts`) sweeps these
pairs; the offline kernel's IR rays (:func:`aes_ros.ir.cast_rays_listed`) take theirs from
the same list. docs/model.md, "Contacts, walls and obstacles".
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Distance [m] taken off a list's skin for the rounding of its references.
TOLERANCE = 1e-9


@njit(cache=True)
def near_pairs(cx: np.ndarray, cy: np.ndarray, cutoff: float) -> np.ndarray:
    """The pairs (K, 2) int64 (i, j), i < j, whose centres cx, cy (N,) [m] are closer
    than ``cutoff`` [m], in lexicographic order; found in a grid of cells of that side
    (larger when the robots spread so far that there would be more cells than 3N).
    Robots with a non-finite centre are in no pair."""
    n = cx.shape[0]
    x0 = np.inf
    y0 = np.inf
    x1 = -np.inf
    y1 = -np.inf
    for i in range(n):
        if math.isfinite(cx[i]) and math.isfinite(cy[i]):
            x0 = min(x0, cx[i])
            x1 = max(x1, cx[i])
            y0 = min(y0, cy[i])
            y1 = max(y1, cy[i])
    if x0 > x1:
        return np.empty((0, 2), np.int64)
    wide = x1 - x0
    high = y1 - y0
    cell = max(cutoff, math.sqrt(wide * high / n), max(wide, high) / n)
    nx = int(wide / cell) + 1
    ny = int(high / cell) + 1
    start = np.zeros(nx * ny + 1, np.int64)
    home = np.full(n, -1, np.int64)
    for i in range(n):
        if math.isfinite(cx[i]) and math.isfinite(cy[i]):
            home[i] = min(int((cx[i] - x0) / cell), nx - 1) * ny + min(
                int((cy[i] - y0) / cell), ny - 1
            )
            start[home[i] + 1] += 1
    for k in range(nx * ny):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    members = np.empty(n, np.int64)
    slot_of = np.empty(n, np.int64)
    for i in range(n):  # a counting sort: each cell's robots in index order
        if home[i] >= 0:
            members[fill[home[i]]] = i
            slot_of[i] = fill[home[i]]
            fill[home[i]] += 1
    cutoff2 = cutoff * cutoff
    # every candidate is written and counted only if close (no branch to mispredict), so
    # the buffers hold at least the candidates of the robot at hand
    first = np.empty(4 * n + 16, np.int64)
    second = np.empty(4 * n + 16, np.int64)
    count = 0
    for i in range(n):
        if home[i] < 0:
            continue
        ix = home[i] // ny
        iy = home[i] - ix * ny
        top = min(iy + 1, ny - 1)
        # half the 3 x 3 stencil, so each pair is met once, as two runs of consecutive
        # cells: the own cell after i (members in index order) and the cell above, then
        # the three cells of the next column
        own_first, own_last = slot_of[i] + 1, start[ix * ny + top + 1]
        next_first, next_last = 0, 0
        if ix + 1 < nx:
            next_first = start[(ix + 1) * ny + max(iy - 1, 0)]
            next_last = start[(ix + 1) * ny + top + 1]
        need = count + (own_last - own_first) + (next_last - next_first)
        if need > first.shape[0]:
            first = _grown(first, count, 2 * need)
            second = _grown(second, count, 2 * need)
        for run in range(2):
            lo, hi = (own_first, own_last) if run == 0 else (next_first, next_last)
            for slot in range(lo, hi):
                j = members[slot]
                dx = cx[j] - cx[i]
                dy = cy[j] - cy[i]
                first[count] = min(i, j)
                second[count] = max(i, j)
                count += dx * dx + dy * dy < cutoff2
    return _in_order(first[:count], second[:count], n)


@njit(cache=True)
def _grown(values: np.ndarray, count: int, size: int) -> np.ndarray:
    """A copy of ``values[:count]`` in a new array of ``size``."""
    out = np.empty(size, values.dtype)
    out[:count] = values[:count]
    return out


@njit(cache=True)
def _in_order(first: np.ndarray, second: np.ndarray, n: int) -> np.ndarray:
    """The pairs (first[e], second[e]) (K,) in lexicographic order, as (K, 2): a counting
    sort by the first index, then each index's few partners by insertion."""
    end = np.zeros(n + 1, np.int64)
    for e in range(first.shape[0]):
        end[first[e] + 1] += 1
    for i in range(n):
        end[i + 1] += end[i]
    pairs = np.empty((first.shape[0], 2), np.int64)
    for e in range(first.shape[0]):  # end[i] runs from where i's pairs start to their end
        slot = end[first[e]]
        end[first[e]] = slot + 1
        pairs[slot, 0] = first[e]
        pairs[slot, 1] = second[e]
    begin = 0
    for i in range(n):
        for slot in range(begin + 1, end[i]):
            j = pairs[slot, 1]
            into = slot
            while into > begin and pairs[into - 1, 1] > j:
                pairs[into, 1] = pairs[into - 1, 1]
                into -= 1
            pairs[into, 1] = j
        begin = end[i]
    return pairs


@njit(cache=True)
def _stale(
    cx: np.ndarray, cy: np.ndarray, x_ref: np.ndarray, y_ref: np.ndarray, skin: float
) -> bool:
    """Whether a centre has moved more than ``skin`` [m] since the list was made."""
    moved = 0  # counted over all centres, without a branch, so the loop runs in SIMD
    for i in range(cx.shape[0]):
        dx = cx[i] - x_ref[i]
        dy = cy[i] - y_ref[i]
        moved += not dx * dx + dy * dy <= skin * skin  # also a NaN
    return moved > 0


@njit(cache=True)
def _follow_rigidly(cx: np.ndarray, cy: np.ndarray, x_ref: np.ndarray, y_ref: np.ndarray) -> None:
    """Move the reference centres x_ref, y_ref (N,) [m] by the rotation and translation
    that carry them closest to cx, cy (N,) [m] (least squares, 2-D Kabsch)."""
    n = cx.shape[0]
    ax = 0.0
    ay = 0.0
    bx = 0.0
    by = 0.0
    for i in range(n):
        ax += x_ref[i]
        ay += y_ref[i]
        bx += cx[i]
        by += cy[i]
    ax /= n
    ay /= n
    bx /= n
    by /= n
    dot = 0.0
    cross = 0.0
    for i in range(n):
        px = x_ref[i] - ax
        py = y_ref[i] - ay
        qx = cx[i] - bx
        qy = cy[i] - by
        dot += px * qx + py * qy
        cross += px * qy - py * qx
    angle = math.atan2(cross, dot)
    c = math.cos(angle)
    s = math.sin(angle)
    for i in range(n):
        px = x_ref[i] - ax
        py = y_ref[i] - ay
        x_ref[i] = bx + c * px - s * py
        y_ref[i] = by + s * px + c * py


@njit(cache=True)
def kept_pairs(
    cx: np.ndarray,
    cy: np.ndarray,
    pairs: np.ndarray,
    x_ref: np.ndarray,
    y_ref: np.ndarray,
    near: float,
    skin: float,
) -> np.ndarray:
    """A candidate list (a Verlet list) kept over steps: ``pairs``, made by
    :func:`near_pairs` at ``near`` [m], while every centre cx, cy (N,) [m] is within
    ``skin`` [m] of its reference x_ref, y_ref (N,); else a list made now, with the
    references set to cx, cy. The list returned holds every pair whose centres are closer
    than near - 2 skin.

    The references start as the centres the list was made at and may follow any rigid
    motion (a rotation and a translation keep every distance): before remaking the list,
    they follow the one that fits the swarm's move best, so a sheet that turns and drives
    as a body keeps its list for longer (in the combined scenario about half as many lists
    are made). Rounding in that motion is far below the ``TOLERANCE`` taken off the skin.
    """
    if not _stale(cx, cy, x_ref, y_ref, skin - TOLERANCE):
        return pairs
    if math.isfinite(x_ref[0]):  # inf: no list yet (else the centres a list was made at)
        _follow_rigidly(cx, cy, x_ref, y_ref)
        if not _stale(cx, cy, x_ref, y_ref, skin - TOLERANCE):
            return pairs
    x_ref[:] = cx
    y_ref[:] = cy
    return near_pairs(cx, cy, near)

"""Nominal formations and the elastic sheet they define (docs/design.md#sheet, #scenarios).

A formation is an ``(N, 2)`` array of nominal positions [m; odom]. The sheet,
i.e. each robot's neighbour set S_i and rest lengths l_ij, comes from the
nominal positions only, never from a perturbed start.

Neighbours are stored as a padded table: ``neighbors (N, K)`` of robot indices
with ``-1`` where robot i has fewer than K neighbours, and ``rest_lengths (N, K)``
(0 in padded slots). The same layout serves the vectorised simulator, the
fused kernel and the per-robot ROS parameters (one row each).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from aes_ros.params import ParameterError


def square_grid(rows: int, cols: int, spacing: float) -> np.ndarray:
    """Square grid centred on the origin, row-major ids.

    Returns positions ``(rows*cols, 2)`` [m]. Robot ``r*cols + c`` sits at
    column c (x) and row r (y).
    """
    if rows < 1 or cols < 1:
        raise ParameterError(f"rows, cols: need at least 1 each, got {rows} x {cols}")
    if not spacing > 0:
        raise ParameterError(f"spacing: {spacing!r} is not allowed; need a positive distance [m]")
    c, r = np.meshgrid(np.arange(cols), np.arange(rows))
    xy = np.stack([c.ravel(), r.ravel()], axis=-1).astype(float) * spacing
    return xy - xy.mean(axis=0)


def hexagonal_sheet(rings: int, spacing: float) -> np.ndarray:
    """Hexagonal patch of ``rings`` rings around a centre robot.

    Returns positions ``(3s(s+1)+1, 2)`` [m], centred on the origin, every
    robot at ``spacing`` from its six lattice neighbours.
    """
    if rings < 0:
        raise ParameterError(f"rings: {rings} is not allowed; need an integer >= 0")
    if not spacing > 0:
        raise ParameterError(f"spacing: {spacing!r} is not allowed; need a positive distance [m]")
    pts = [
        (q + r / 2.0, r * np.sqrt(3.0) / 2.0)
        for r in range(-rings, rings + 1)
        for q in range(-rings, rings + 1)
        if abs(q + r) <= rings
    ]
    return np.asarray(pts) * spacing


def from_csv(path: str | Path) -> np.ndarray:
    """Read nominal positions from a CSV file with columns ``x,y`` [m] (header optional)."""
    path = Path(path)
    try:
        with path.open(newline="") as fh:
            rows = [row for row in csv.reader(fh) if row and not row[0].startswith("#")]
    except OSError as exc:
        raise ParameterError(
            f"formation_file: cannot read {str(path)!r} ({exc.strerror})"
        ) from None
    if rows and not _is_number(rows[0][0]):
        rows = rows[1:]
    try:
        xy = np.array([[float(row[0]), float(row[1])] for row in rows])
    except (ValueError, IndexError):
        raise ParameterError(
            f"formation_file: {str(path)!r} must hold rows of two numbers 'x,y' [m]"
        ) from None
    if len(xy) < 1 or not np.all(np.isfinite(xy)):
        raise ParameterError(f"formation_file: {str(path)!r} holds no finite positions")
    return xy


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def neighbor_table(nominal: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Neighbour sets S_i and rest lengths l_ij from nominal positions (docs/design.md#sheet).

    Parameters
    ----------
    nominal : (N, 2) nominal positions [m].
    radius : neighbour radius [m]; j is a neighbour of i when 0 < |x_j - x_i| <= radius.

    Returns
    -------
    neighbors : (N, K) int64, neighbour ids in increasing order, -1 padded.
    rest_lengths : (N, K) float64, l_ij [m], 0 in padded slots.

    Notes
    -----
    The candidate pairs come from a k-d tree (O(N log N) time and memory, so that a
    sheet of any N a message announces can be built), and each is decided on
    ``|x_j - x_i| <= radius`` exactly as the all-pairs distance matrix of
    :func:`_neighbor_table_dense` decides it (the tests compare the two).
    """
    from scipy.spatial import cKDTree

    nominal = np.asarray(nominal, dtype=float)
    n = len(nominal)
    # a little wider than radius: the tree's rounding must not lose a pair at the edge
    pairs = cKDTree(nominal).query_pairs(radius * (1 + 1e-9) + 1e-12, output_type="ndarray")
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    dist = np.linalg.norm(nominal[i] - nominal[j], axis=-1)
    keep = dist <= radius
    i, j, dist = i[keep], j[keep], dist[keep]
    order = np.lexsort((j, i))
    i, j, dist = i[order], j[order], dist[order]
    degree = np.bincount(i, minlength=n)
    K = max(int(degree.max(initial=0)), 1)
    slot = np.arange(len(i)) - np.repeat(np.cumsum(degree) - degree, degree)
    neighbors = np.full((n, K), -1, dtype=np.int64)
    rest = np.zeros((n, K))
    neighbors[i, slot] = j
    rest[i, slot] = dist
    return neighbors, rest


def _neighbor_table_dense(nominal: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`neighbor_table` from the (N, N) distance matrix: the plain reference."""
    nominal = np.asarray(nominal, dtype=float)
    dist = np.linalg.norm(nominal[:, None, :] - nominal[None, :, :], axis=-1)
    linked = (dist <= radius) & ~np.eye(len(nominal), dtype=bool)
    degree = linked.sum(axis=1)
    K = max(int(degree.max(initial=0)), 1)
    neighbors = np.full((len(nominal), K), -1, dtype=np.int64)
    rest = np.zeros((len(nominal), K))
    for i in range(len(nominal)):
        js = np.flatnonzero(linked[i])
        neighbors[i, : len(js)] = js
        rest[i, : len(js)] = dist[i, js]
    return neighbors, rest


def spring_pairs(neighbors: np.ndarray) -> np.ndarray:
    """Undirected springs ``(M, 2)`` with i < j, for drawing the sheet."""
    i, slot = np.nonzero(neighbors >= 0)
    j = neighbors[i, slot]
    keep = i < j
    return np.stack([i[keep], j[keep]], axis=-1)


def perturbed_start(
    nominal: np.ndarray, spacing: float, perturbation: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Initial state of one run (docs/design.md#scenarios).

    Positions are the nominal ones plus a uniform offset in
    ``[-perturbation*spacing, perturbation*spacing]`` per axis; headings are
    uniform in [-π, π). Draws positions first, then headings, from ``rng``.

    Returns positions ``(N, 2)`` [m] and headings ``(N,)`` [rad].
    """
    n = len(nominal)
    offset = rng.uniform(-1.0, 1.0, size=(n, 2)) * (perturbation * spacing)
    headings = rng.uniform(-np.pi, np.pi, size=n)
    return nominal + offset, headings

"""The sheet's springs for the offline kernel (:mod:`aes_ros.kernel`), each listed once, and
their forces (E1) a spring at a time: with perception on, the kernel needs two spring forces
per robot and step (the true one and the perceived one), and computing each spring once, ±
on its two robots, makes the two cost about what one did per robot."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def spring_list(neighbors: np.ndarray, rest_lengths: np.ndarray) -> tuple[np.ndarray, ...]:
    """The sheet's springs for :func:`aes_ros.kernel.advance`: each spring once.

    neighbors : (N, K) int64, -1 padded; rest_lengths : (N, K) [m].
    Returns ends (S, 2) int64 (i, j), rest (S,) [m] and mutual (S,) bool: True when
    j also has i as a neighbour with the same rest length (the spring acts on both;
    listed once, with i < j), False for a one-way link (acts on i only).
    """
    i, slot = np.nonzero(neighbors >= 0)
    j = neighbors[i, slot]
    rest = rest_lengths[i, slot]
    n = max(len(neighbors), 1)
    key = dict(zip((i * n + j).tolist(), rest.tolist(), strict=True))
    mutual = np.array([key.get(b * n + a) == r for a, b, r in zip(i, j, rest, strict=True)])
    keep = ~mutual | (i < j)
    ends = np.stack([i[keep], j[keep]], axis=1).astype(np.int64)
    return ends, rest[keep].astype(float), mutual[keep]


@njit(inline="always")
def spring_forces(
    frame: np.ndarray,
    ends: np.ndarray,
    stiffness: np.ndarray,
    rest: np.ndarray,
    mutual: np.ndarray,
    out: np.ndarray,
) -> None:
    """Spring forces (E1) on every robot from positions ``frame`` (N, ≥2) [m] into
    ``out`` (N, 2), a spring at a time; ``stiffness`` = k / l per spring."""
    out[:, :] = 0.0
    for e in range(ends.shape[0]):
        i = ends[e, 0]
        j = ends[e, 1]
        rx = frame[j, 0] - frame[i, 0]
        ry = frame[j, 1] - frame[i, 1]
        d = math.sqrt(rx * rx + ry * ry)
        if d > 0.0:
            scale = stiffness[e] * (d - rest[e]) / d
            out[i, 0] += scale * rx
            out[i, 1] += scale * ry
            if mutual[e]:
                out[j, 0] -= scale * rx
                out[j, 1] -= scale * ry

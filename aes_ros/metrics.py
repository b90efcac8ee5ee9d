"""Swarm metrics (docs/design.md#metrics, E7–E9), reduced over the trailing robot axis.

All take the noise-free force f_i of E4. Shapes: ``forces (..., N, 2)``,
``headings (..., N)`` [rad], ``positions (..., N, 2)`` [m]; results have shape
``(...)``. Beyond docs/design.md#metrics, :func:`spring_strain` measures how far the sheet
has come apart (the tuning study's cohesion column).
"""

from __future__ import annotations

import numpy as np

#: Forces below this magnitude [N] count as zero in E8: a sheet exactly at its
#: rest lengths has round-off forces (~1e-16) whose direction is meaningless.
FORCE_EPS = 1e-9


def heading_order(headings: np.ndarray) -> np.ndarray:
    """Ferrante's heading order (E7): ψ_heading = |(1/N) Σ_i n̂_i| in [0, 1]."""
    return np.hypot(np.cos(headings).mean(axis=-1), np.sin(headings).mean(axis=-1))


def alignment_order(forces: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """Raoufi's force alignment (E8): ψ = (1/N) Σ_i |f_i·n̂_i| / |f_i|.

    ψ_i = 1 when |f_i| <= FORCE_EPS (a robot with no force is not misaligned).
    """
    norm = np.sqrt(np.sum(forces * forces, axis=-1))
    along = np.abs(forces[..., 0] * np.cos(headings) + forces[..., 1] * np.sin(headings))
    has_force = norm > FORCE_EPS
    psi_i = np.where(has_force, along / np.where(has_force, norm, 1.0), 1.0)
    return psi_i.mean(axis=-1)


def total_force(forces: np.ndarray) -> np.ndarray:
    """Total force magnitude (E9): F = Σ_i |f_i|."""
    return np.sqrt(np.sum(forces * forces, axis=-1)).sum(axis=-1)


def centroid_velocity(positions: np.ndarray, dt: float) -> np.ndarray:
    """Centroid velocity [m/s] by finite differences along the time axis.

    positions : (..., T, N, 2) sampled every ``dt`` [s]. Returns (..., T-1, 2).
    """
    c = positions.mean(axis=-2)
    return np.diff(c, axis=-2) / dt


def rotation_angle(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Least-squares rigid rotation [rad] of a point set about its centroid.

    before, after : (..., N, 2). Both are centred on their own centroids; the
    angle that best maps one onto the other is atan2(Σ a×b, Σ a·b).
    Returns (...), counter-clockwise positive.
    """
    a = before - before.mean(axis=-2, keepdims=True)
    b = after - after.mean(axis=-2, keepdims=True)
    cross = np.sum(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0], axis=-1)
    dot = np.sum(a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1], axis=-1)
    return np.arctan2(cross, dot)


def angular_velocity(positions: np.ndarray, dt: float) -> np.ndarray:
    """Angular velocity [rad/s] of the swarm about its centroid between samples.

    positions : (..., T, N, 2) sampled every ``dt`` [s]. Returns (..., T-1).
    """
    return rotation_angle(positions[..., :-1, :, :], positions[..., 1:, :, :]) / dt


def spring_strain(positions: np.ndarray, neighbors: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """Mean relative spring deformation |‖r_ij‖ − l_ij| / l_ij of each formation.

    positions : (..., N, 2); neighbors, rest : (N, K), −1 padded. Returns (...).
    0 for the nominal sheet; ≳ 1 means the formation has come apart.
    """
    active = neighbors >= 0
    offsets = positions[..., np.where(active, neighbors, 0), :] - positions[..., :, None, :]
    dist = np.linalg.norm(offsets, axis=-1)
    rel = np.abs(dist - rest) / np.where(active, rest, 1.0)
    return rel[..., active].mean(axis=-1)

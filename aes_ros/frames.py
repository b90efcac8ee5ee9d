"""Planar poses in ROS frames (REP-103): yaw about z ↔ unit quaternion (x, y, z, w).

The one definition of that conversion, shared by the message conversions
(:mod:`aes_ros.ros.conversions`, :mod:`aes_ros.ros.cdr`) and the pybullet world
(:mod:`sim_bridge.world`).
"""

from __future__ import annotations

import math

import numpy as np


def yaw_from_quaternion(q: np.ndarray) -> np.ndarray:
    """Yaw [rad, in [-π, π]] of quaternions ``q: (..., 4)`` in xyzw order.

    The rotation about z of the quaternion's frame; roll and pitch are ignored.
    Returns shape ``(...)``.
    """
    x, y, z, w = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def planar_yaw(x: float, y: float, z: float, w: float) -> float:
    """:func:`yaw_from_quaternion` of one quaternion in plain floats: for a message per
    robot per step, where numpy's per-call cost would dominate."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_yaw(yaw: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` (xyzw) of rotations about z by ``yaw: (...)`` [rad]."""
    half = 0.5 * np.asarray(yaw, dtype=float)
    q = np.zeros((*half.shape, 4))
    q[..., 2] = np.sin(half)
    q[..., 3] = np.cos(half)
    return q

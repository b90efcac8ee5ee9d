"""Messages to arrays and back: the one boundary between ROS and the model.

Input is cleaned here: a message with NaN/inf or the wrong length raises
:class:`BadMessageError` (callers drop it with a throttled warning) instead of
reaching the model.
"""

from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import Pose, PoseArray, Quaternion


class BadMessageError(ValueError):
    """A message that must be dropped (non-finite values, wrong size)."""


def yaw_to_quaternion(yaw: float) -> Quaternion:
    """Rotation about z by ``yaw`` [rad] as a ROS quaternion (xyzw)."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))


def quaternion_to_yaw(q: Quaternion) -> float:
    """Yaw [rad] of a ROS quaternion (rotation about z; roll and pitch ignored)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def pose_to_array(pose: Pose) -> tuple[float, float, float]:
    """(x, y, yaw) of a Pose; raises BadMessageError if any value is not finite."""
    values = (pose.position.x, pose.position.y, quaternion_to_yaw(pose.orientation))
    if not all(math.isfinite(v) for v in values):
        raise BadMessageError("pose has a non-finite value")
    return values


def poses_to_arrays(msg: PoseArray, expected: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 2) [m] and headings (N,) [rad] of a PoseArray (index = robot id).

    Raises BadMessageError when the array's length differs from ``expected`` or a
    value is not finite.
    """
    n = len(msg.poses)
    if expected is not None and n != expected:
        raise BadMessageError(f"PoseArray has {n} poses, expected {expected}")
    xy = np.empty((n, 2))
    q = np.empty((n, 4))
    for i, p in enumerate(msg.poses):
        xy[i] = (p.position.x, p.position.y)
        o = p.orientation
        q[i] = (o.x, o.y, o.z, o.w)
    yaw = np.arctan2(
        2.0 * (q[:, 3] * q[:, 2] + q[:, 0] * q[:, 1]), 1.0 - 2.0 * (q[:, 1] ** 2 + q[:, 2] ** 2)
    )
    if not (np.all(np.isfinite(xy)) and np.all(np.isfinite(yaw))):
        raise BadMessageError("PoseArray has a non-finite value")
    return xy, yaw


def arrays_to_poses(positions: np.ndarray, headings: np.ndarray) -> list[Pose]:
    """Poses for positions (N, 2) [m] and headings (N,) [rad] (z = 0)."""
    out = []
    for (x, y), yaw in zip(positions.tolist(), headings.tolist(), strict=True):
        p = Pose()
        p.position.x, p.position.y = x, y
        p.orientation = yaw_to_quaternion(yaw)
        out.append(p)
    return out

"""Messages to arrays and back: the one boundary between ROS and the model.

Input is cleaned here: a message with NaN/inf, a coordinate beyond
:data:`MAX_COORDINATE` or the wrong length raises :class:`BadMessageError`
(callers drop it with a throttled warning and keep the last good value) instead
of reaching the model. Within that bound the model's output is finite
(tests/unit/test_conversions.py checks it with hypothesis).
"""

from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose, PoseArray, Quaternion, Twist
from nav_msgs.msg import Odometry

from aes_ros.frames import planar_yaw, yaw_from_quaternion

#: Largest accepted |x|, |y| of a position [m]: far beyond any arena, and small
#: enough that squared distances and spring forces stay finite in float64.
MAX_COORDINATE = 1e6
#: Largest accepted quaternion component: a rotation has all four in [-1, 1]; a
#: little slack for publishers that do not normalise.
MAX_QUATERNION = 2.0


class BadMessageError(ValueError):
    """A message that must be dropped (non-finite or out-of-range values, wrong size)."""


def _check_coordinates(values, what: str) -> None:
    arr = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise BadMessageError(f"{what} has a non-finite value")
    if arr.size and np.abs(arr).max() > MAX_COORDINATE:
        raise BadMessageError(f"{what} has a coordinate beyond ±{MAX_COORDINATE:g} m")


def yaw_to_quaternion(yaw: float) -> Quaternion:
    """Rotation about z by ``yaw`` [rad] as a ROS quaternion (xyzw)."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))


def quaternion_to_yaw(q: Quaternion) -> float:
    """Yaw [rad] of a ROS quaternion (rotation about z; roll and pitch ignored)."""
    return float(yaw_from_quaternion((q.x, q.y, q.z, q.w)))


def pose_to_array(pose: Pose) -> tuple[float, float, float]:
    """(x, y, yaw) of a Pose; raises BadMessageError if a value is not finite or a
    coordinate is beyond ±MAX_COORDINATE."""
    o = pose.orientation
    return planar_pose(pose.position.x, pose.position.y, o.x, o.y, o.z, o.w)


def planar_pose(
    x: float, y: float, qx: float, qy: float, qz: float, qw: float
) -> tuple[float, float, float]:
    """(x, y, yaw) of one pose, with the checks of :func:`planar_poses` in plain floats
    (a message per robot per step: numpy's per-call cost would dominate)."""
    if not all(abs(v) <= MAX_QUATERNION for v in (qx, qy, qz, qw)):  # also false for NaN
        raise BadMessageError("pose has an orientation that is not a rotation")
    if not (math.isfinite(x) and math.isfinite(y)):
        raise BadMessageError("pose has a non-finite value")
    if abs(x) > MAX_COORDINATE or abs(y) > MAX_COORDINATE:
        raise BadMessageError(f"pose has a coordinate beyond ±{MAX_COORDINATE:g} m")
    return x, y, planar_yaw(qx, qy, qz, qw)


def poses_to_arrays(msg: PoseArray, expected: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 2) [m] and headings (N,) [rad] of a PoseArray (index = robot id).

    Raises BadMessageError when the array's length differs from ``expected``, a
    value is not finite or a coordinate is beyond ±MAX_COORDINATE.
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
    return planar_poses(xy, q)


def planar_poses(xy: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Checked positions ``xy: (N, 2)`` [m] and yaw (N,) [rad] of quaternions ``q: (N, 4)`` (xyzw).

    The checks of every PoseArray, however it was read (message or wire format,
    :mod:`aes_ros.ros.cdr`): raises BadMessageError for a non-finite value, a
    coordinate beyond ±MAX_COORDINATE or a quaternion component beyond ±MAX_QUATERNION.
    """
    if not np.all(np.abs(q) <= MAX_QUATERNION):  # also false for NaN
        raise BadMessageError("PoseArray has an orientation that is not a rotation")
    yaw = yaw_from_quaternion(q)
    _check_coordinates(xy, "PoseArray")
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


# --- stamps, odometry, commands (robot node and supervisor) -------------------


def stamp_to_ns(stamp: Time) -> int:
    """A ``builtin_interfaces/Time`` as integer nanoseconds."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def odom_to_pose(msg: Odometry) -> tuple[int, float, float, float]:
    """(stamp [ns], x [m], y [m], yaw [rad]) of an Odometry message's pose in its frame.

    Raises BadMessageError if a value is not finite.
    """
    x, y, yaw = pose_to_array(msg.pose.pose)
    return stamp_to_ns(msg.header.stamp), x, y, yaw


def point_to_array(point: Point) -> np.ndarray:
    """(x, y) [m] of a Point (z ignored); raises BadMessageError if not finite or
    beyond ±MAX_COORDINATE."""
    xy = np.array([point.x, point.y])
    _check_coordinates(xy, "point")
    return xy


def twist_to_drive(twist: Twist) -> tuple[tuple[float, float], float]:
    """Desired direction v_d = (linear.x, linear.y) and ω = angular.z of a Twist.

    Used for ``/swarm/desired_velocity`` and ``/swarm/cmd`` (docs/design.md#ros-interface); raises
    BadMessageError if one of the three values is not finite.
    """
    values = (twist.linear.x, twist.linear.y, twist.angular.z)
    if not all(math.isfinite(v) for v in values):
        raise BadMessageError("twist has a non-finite value")
    return (values[0], values[1]), values[2]


def drive_to_twist(direction: tuple[float, float], omega: float) -> Twist:
    """Twist with linear.{x,y} = v_d and angular.z = ω (the inverse of twist_to_drive)."""
    msg = Twist()
    msg.linear.x, msg.linear.y = float(direction[0]), float(direction[1])
    msg.angular.z = float(omega)
    return msg


def unicycle_twist(linear: float, angular: float) -> Twist:
    """``cmd_vel`` of a unicycle: linear.x forward [m/s], angular.z [rad/s], rest 0."""
    msg = Twist()
    msg.linear.x = float(linear)
    msg.angular.z = float(angular)
    return msg

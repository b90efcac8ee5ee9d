"""Messages the tests build and read (no DDS: usable by unit and system tests)."""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseArray, Twist, TwistStamped
from nav_msgs.msg import Odometry

from aes_ros.ros.conversions import arrays_to_poses, stamp_to_ns, yaw_to_quaternion
from aes_ros.ros.interface import WORLD_FRAME


def stamp(t: float) -> Time:
    """Sim time ``t`` [s] as a ``builtin_interfaces/Time``."""
    ns = round(t * 1e9)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def seconds(msg) -> float:
    """The header stamp of ``msg`` [s]."""
    return stamp_to_ns(msg.header.stamp) * 1e-9


def poses_msg(xy, yaw, t: float) -> PoseArray:
    """``/swarm/poses`` of positions ``xy`` (N, 2) [m] and headings ``yaw`` (N,) [rad] at ``t``."""
    msg = PoseArray()
    msg.header.frame_id = WORLD_FRAME
    msg.header.stamp = stamp(t)
    msg.poses = arrays_to_poses(np.asarray(xy, dtype=float), np.asarray(yaw, dtype=float))
    return msg


def odom_msg(x: float, y: float, yaw: float, t: float) -> Odometry:
    """A robot's odometry at (x, y) [m] with heading ``yaw`` [rad] at ``t``."""
    msg = Odometry()
    msg.header.frame_id = WORLD_FRAME
    msg.header.stamp = stamp(t)
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation = yaw_to_quaternion(yaw)
    return msg


def twist(vx: float = 0.0, vy: float = 0.0, w: float = 0.0) -> Twist:
    """A Twist with linear.x, linear.y and angular.z (any float, NaN included)."""
    msg = Twist()
    msg.linear.x, msg.linear.y, msg.angular.z = float(vx), float(vy), float(w)
    return msg


def twist_stamped(vx: float = 0.0, vy: float = 0.0, w: float = 0.0) -> TwistStamped:
    """A TwistStamped with linear.x, linear.y and angular.z."""
    return TwistStamped(twist=twist(vx, vy, w))

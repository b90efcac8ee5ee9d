"""QoS profiles of the AES interface (SPEC §7).

Pose and odometry streams are sensor data (best-effort, keep-last 1); commands
are reliable; supervisor topics are reliable and transient-local so that a late
robot receives the last value.
"""

from __future__ import annotations

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

#: /swarm/poses, /mona_<i>/odom
SENSOR = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)

#: cmd_vel, aes_force, /swarm/cmd
COMMAND = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

#: /swarm/desired_velocity, /swarm/rotation_center, /swarm/alignment, … (supervisor → all)
LATCHED = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

"""QoS profiles of the AES interface (docs/design.md#ros-interface).

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

#: The robots' cmd_vel publishers: COMMAND, with the last 100 commands kept (a
#: reader that missed a burst of datagrams, a recorder on a loaded machine, is
#: resent them; with 10 a burst of 19 was lost) and given to late readers that ask
#: for them (transient-local). Only the recorder does: it would otherwise miss
#: the first commands of a robot published before discovery matched the two
#: (tests/system/test_recording.py). Volatile readers (the bridge, a motor driver) match
#: as before and never receive old commands.
COMMAND_KEPT = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

#: The bridge's cmd_vel subscriptions: only the newest command matters to a motor.
#: Publishers stay reliable (COMMAND; a best-effort reader matches them): with a
#: reliable reader, one lost datagram holds back every later command of that robot
#: until the writer's next heartbeat (3 s by default), so under packet loss the
#: bridge would drive with stale commands (tests/system/test_multihost.py).
LATEST_COMMAND = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)

#: /swarm/desired_velocity, /swarm/rotation_center, /swarm/alignment, … (supervisor → all)
LATCHED = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

#: The supervisor's publishers of those topics. Same contract as LATCHED (a late
#: reader of depth 1 still gets only the newest value), but the writer keeps its
#: last 100 samples: with a history of 1 a sample is replaced by the next one
#: before a reader that missed a datagram (a busy recorder) can ask for it again,
#: and the bag would lack it (tests/system/test_recording.py).
LATCHED_WRITER = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

#: Queue depth of the readers whose messages are a run's outputs (the recorder's, the
#: launcher's of the poses): the middleware's threads go on receiving (and acknowledging)
#: into them while the reader's executor is held up, so they bound how long it may lag
#: (1000 messages: 20 s at 50 Hz, 5 s of a lockstep run at full speed). They hold
#: messages only while the reader lags, so a deep one costs memory only then.
#: docs/reliability.md#runs-of-hours.
OUTPUT_DEPTH = 1000


#: The publishers of /clock and /swarm/poses (the bridge's, the tracker's) and of
#: /sim/ground_truth/poses. Every reader in the system reads them best-effort (SENSOR:
#: a late pose is worthless to a controller; rclpy's /clock subscription is best-effort
#: too), which a reliable writer serves just the same. The recorder and the launcher
#: read them reliably, so that a datagram missed while busy is resent instead of
#: leaving a step out of the bag or the run's outputs (tests/system/test_recording.py,
#: tests/system/test_perception_ros.py). The writer keeps as many as those readers
#: queue: a reader whose whole process is held up (descheduled, stopped) acknowledges
#: nothing, and with a history of 50 a launcher stopped for 1.5 s of a lockstep run at
#: full speed (over 160 steps/s) found the samples it had missed gone, the next one past
#: the run's end, and its outputs ended at 0.35 s of 10 (test_perception_ros).
STREAM_WRITER = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=OUTPUT_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)


#: /swarm/markers as a viewer reads it (RViz2, Foxglove): reliable (RViz2's default)
#: and only the newest; a viewer that lags skips to the latest picture.
DISPLAY = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)

#: The dashboard's publisher of /swarm/markers: the writer keeps the last 20 pictures
#: (2 s at 10 Hz) to resend to a reader that missed them. With a history of one, the
#: recorder lost a picture whenever it fell one frame behind: 4 in the hour's chaos
#: soak on a shared machine (docs/reliability.md), sequence gaps that the middleware
#: does not report as lost. Viewers still keep only the newest (DISPLAY).
DISPLAY_WRITER = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE)

#: /arena_camera/image_raw (camera → tracker): reliable, only the newest frame. A
#: 1.2 MB frame is larger than Fast DDS's shared-memory segment and travels as ~20 UDP
#: fragments; best-effort, losing any one lost the frame (the tracker got 38 % of
#: 20 frames/s on this machine). Reliable resends the missing fragments; depth 1 lets a
#: slow tracker skip to the newest frame rather than queue old ones.
IMAGES = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)

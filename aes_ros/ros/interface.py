"""The names of the AES ROS 2 interface (SPEC §7), defined once.

Topic, service, node and frame names, the choices of the string parameters and
the ready signals that nodes print and the launcher and the tests wait for:
whatever two parts of the system must agree on. Plain constants, no rclpy, so
that pure modules (the launch plan, the pybullet world) can use them too.
"""

from __future__ import annotations

# --- frames (REP-105) ------------------------------------------------------------------

#: The world frame of every pose, force and marker.
WORLD_FRAME = "odom"


def base_link(robot_id: int) -> str:
    """Frame of robot ``robot_id``'s body: ``mona_<i>/base_link``."""
    return f"mona_{robot_id}/base_link"


# --- robots: namespace /mona_<i> ------------------------------------------------------

#: Topics relative to a robot's namespace.
CMD_VEL = "cmd_vel"
ODOM = "odom"
AES_FORCE = "aes_force"


def robot_namespace(robot_id: int) -> str:
    """``/mona_<i>``: the namespace of robot ``robot_id``'s topics and node."""
    return f"/mona_{robot_id}"


def robot_topic(robot_id: int, name: str) -> str:
    """Absolute name of a robot's topic, e.g. ``robot_topic(3, CMD_VEL)`` = ``/mona_3/cmd_vel``."""
    return f"{robot_namespace(robot_id)}/{name}"


#: Pattern of a robot's namespace (the robot id is its one group).
ROBOT_NAMESPACE_PATTERN = r"/mona_(\d+)"

# --- swarm level -------------------------------------------------------------------------

CLOCK = "/clock"
POSES = "/swarm/poses"
DESIRED_VELOCITY = "/swarm/desired_velocity"
ROTATION_CENTER = "/swarm/rotation_center"
ENABLED = "/swarm/enabled"
CMD = "/swarm/cmd"
ALIGNMENT = "/swarm/alignment"
HEADING_ORDER = "/swarm/heading_order"
TOTAL_FORCE = "/swarm/total_force"
#: visualization_msgs/MarkerArray of the swarm for RViz2 and Foxglove (the dashboard's).
MARKERS = "/swarm/markers"
#: The overhead camera (SPEC §8): sensor_msgs/Image (mono8, stamp = exposure time) and
#: sensor_msgs/CameraInfo (its true intrinsics and distortion).
CAMERA_IMAGE = "/arena_camera/image_raw"
CAMERA_INFO = "/arena_camera/camera_info"
#: The bridge's exact poses while a tracker publishes /swarm/poses: for evaluation only,
#: never read by the control loop.
GROUND_TRUTH_POSES = "/sim/ground_truth/poses"
#: The simulated camera's and the tracker's node names.
CAMERA_NODE = "arena_camera"
TRACKER_NODE = "tracker"
#: The frame of the camera's images (REP-105 style: a sensor frame of its own).
CAMERA_FRAME = "arena_camera"
#: diagnostic_msgs/DiagnosticArray: the bridge's view of which robots are silent
#: (:mod:`aes_ros.ros.diagnostics`).
DIAGNOSTICS = "/diagnostics"

#: The recorder's progress: the stamp of the latest ``/swarm/poses`` it has written
#: (rosgraph_msgs/Clock). A lockstep bridge with ``wait_for_recorder`` waits for it.
RECORDER_PROGRESS = "/recorder/progress"

# --- services ----------------------------------------------------------------------------

ENABLE = "/swarm/enable"
SIM_RESET = "/sim/reset"
SIM_PAUSE = "/sim/pause"
SIM_STATS = "/sim/stats"

# --- nodes -------------------------------------------------------------------------------

ROBOT_NODE = "aes_robot"
ROBOT_HOST_NODE = "robot_host"
SUPERVISOR_NODE = "supervisor"
SIM_BRIDGE_NODE = "sim_bridge"
RECORDER_NODE = "aes_recorder"
LAUNCHER_NODE = "aes_launcher"
STEER_NODE = "aes_steer"
DASHBOARD_NODE = "dashboard"

# --- choices of string parameters and options --------------------------------------------

#: Where a robot's neighbour positions come from.
NEIGHBOR_SOURCES = ("poses", "odom")
#: How the bridge moves the bodies.
MODES = ("kinematic", "dynamic")
#: How ``aes-swarm launch`` spreads the robots over processes.
LAYOUTS = ("auto", "single", "per-core", "per-robot")
#: The supervisor's rotation centre: the live centroid or a fixed point.
CENTER_MODES = ("centroid", "fixed")

# --- ready signals -----------------------------------------------------------------------
# Lines a process prints once it has reached a state another process waits for
# (the launcher before it starts the next processes, the tests).

#: The supervisor, at its first valid /swarm/poses.
SUPERVISOR_RECEIVING_POSES = f"receiving {POSES}"
#: The bridge, once its world is built and its first state published.
BRIDGE_READY = "bridge ready:"
#: A robot host or a robot node, once its robot nodes exist.
ROBOTS_READY = "robots ready:"
#: The dashboard, once its web server listens (the URL follows).
DASHBOARD_READY = "dashboard at"
#: The recorder, once its bag is open.
RECORDER_STARTED = "recording to"
#: The recorder, once every robot's cmd_vel and every supervisor topic has a publisher.
RECORDER_MATCHED_ALL = "found the publishers of every robot and of the supervisor"

#: Before a line a process logs for the run's event log (``events.csv``): the event,
#: then ``; `` and what the process did about it (the supervisor's arena keeper).
LOG_EVENT = "swarm event:"


#: Exit code of a recorder that stopped because it could not write (disk full):
#: restarting it would fail again.
RECORDER_CANNOT_WRITE = 3


def recorder_receiving(topic: str) -> str:
    """What the recorder prints at the first message of ``topic``."""
    return f"receiving {topic}"

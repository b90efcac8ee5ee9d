"""The names of the AES ROS 2 interface (docs/design.md#ros-interface), defined once.

Topic, service, node and frame names, the choices of the string parameters and
the ready signals that nodes print and the launcher and the tests wait for:
whatever two parts of the system must agree on. Plain constants, no rclpy, so
that pure modules (the launch plan, the pybullet world) can use them too.
"""

from __future__ import annotations

from dataclasses import dataclass

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
#: A real Mona's driver (``aes-mona-driver``) in the robot's namespace: wheel odometry
#: (nav_msgs/Odometry), IR ranges ``ir_<k>`` (sensor_msgs/Range; a name token cannot
#: start with a digit, so not ``ir/<k>``), battery
#: (sensor_msgs/BatteryState).
WHEEL_ODOM = "wheel_odom"
IR = "ir"
BATTERY = "battery"
#: ``aes-swarm launch --firmware sil``: the twist robot i's simulated MCU drives, read
#: back from its PWM outputs (``firmware_loop``); the bridge takes it for ``cmd_vel``.
WHEEL_CMD = "wheel_cmd"


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
#: The overhead camera (docs/design.md#tracking): sensor_msgs/Image (mono8, stamp =
#: exposure time) and sensor_msgs/CameraInfo (its true intrinsics and distortion).
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
MONA_DRIVER_NODE = "mona_driver"
FIRMWARE_LOOP_NODE = "firmware_loop"

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
#: The Mona driver, once its links are open and its topics exist.
MONA_DRIVER_READY = "mona driver ready:"
#: ``firmware_loop``, once it reads the MCUs' logs and its topics exist.
FIRMWARE_LOOP_READY = "firmware loop ready:"
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


# --- the interface at a glance (docs/interface.md is generated from these) ---------------


@dataclass(frozen=True)
class Endpoint:
    """One topic or service: its name, type, who provides it, who uses it, what it is."""

    name: str
    type: str
    source: str
    users: str
    description: str


#: Every topic of a running swarm. ``mona_<i>`` topics exist once per robot.
TOPICS: tuple[Endpoint, ...] = (
    Endpoint(f"/mona_<i>/{CMD_VEL}", "geometry_msgs/msg/Twist", "robot node i",
             "bridge or robot driver", "wheel command: linear.x [m/s], angular.z [rad/s]"),
    Endpoint(f"/mona_<i>/{ODOM}", "nav_msgs/msg/Odometry", "bridge",
             "robot nodes (neighbor_source odom)", "robot i's pose and twist, frame odom"),
    Endpoint(f"/mona_<i>/{AES_FORCE}", "geometry_msgs/msg/Vector3Stamped", "robot node i",
             "its neighbours' robot nodes, recorder", "robot i's elastic force F_i (E2)"),
    Endpoint(f"/mona_<i>/{WHEEL_ODOM}", "nav_msgs/msg/Odometry", "mona driver", "you",
             "a real robot's wheel odometry"),
    Endpoint(f"/mona_<i>/{IR}_<k>", "sensor_msgs/msg/Range", "mona driver", "you",
             "a real robot's IR range sensor k (0 to 4)"),
    Endpoint(f"/mona_<i>/{BATTERY}", "sensor_msgs/msg/BatteryState", "mona driver", "you",
             "a real robot's battery"),
    Endpoint(f"/mona_<i>/{WHEEL_ODOM}", "nav_msgs/msg/Odometry", "mona driver", "you",
             "real robot i's pose and twist integrated from its wheel speeds"),
    Endpoint(f"/mona_<i>/{IR}_<k>", "sensor_msgs/msg/Range", "mona driver", "you",
             "real robot i's IR sensor k = 0…4 (0°, +37°, −37°, +67°, −67°)"),
    Endpoint(f"/mona_<i>/{IR}_<k>", "sensor_msgs/msg/Range", "bridge", "robot nodes (w_o > 0)",
             "simulated robot i's IR sensor k, as the driver's (bridge parameters ir_*)"),
    Endpoint(f"/mona_<i>/{BATTERY}", "sensor_msgs/msg/BatteryState", "mona driver", "you",
             "real robot i's battery voltage"),
    Endpoint(f"/mona_<i>/{WHEEL_CMD}", "geometry_msgs/msg/Twist", "firmware_loop",
             "bridge (its cmd_vel remapped)", "with --firmware sil: the twist robot i's "
             "simulated MCU drives, from its PWM outputs; 255 = the top rim speed"),
    Endpoint(CLOCK, "rosgraph_msgs/msg/Clock", "bridge", "every node (use_sim_time)",
             "sim time"),
    Endpoint(POSES, "geometry_msgs/msg/PoseArray", "bridge or tracker",
             "robot nodes, supervisor, dashboard, recorder",
             "every robot's pose, index = robot id, frame odom"),
    Endpoint(GROUND_TRUTH_POSES, "geometry_msgs/msg/PoseArray", "bridge (with a tracker)",
             "simulated camera, recorder", "the exact poses, for evaluation only"),
    Endpoint(DESIRED_VELOCITY, "geometry_msgs/msg/TwistStamped", "supervisor",
             "robot nodes, dashboard, launcher", "v_d (linear.x/y) and ω (angular.z); latched"),
    Endpoint(ROTATION_CENTER, "geometry_msgs/msg/PointStamped", "supervisor",
             "robot nodes, dashboard", "the rotation centre x_c; latched"),
    Endpoint(ENABLED, "std_msgs/msg/Bool", "supervisor",
             "robot nodes, robot drivers, dashboard, launcher",
             "whether the swarm may move; latched"),
    Endpoint(CMD, "geometry_msgs/msg/Twist", "aes-swarm steer, dashboard, you", "supervisor",
             "the swarm command: linear.x/y = direction, angular.z = ω"),
    Endpoint(ALIGNMENT, "std_msgs/msg/Float64", "supervisor", "dashboard, recorder",
             "force alignment ψ (E8)"),
    Endpoint(HEADING_ORDER, "std_msgs/msg/Float64", "supervisor", "dashboard, recorder",
             "heading order ψ_heading (E7)"),
    Endpoint(TOTAL_FORCE, "std_msgs/msg/Float64", "supervisor", "dashboard, recorder",
             "total elastic force F (E9)"),
    Endpoint(MARKERS, "visualization_msgs/msg/MarkerArray", "dashboard", "RViz2, Foxglove",
             "the swarm drawn: robots, springs, centroid trail, walls and obstacles"),
    Endpoint(CAMERA_IMAGE, "sensor_msgs/msg/Image", "simulated camera or a real one",
             "tracker", "mono8 frames, stamp = exposure time"),
    Endpoint(CAMERA_INFO, "sensor_msgs/msg/CameraInfo", "simulated camera or a real one",
             "tracker", "the camera's intrinsics and distortion"),
    Endpoint(DIAGNOSTICS, "diagnostic_msgs/msg/DiagnosticArray", "bridge, tracker, mona driver",
             "robot nodes, dashboard", "which robots are silent or unseen, the real robots' "
             "links; latched"),
    Endpoint(RECORDER_PROGRESS, "rosgraph_msgs/msg/Clock", "recorder",
             "bridge (wait_for_recorder)", "stamp of the latest /swarm/poses written"),
)  # fmt: skip

#: Every service of a running swarm.
SERVICES: tuple[Endpoint, ...] = (
    Endpoint(ENABLE, "std_srvs/srv/SetBool", "supervisor", "aes-swarm steer, dashboard, you",
             "enable (true) or stop (false) the swarm"),
    Endpoint(SIM_RESET, "std_srvs/srv/Trigger", "bridge", "dashboard",
             "back to the initial state, every robot stopped; the clock runs on"),
    Endpoint(SIM_PAUSE, "std_srvs/srv/SetBool", "bridge", "dashboard",
             "pause (true) or resume (false) the simulation"),
    Endpoint(SIM_STATS, "std_srvs/srv/Trigger", "bridge", "launcher, benchmarks",
             "control-loop figures, contacts per second and the closest bodies since the "
             "previous call, as JSON in message"),
)  # fmt: skip

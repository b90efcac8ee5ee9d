"""The ``/swarm/*`` inputs of the robots of one process: subscribed once, decoded once.

Every robot process, a lone ``aes-robot-node`` as much as an ``aes-robot-host``
with hundreds of robots, reads the swarm's topics through one :class:`SwarmInputs`:
``/swarm/poses`` (raw, decoded with numpy: :mod:`aes_ros.ros.cdr`),
``/swarm/desired_velocity``, ``/swarm/rotation_center`` and ``/swarm/enabled``, and
in the ``odom`` source each ``/mona_<j>/odom`` its robots read (:meth:`listen_odom`).
Each message is checked and converted once and handed to every robot, and the
control law of all robots acting on a poses message is evaluated in one call
(:func:`aes_ros.robot_batch.evaluate_robots`); in the ``odom`` source the robots' inputs of
one step are gathered and evaluated together too (:meth:`SwarmInputs.odom_input`).
So both layouts take the same path.

It also knows which robots run in this process, so that a robot listens for the
liveness of its other neighbours only (:attr:`version` changes with that set).
"""

from __future__ import annotations

import time
from typing import Any, Protocol

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseArray, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Bool

from aes_ros.model import RobotCommand, SwarmCommand
from aes_ros.params import PARAMS, ParameterError
from aes_ros.robot_batch import RobotInput, evaluate_robots
from aes_ros.ros import interface as names
from aes_ros.ros.cdr import decode_odometry, decode_pose_array
from aes_ros.ros.conversions import BadMessageError, point_to_array, stamp_to_ns, twist_to_drive
from aes_ros.ros.diagnostics import lost_robots
from aes_ros.ros.node_tools import ThrottledWarnings
from aes_ros.ros.qos import LATCHED, SENSOR
from robot_node.controller import RobotController
from robot_node.rotation_center import rotation_center_rule

#: Wall seconds an odometry batch waits for its last robots (the bridge publishes a
#: step's odometry within a millisecond or two).
ODOM_WAIT = 0.004


class InputRobot(Protocol):
    """What :class:`SwarmInputs` needs of a robot it feeds (:class:`robot_node.node.RobotNode`)."""

    controller: RobotController

    @property
    def robot_id(self) -> int: ...

    @property
    def uses_poses(self) -> bool: ...

    def poses_input(
        self, stamp_ns: int, positions: np.ndarray, headings: np.ndarray, centroid: np.ndarray
    ) -> RobotInput | None: ...

    def on_odom(self, sec: int, nanosec: int, x: float, y: float, yaw: float) -> None: ...

    def publish_command(self, stamp: Time, result: RobotCommand) -> None: ...


class SwarmInputs:
    """The swarm inputs of the robots in :attr:`robots`, subscribed on ``node``."""

    def __init__(self, node: Node, command: SwarmCommand) -> None:
        self.node = node
        self.robots: list[InputRobot] = []
        #: The rotation centre rule of every robot here: they all hear the same poses
        #: and centres. Fed once per message instead of once per robot: a 1000-robot
        #: host at 20 Hz 100 / 98 % -> 88 / 89 % of a core (bench_ros, two A/B pairs).
        self.center = rotation_center_rule(command)
        #: Changes whenever a robot joins, leaves or changes its id or source.
        self.version = 0
        self._warn = ThrottledWarnings(node.get_logger())
        self._poses_sub = None
        #: The robots of :attr:`robots` in the ``poses`` source (the others read odometry).
        self._poses_robots: list[InputRobot] = []
        self._odom_robots = 0
        self._odom_pending: dict[InputRobot, tuple[Time, RobotInput]] = {}
        self._odom_since = 0.0
        self._odom_timer = None
        self._odom_subs: dict[str, Any] = {}
        #: topic -> (robot, neighbour id, or None: the robot's own odometry)
        self._odom_listeners: dict[str, list[tuple[InputRobot, int | None]]] = {}
        #: robot -> the topics it is handed (listen_odom's argument)
        self._odom_topics: dict[InputRobot, dict[str, int | None]] = {}
        node.create_subscription(
            TwistStamped, names.DESIRED_VELOCITY, self.on_desired_velocity, LATCHED
        )
        node.create_subscription(
            PointStamped, names.ROTATION_CENTER, self.on_rotation_center, LATCHED
        )
        node.create_subscription(Bool, names.ENABLED, self.on_enabled, LATCHED)
        #: The robots a tracker has lost (its ``/diagnostics``): left out of every sum.
        self.lost: frozenset[int] = frozenset()
        node.create_subscription(DiagnosticArray, names.DIAGNOSTICS, self.on_diagnostics, LATCHED)

    # --- the robots of this process -------------------------------------------------

    def add(self, robot: InputRobot) -> None:
        # Sorted in for the new robot alone: re-sorting all was quadratic in a host
        # adding its robots one by one.
        self.robots.append(robot)
        robot.controller.liveness.lost = self.lost
        if robot.uses_poses:
            self._poses_robots.append(robot)
        self._update()

    def remove(self, robot: InputRobot) -> None:
        self.listen_odom(robot, {})
        if robot in self.robots:
            self.robots.remove(robot)
            if robot in self._poses_robots:
                self._poses_robots.remove(robot)
            self._update()

    def changed(self) -> None:
        """A robot changed its id, neighbour source or neighbours: re-check liveness
        subscriptions (lazily, by :attr:`version`) and whether ``/swarm/poses`` is needed."""
        self._poses_robots = [robot for robot in self.robots if robot.uses_poses]
        self._update()

    def _update(self) -> None:
        """After :attr:`robots` or their sources changed (``_poses_robots`` up to date)."""
        self.version += 1
        self._odom_robots = len(self.robots) - len(self._poses_robots)
        wanted = bool(self._poses_robots)  # some robot reads /swarm/poses
        if wanted and self._poses_sub is None:
            self._poses_sub = self.node.create_subscription(
                PoseArray, names.POSES, self.on_poses, SENSOR, raw=True
            )
        elif not wanted and self._poses_sub is not None:
            self.node.destroy_subscription(self._poses_sub)
            self._poses_sub = None
        if self._odom_robots and self._odom_timer is None:
            # Started only while a batch waits (odom_input), so that an idle host sleeps:
            # polling every ODOM_WAIT s cost it ~1000 thread wake-ups a second (2 % of a core).
            steady = Clock(clock_type=ClockType.STEADY_TIME)
            self._odom_timer = self.node.create_timer(
                ODOM_WAIT, self._flush_late, clock=steady, autostart=False
            )
        self._odom_pending = {r: v for r, v in self._odom_pending.items() if r in self.robots}

    def local_ids(self) -> set[int]:
        """Robot ids run by this process."""
        return {robot.robot_id for robot in self.robots}

    def listen_odom(
        self, robot: InputRobot, topics: dict[str, int | None]
    ) -> dict[str, int | None]:
        """From now on hand ``robot`` the odometry of ``topics`` (topic -> the neighbour
        id it belongs to, or None for the robot's own), and no other; returns what it
        was handed before.

        Each topic is subscribed to once per process and decoded once, however many
        of its robots read it: in the ``odom`` source a robot's odometry is read by
        itself and by each of its neighbours, and one subscription per reader was
        most of a host's messages."""
        before = self._odom_topics.pop(robot, {})
        for topic in before:
            listeners = self._odom_listeners[topic]
            listeners[:] = [entry for entry in listeners if entry[0] is not robot]
        if topics:
            self._odom_topics[robot] = dict(topics)
        for topic, neighbor in topics.items():
            self._odom_listeners.setdefault(topic, []).append((robot, neighbor))
            if topic not in self._odom_subs:
                self._odom_subs[topic] = self.node.create_subscription(
                    Odometry,
                    topic,
                    lambda data, topic=topic: self.on_odom(topic, data),
                    SENSOR,
                    raw=True,
                )
        for topic in before:  # kept while anyone still reads it
            if not self._odom_listeners[topic]:
                del self._odom_listeners[topic]
                self.node.destroy_subscription(self._odom_subs.pop(topic))
        return before

    # --- inputs -----------------------------------------------------------------------

    def on_odom(self, topic: str, data: bytes) -> None:
        """One robot's odometry (raw CDR), decoded once for every robot reading it."""
        try:
            sec, nanosec, x, y, yaw = decode_odometry(data)
        except BadMessageError as exc:
            self._warn(f"dropped {topic}: {exc}")
            return
        stamp_ns = sec * 1_000_000_000 + nanosec
        own = []
        for robot, neighbor in self._odom_listeners.get(topic, ()):
            if neighbor is None:
                own.append(robot)
            else:
                robot.controller.neighbor_odom(neighbor, stamp_ns, x, y)
        for robot in own:
            robot.on_odom(sec, nanosec, x, y, yaw)

    def on_poses(self, data: bytes) -> None:
        """Decode ``/swarm/poses`` once; every robot using it acts on it."""
        robots = self._poses_robots
        if not robots:
            return
        try:
            sec, nanosec, xy, yaw = decode_pose_array(data, frame_id=names.WORLD_FRAME)
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/poses: {exc}")
            return
        centroid = xy.mean(axis=0) if len(xy) else np.zeros(2)
        stamp = Time(sec=sec, nanosec=nanosec)
        stamp_ns = stamp_to_ns(stamp)
        self.center.on_poses(stamp_ns, centroid)
        acting, inputs = [], []
        for robot in robots:
            job = robot.poses_input(stamp_ns, xy, yaw, centroid)
            if job is not None:
                acting.append(robot)
                inputs.append(job)
        for robot, result in zip(acting, evaluate_robots(inputs), strict=True):
            robot.publish_command(stamp, result)

    def odom_input(self, robot: InputRobot, stamp: Time, job: RobotInput) -> None:
        """An ``odom``-source robot's input for its own odometry at ``stamp``.

        The bridge publishes every robot's odometry of a step at once, so the inputs
        are gathered and evaluated in one call once every such robot of this process
        has one (as for ``/swarm/poses``: robot by robot, the numpy work per call
        was most of a robot's step). A batch that cannot fill (an odometry message
        lost, a robot of another rate) goes out when a robot's next input comes, or
        at the latest ODOM_WAIT s after its first input (a timer that runs only then)."""
        if robot in self._odom_pending:
            self._flush_odom()
        if not self._odom_pending:
            self._odom_since = time.monotonic()
        self._odom_pending[robot] = (stamp, job)
        if len(self._odom_pending) >= self._odom_robots:
            self._flush_odom()
        elif len(self._odom_pending) == 1:
            self._odom_timer.reset()  # due ODOM_WAIT s from now

    def _flush_late(self) -> None:
        # The time is checked: a tick queued before its batch went out can come after
        # the next batch began.
        if not self._odom_pending:
            self._odom_timer.cancel()
        elif time.monotonic() - self._odom_since >= ODOM_WAIT:
            self._flush_odom()

    def _flush_odom(self) -> None:
        pending, self._odom_pending = self._odom_pending, {}
        if self._odom_timer is not None:
            self._odom_timer.cancel()
        results = evaluate_robots([job for _, job in pending.values()])
        for (robot, (stamp, _)), result in zip(pending.items(), results, strict=True):
            robot.publish_command(stamp, result)

    def on_desired_velocity(self, msg: TwistStamped) -> None:
        """The swarm command, checked against the ranges of ``direction`` and ``omega``."""
        try:
            direction, omega = twist_to_drive(msg.twist)
            PARAMS["direction"].validate(list(direction))
            PARAMS["omega"].validate(omega)
        except (BadMessageError, ParameterError) as exc:
            self._warn(f"dropped /swarm/desired_velocity: {exc}")
            return
        for robot in self.robots:
            robot.controller.set_drive(direction, omega)

    def on_rotation_center(self, msg: PointStamped) -> None:
        try:
            point = point_to_array(msg.point)
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/rotation_center: {exc}")
            return
        self.center.on_center(stamp_to_ns(msg.header.stamp), point)

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        """The tracker's lost robots (its status on ``/diagnostics``, once a second):
        their poses are old, so every robot here leaves them out of its spring sum,
        as it does a neighbour gone silent (:mod:`robot_node.liveness`)."""
        lost = lost_robots(msg)
        if lost is None or frozenset(lost) == self.lost:
            return
        self.lost = frozenset(lost)
        for robot in self.robots:
            robot.controller.liveness.lost = self.lost
        self.node.get_logger().info(f"the tracker has lost robots {sorted(self.lost)}")

    def on_enabled(self, msg: Bool) -> None:
        for robot in self.robots:
            robot.controller.enabled = bool(msg.data)

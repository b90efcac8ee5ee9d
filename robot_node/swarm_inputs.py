"""The ``/swarm/*`` inputs of the robots of one process: subscribed once, decoded once.

Every robot process, a lone ``aes-robot-node`` as much as an ``aes-robot-host``
with hundreds of robots, reads the swarm's topics through one :class:`SwarmInputs`:
``/swarm/poses`` (raw, decoded with numpy: :mod:`aes_ros.ros.cdr`),
``/swarm/desired_velocity``, ``/swarm/rotation_center`` and ``/swarm/enabled``.
Each message is checked and converted once and handed to every robot, and the
control law of all robots acting on a poses message is evaluated in one call
(:func:`aes_ros.model.evaluate_robots`); in the ``odom`` source the robots' inputs of
one step are gathered and evaluated together too (:meth:`SwarmInputs.odom_input`).
So both layouts take the same path.

It also carries the robots' liveness: after acting on a poses message it publishes
the process's heartbeat on ``/swarm/heartbeat`` (:func:`aes_ros.ros.diagnostics.heartbeat`),
and it fills :attr:`heard`, the stamp at which every robot of the other processes
was last heard from, from theirs; every robot of this process judges its
neighbours by that one table.
"""

from __future__ import annotations

import os
import socket
import time
from typing import TYPE_CHECKING

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseArray, TwistStamped
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Bool

from aes_ros.model import RobotInput, evaluate_robots
from aes_ros.params import PARAMS, ParameterError
from aes_ros.ros import interface as names
from aes_ros.ros.cdr import decode_pose_array
from aes_ros.ros.conversions import BadMessageError, point_to_array, stamp_to_ns, twist_to_drive
from aes_ros.ros.diagnostics import heartbeat, heartbeat_robots, parse_ids
from aes_ros.ros.node_tools import ThrottledWarnings
from aes_ros.ros.qos import HEARTBEAT, LATCHED, SENSOR

if TYPE_CHECKING:
    from robot_node.node import RobotNode

#: Wall seconds an odometry batch waits for its last robots (the bridge publishes a
#: step's odometry within a millisecond or two).
ODOM_WAIT = 0.004
#: Heartbeat id lists remembered parsed (one per process, unless ids change).
_PARSED_MEMORY = 64


class SwarmInputs:
    """The swarm inputs of the robots in :attr:`robots`, subscribed on ``node``."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.robots: list[RobotNode] = []
        #: Stamp [ns] at which each robot of another process was last heard from.
        self.heard: dict[int, int] = {}
        self._warn = ThrottledWarnings(node.get_logger())
        self._poses_sub = None
        self._odom_robots = 0
        self._odom_pending: dict[RobotNode, tuple[Time, RobotInput]] = {}
        self._odom_since = 0.0
        self._odom_timer = None
        node.create_subscription(
            TwistStamped, names.DESIRED_VELOCITY, self.on_desired_velocity, LATCHED
        )
        node.create_subscription(
            PointStamped, names.ROTATION_CENTER, self.on_rotation_center, LATCHED
        )
        node.create_subscription(Bool, names.ENABLED, self.on_enabled, LATCHED)
        self._hardware_id = f"{socket.gethostname()}:{os.getpid()}"
        self._heartbeat = heartbeat(node.get_fully_qualified_name(), self._hardware_id, [])
        self._heartbeat_pub = node.create_publisher(DiagnosticArray, names.HEARTBEAT, HEARTBEAT)
        self._parsed: dict[str, list[int]] = {}
        node.create_subscription(DiagnosticArray, names.HEARTBEAT, self.on_heartbeat, HEARTBEAT)

    # --- the robots of this process -------------------------------------------------

    def add(self, robot: RobotNode) -> None:
        self.robots.append(robot)
        self.changed()

    def remove(self, robot: RobotNode) -> None:
        if robot in self.robots:
            self.robots.remove(robot)
            self.changed()

    def changed(self) -> None:
        """A robot changed its id or neighbour source: re-check whether ``/swarm/poses``
        is needed at all, and which robots the heartbeat names."""
        acting = [robot.robot_id for robot in self.robots if robot.uses_poses]
        self._heartbeat = heartbeat(self.node.get_fully_qualified_name(), self._hardware_id, acting)
        for robot_id in acting:  # run here now: never judged by another's heartbeat
            self.heard.pop(robot_id, None)
        wanted = bool(acting)
        if wanted and self._poses_sub is None:
            self._poses_sub = self.node.create_subscription(
                PoseArray, names.POSES, self.on_poses, SENSOR, raw=True
            )
        elif not wanted and self._poses_sub is not None:
            self.node.destroy_subscription(self._poses_sub)
            self._poses_sub = None
        self._odom_robots = sum(1 for robot in self.robots if not robot.uses_poses)
        if self._odom_robots and self._odom_timer is None:
            steady = Clock(clock_type=ClockType.STEADY_TIME)
            self._odom_timer = self.node.create_timer(ODOM_WAIT, self._flush_late, clock=steady)
        self._odom_pending = {r: v for r, v in self._odom_pending.items() if r in self.robots}

    # --- inputs -----------------------------------------------------------------------

    def on_poses(self, data: bytes) -> None:
        """Decode ``/swarm/poses`` once; every robot using it acts on it."""
        robots = [robot for robot in self.robots if robot.uses_poses]
        if not robots:
            return
        try:
            sec, nanosec, xy, yaw = decode_pose_array(data)
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/poses: {exc}")
            return
        centroid = xy.mean(axis=0) if len(xy) else np.zeros(2)
        stamp = Time(sec=sec, nanosec=nanosec)
        stamp_ns = stamp_to_ns(stamp)
        acting, inputs = [], []
        for robot in robots:
            job = robot.poses_input(stamp_ns, xy, yaw, centroid)
            if job is not None:
                acting.append(robot)
                inputs.append(job)
        for robot, result in zip(acting, evaluate_robots(inputs), strict=True):
            robot.publish_command(stamp, result)
        if acting:
            self._heartbeat.header.stamp = stamp
            self._heartbeat_pub.publish(self._heartbeat)

    def on_heartbeat(self, msg: DiagnosticArray) -> None:
        """Another process's robots acted at the message's stamp: they are alive."""
        stamp_ns = stamp_to_ns(msg.header.stamp)
        for hardware_id, text in heartbeat_robots(msg):
            if hardware_id == self._hardware_id:
                continue  # this process's own robots are alive while it runs
            ids = self._parsed.get(text)
            if ids is None:
                try:
                    ids = parse_ids(text)
                except ValueError as exc:
                    self._warn(f"dropped {names.HEARTBEAT}: {exc}")
                    continue
                if len(self._parsed) >= _PARSED_MEMORY:
                    self._parsed.clear()
                self._parsed[text] = ids
            self.heard.update(dict.fromkeys(ids, stamp_ns))

    def odom_input(self, robot: RobotNode, stamp: Time, job: RobotInput) -> None:
        """An ``odom``-source robot's input for its own odometry at ``stamp``.

        The bridge publishes every robot's odometry of a step at once, so the inputs
        are gathered and evaluated in one call once every such robot of this process
        has one (as for ``/swarm/poses``: robot by robot, the numpy work per call
        was most of a robot's step). A batch that cannot fill (an odometry message
        lost, a robot of another rate) goes out when a robot's next input comes, or
        at the latest ODOM_WAIT s after its first input."""
        if robot in self._odom_pending:
            self._flush_odom()
        if not self._odom_pending:
            self._odom_since = time.monotonic()
        self._odom_pending[robot] = (stamp, job)
        if len(self._odom_pending) >= self._odom_robots:
            self._flush_odom()

    def _flush_late(self) -> None:
        if self._odom_pending and time.monotonic() - self._odom_since >= ODOM_WAIT:
            self._flush_odom()

    def _flush_odom(self) -> None:
        pending, self._odom_pending = self._odom_pending, {}
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
        stamp_ns = stamp_to_ns(msg.header.stamp)
        for robot in self.robots:
            robot.controller.center.on_center(stamp_ns, point)

    def on_enabled(self, msg: Bool) -> None:
        for robot in self.robots:
            robot.controller.enabled = bool(msg.data)

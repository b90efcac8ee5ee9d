"""AES robot node: the controller of one Mona robot (docs/design.md#motion, #ros-interface).

For every new pose of its robot the node evaluates the control law
(:func:`aes_ros.robot_batch.evaluate_robots`, i.e. :func:`aes_ros.model.robot_command`,
E1–E6) and publishes exactly one ``cmd_vel`` (geometry_msgs/Twist) and, when
anything subscribes to it, one ``aes_force`` (the noise-free force f_i,
geometry_msgs/Vector3Stamped in ``odom``; unheard, it would cost a third of the
robot's CPU). With ``w_o > 0`` it also reads its robot's five IR ranges for the
avoidance term (docs/model.md, "Obstacle avoidance"). The node only converts: parameters into
:class:`robot_node.controller.RobotSettings`, messages into the calls of
:class:`robot_node.controller.RobotController`, results into messages. The
``/swarm/*`` inputs come through the process's :class:`robot_node.swarm_inputs.SwarmInputs`.

Start one robot by hand, with its sheet given explicitly::

    aes-robot-node --ros-args -r __ns:=/mona_3 -p robot_id:=3 \\
        -p neighbors:=[2,4,7] -p rest_lengths:=[0.2,0.2,0.2]

or with neighbours and rest lengths taken from a scenario's formation::

    aes-robot-node --ros-args -r __ns:=/mona_3 -p robot_id:=3 \\
        -p scenario:=linear -p num_robots:=16 -p use_sim_time:=true

Change a gain at runtime (full ROS 2 install): ``ros2 param set /mona_3/aes_robot alpha 0.1``.
Many robots in one process: ``aes-robot-host`` (:mod:`robot_node.host`).
"""

from __future__ import annotations

import math
import re
import sys
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Twist, Vector3Stamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Range

from aes_ros.avoidance import N_IR
from aes_ros.model import GAIN_FIELDS, Gains, RobotCommand
from aes_ros.robot_batch import RobotInput
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.cdr import Vector3StampedEncoder, encode_twist
from aes_ros.ros.conversions import stamp_to_ns
from aes_ros.ros.node_tools import PublishCounter, ThrottledWarnings
from aes_ros.ros.qos import COMMAND, COMMAND_KEPT, SENSOR
from aes_ros.ros.spin import run_node_process
from aes_ros.scenario import Scenario
from robot_node.controller import (
    MAX_ROBOT_ID,
    REST_LENGTH_RANGE,
    RobotController,
    RobotSettings,
    sheet_error,
)
from robot_node.swarm_inputs import SwarmInputs

_MODEL_NAMES = (*GAIN_FIELDS, *rp.LIMIT_NAMES)
#: The parameters the controller reads (scenario and num_robots are read-only).
_APPLIED_NAMES = (
    *_MODEL_NAMES,
    "robot_id",
    "neighbors",
    "rest_lengths",
    "clip",
    "neighbor_timeout",
    "seed",
    "neighbor_source",
)


class RobotNode(Node):
    """Controller of one robot, node ``aes_robot`` in namespace ``/mona_<i>``.

    Parameters (all settable at runtime unless marked read-only; out-of-range or
    inconsistent values are rejected with a reason and the old value stays):

    - ``robot_id`` (int, default: ``<i>`` of the namespace ``/mona_<i>``, else 0):
      index of this robot in ``/swarm/poses``.
    - ``neighbors`` (int[], default: from the scenario's sheet): ids j of S_i.
    - ``rest_lengths`` (double[] [m], default: from the scenario's sheet if the
      neighbours are too, else empty): l_ij, one per neighbour; empty = latch the
      distances at the first poses received.
    - ``alpha``, ``beta``, ``k``, ``v0``, ``w_l``, ``w_r``, ``d_r``, ``d_theta``, ``w_o``,
      ``max_linear_speed`` [m/s], ``max_angular_speed`` [rad/s] (double, default:
      the scenario's values; ranges from :data:`aes_ros.params.PARAMS`). With ``w_o > 0``
      the robot subscribes to its IR ranges (and only then).
    - ``clip`` (bool, default true): clip commands to the robot's limits.
    - ``neighbor_timeout`` (double [s], default 1.0): a neighbour not heard from
      for longer than this (by stamp, relative to the own pose) is left out of the
      sum. Heard from = its ``aes_force`` (both sources; a robot whose controller
      died still has a pose from the tracking system or the simulator) and, in the
      ``odom`` source, its odometry. A neighbour never heard from counts as alive
      (it may still be starting); one that speaks again is taken back at once.
    - ``seed`` (int, default 0): noise seed, combined with ``robot_id``; -1 = random.
    - ``neighbor_source`` (string, ``poses`` | ``odom``, default ``poses``).
    - ``scenario`` (string, default ``combined``) and ``num_robots`` (int, default
      0), read-only: the scenario giving the defaults above.

    Topics: ``/swarm/poses`` (``poses`` source), ``/swarm/desired_velocity``,
    ``/swarm/rotation_center``, ``/swarm/enabled`` through ``inputs`` (the
    process's :class:`SwarmInputs`; a robot alone makes its own); ``odom`` and
    ``/mona_<j>/odom`` of every neighbour j (``odom`` source; each topic subscribed once
    per process, through ``inputs``); ``/mona_<j>/aes_force``
    of every neighbour j run by another process (liveness); ``/mona_<i>/ir_<k>``, k = 0…4
    (sensor_msgs/Range, sensor-data QoS; only while ``w_o > 0``: a reading older than
    0.5 s counts as nothing seen, one that is no distance in [0, 1] m is dropped with a
    warning). Publishes ``cmd_vel`` and ``aes_force``.
    """

    def __init__(
        self,
        *,
        scenario: Scenario | None = None,
        inputs: SwarmInputs | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(names.ROBOT_NODE, **kwargs)
        self._warn = ThrottledWarnings(self.get_logger())
        scen = rp.declare_scenario(self, scenario)
        self._declare_parameters(scen)
        self._fill_sheet(scen)
        rp.guard_parameters(self, self._check, self._apply_parameters)

        # Both are published in their wire format (aes_ros.ros.cdr): converting Twist
        # objects was over half of a robot's publishing cost.
        self._cmd_pub = self.create_publisher(Twist, names.CMD_VEL, COMMAND_KEPT)
        self._force_pub = self.create_publisher(Vector3Stamped, names.AES_FORCE, COMMAND)
        self._force_encoder = Vector3StampedEncoder(names.WORLD_FRAME)
        self.counter = PublishCounter()
        self._counts_logged = False

        alone = inputs is None
        self._inputs = SwarmInputs(self, scen.command) if alone else inputs
        self.controller = RobotController(
            self._settings(), scen.command, self._warn, self.get_logger().info,
            center=self._inputs.center,
        )  # fmt: skip
        self._alive_subs: dict[int, Any] = {}
        self._ir_subs: list[Any] = []
        self._ir_robot: int | None = None
        self._local_version = -1
        self._sync_subscriptions()
        self._sync_ir()
        self._inputs.add(self)
        if alone:
            self.get_logger().info(f"{names.ROBOTS_READY} robot {self.robot_id}")

    @property
    def robot_id(self) -> int:
        return self.controller.settings.robot_id

    @property
    def uses_poses(self) -> bool:
        """True when the neighbour source is ``/swarm/poses``."""
        return self.controller.settings.neighbor_source == "poses"

    # --- parameters -------------------------------------------------------------------

    def _declare_parameters(self, scen: Scenario) -> None:
        rp.declare_model_parameters(self, _MODEL_NAMES, scen.values)
        match = re.fullmatch(names.ROBOT_NAMESPACE_PATTERN, self.get_namespace())
        self.declare_parameter(
            "robot_id",
            int(match.group(1)) if match else 0,
            rp.int_descriptor("index of this robot in /swarm/poses", 0, MAX_ROBOT_ID),
        )
        self.declare_parameter(
            "neighbors",
            Parameter.Type.INTEGER_ARRAY,
            rp.array_descriptor(
                "neighbour ids j of the sheet S_i (default: from the scenario)",
                "",
                f"distinct ids in [0, {MAX_ROBOT_ID}], not robot_id",
            ),
        )
        self.declare_parameter(
            "rest_lengths",
            Parameter.Type.DOUBLE_ARRAY,
            rp.array_descriptor(
                "spring rest lengths l_ij, one per neighbour; empty = latch the distances "
                "at the first poses received",
                "m",
                "empty, or one number in [{:g}, {:g}] per neighbour".format(*REST_LENGTH_RANGE),
            ),
        )
        self.declare_parameter(
            "clip", True, rp.bool_descriptor("clip commands to max_linear/angular_speed")
        )
        self.declare_parameter(
            "neighbor_timeout",
            1.0,
            rp.float_descriptor(
                "leave out a neighbour not heard from (aes_force, odom) for longer than this",
                "s",
                0.0,
                1e6,
            ),
        )
        self.declare_parameter(
            "seed",
            0,
            rp.int_descriptor("noise seed (combined with robot_id); -1 = random", -1, 2**31 - 1),
        )
        self.declare_parameter(
            "neighbor_source",
            "poses",
            rp.text_descriptor(
                "where neighbour positions come from: /swarm/poses or the neighbours' odom",
                names.NEIGHBOR_SOURCES,
            ),
        )

    def _fill_sheet(self, scen: Scenario) -> None:
        """Take unset ``neighbors``/``rest_lengths`` from the scenario's sheet."""
        neighbors = self.get_parameter_or("neighbors").value
        rest = self.get_parameter_or("rest_lengths").value
        robot_id = self.get_parameter("robot_id").value
        updates = []
        if neighbors is None:
            _, table, rest_table = scen.sheet()
            neighbors, sheet_rest = [], []
            if robot_id < len(table):
                keep = table[robot_id] >= 0
                neighbors = table[robot_id][keep].tolist()
                sheet_rest = rest_table[robot_id][keep].tolist()
            else:
                self.get_logger().warning(
                    f"robot_id {robot_id} is not in the scenario's {len(table)} robots: "
                    "no neighbours"
                )
            updates.append(Parameter("neighbors", Parameter.Type.INTEGER_ARRAY, neighbors))
            if rest is None:
                rest = sheet_rest
                updates.append(Parameter("rest_lengths", Parameter.Type.DOUBLE_ARRAY, rest))
        if rest is None:
            updates.append(Parameter("rest_lengths", Parameter.Type.DOUBLE_ARRAY, []))
        if updates:
            self.set_parameters(updates)

    def _check(self, updates: dict[str, Any]) -> str | None:
        """Reason why the parameters with ``updates`` applied are invalid, or None."""

        def value(name: str) -> Any:
            if name in updates:
                return updates[name]
            return self.get_parameter_or(name).value

        reason = rp.check(
            [Parameter(n, value=value(n)) for n in _MODEL_NAMES if value(n) is not None]
        )
        if reason is not None:
            return reason
        reason = sheet_error(
            value("robot_id"), list(value("neighbors") or []), list(value("rest_lengths") or [])
        )
        if reason is not None:
            return reason
        return rp.choice_error("neighbor_source", value("neighbor_source"), names.NEIGHBOR_SOURCES)

    def _settings(self) -> RobotSettings:
        p = {param.name: param.value for param in self.get_parameters(_APPLIED_NAMES)}
        return RobotSettings(
            robot_id=p["robot_id"],
            neighbors=tuple(p["neighbors"]),
            rest_lengths=tuple(p["rest_lengths"]),
            gains=Gains(**{name: p[name] for name in GAIN_FIELDS}),
            limits=(p["max_linear_speed"], p["max_angular_speed"]) if p["clip"] else None,
            neighbor_timeout=p["neighbor_timeout"],
            seed=p["seed"],
            neighbor_source=p["neighbor_source"],
        )

    def _apply_parameters(self) -> None:
        """Hand the parameters to the controller and fix the subscriptions; tell the
        process's inputs when what they track changed (id, source, neighbours: a
        recount over all its robots)."""
        old = self.controller.settings
        self.controller.configure(self._settings())
        self._sync_subscriptions()
        self._sync_ir()
        new = self.controller.settings
        if (old.robot_id, old.neighbor_source, old.neighbors) != (
            new.robot_id,
            new.neighbor_source,
            new.neighbors,
        ):
            self._inputs.changed()

    def _sync_subscriptions(self) -> None:
        """Receive the odometry the neighbour source needs (own and neighbours'), and
        nothing else. The process subscribes to each topic once
        (:meth:`SwarmInputs.listen_odom`): a robot's odometry is read by itself and by
        its neighbours, mostly robots of the same process."""
        topics: dict[str, int | None] = {}
        if not self.uses_poses:
            for j in self.controller.neighbors.tolist():
                topics[names.robot_topic(j, names.ODOM)] = j
            topics[self.resolve_topic_name(names.ODOM)] = None  # own
        before = self._inputs.listen_odom(self, topics)
        for j in set(before.values()) - set(topics.values()) - {None}:
            self.controller.forget_neighbor(j)

    def _sync_ir(self) -> None:
        """Read this robot's five IR ranges while ``w_o > 0``, and not otherwise: a host of
        100 robots without avoidance keeps no 500 subscriptions."""
        robot = self.robot_id if self.controller.settings.gains.w_o > 0.0 else None
        if robot == self._ir_robot:
            return
        for sub in self._ir_subs:
            self.destroy_subscription(sub)
        self._ir_subs, self._ir_robot = [], robot
        self.controller.ir.clear()
        if robot is None:
            return
        for k in range(N_IR):
            self._ir_subs.append(
                self.create_subscription(
                    Range,
                    names.robot_topic(robot, f"{names.IR}_{k}"),
                    lambda msg, k=k: self.on_ir(k, msg),
                    SENSOR,
                )
            )

    def _sync_liveness(self) -> None:
        """``poses`` source: listen to the ``aes_force`` of every neighbour not run by
        this process (one run here is alive as long as this robot is). The ``odom``
        source needs none: a neighbour's own odometry stamps say whether it is there
        (:meth:`RobotController.odom_input`), and each extra reader would make every
        robot publish ``aes_force`` too."""
        self._local_version = self._inputs.version
        wanted = set(self.controller.neighbors.tolist()) - self._inputs.local_ids()
        if not self.uses_poses:
            wanted = set()
        for j in set(self._alive_subs) - wanted:
            self.destroy_subscription(self._alive_subs.pop(j))
            self.controller.liveness.forget(j)
        for j in sorted(wanted - set(self._alive_subs)):
            self._alive_subs[j] = self.create_subscription(
                Vector3Stamped,
                names.robot_topic(j, names.AES_FORCE),
                lambda msg, j=j: self.controller.heard_force(j, stamp_to_ns(msg.header.stamp)),
                COMMAND,
            )

    # --- inputs -----------------------------------------------------------------------

    def poses_input(
        self, stamp_ns: int, positions: np.ndarray, headings: np.ndarray, centroid: np.ndarray
    ) -> RobotInput | None:
        """The control law's inputs for one decoded ``/swarm/poses`` (None: no command)."""
        if self._local_version != self._inputs.version:
            self._sync_liveness()
        return self.controller.poses_input(stamp_ns, positions, headings, centroid)

    def on_odom(self, sec: int, nanosec: int, x: float, y: float, yaw: float) -> None:
        """Own odometry (``odom`` source, decoded by :class:`SwarmInputs`): act with the
        neighbours heard from recently."""
        if self._local_version != self._inputs.version:
            self._sync_liveness()
        job = self.controller.odom_input(sec * 1_000_000_000 + nanosec, x, y, yaw)
        self._inputs.odom_input(self, Time(sec=sec, nanosec=nanosec), job)

    def on_ir(self, sensor: int, msg: Range) -> None:
        """One IR range of this robot: kept for the next command, or dropped with a reason."""
        reason = self.controller.ir.heard(sensor, stamp_to_ns(msg.header.stamp), msg.range)
        if reason is not None:
            self._warn(reason)

    # --- output -----------------------------------------------------------------------

    def publish_command(self, stamp: Time, result: RobotCommand) -> None:
        """Publish ``cmd_vel`` (zero while the swarm is disabled) and, if anyone
        listens, ``aes_force`` for one evaluated input stamped ``stamp``."""
        force = result.force
        if not (
            math.isfinite(result.linear)
            and math.isfinite(result.angular)
            and math.isfinite(force[0])
            and math.isfinite(force[1])
        ):  # cannot happen with inputs that passed the conversions; never publish it
            self._warn(f"no command at t={stamp_to_ns(stamp) * 1e-9:.2f} s: not finite")
            return
        if self.controller.enabled:
            cmd = encode_twist(result.linear, result.angular)
        else:
            cmd = encode_twist(0.0, 0.0)
        self.counter.publish(self._cmd_pub, cmd)
        if self._force_pub.get_subscription_count():  # for inspection: skip when unheard
            data = self._force_encoder.encode(stamp.sec, stamp.nanosec, force[0], force[1])
            self._force_pub.publish(data)

    def log_counts(self) -> None:
        """Log what this robot published (once; :class:`PublishCounter`)."""
        if not self._counts_logged:
            self._counts_logged = True
            self.counter.log(self.get_namespace())

    def destroy_node(self) -> None:
        self.log_counts()
        self._inputs.remove(self)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """``aes-robot-node``: one robot in this process."""
    return run_node_process(names.ROBOT_NODE, args, RobotNode)


if __name__ == "__main__":
    sys.exit(main())

"""AES supervisor node: what every robot is told, and how the swarm is doing.

See docs/design.md#ros-interface.

Publishes the swarm command ``/swarm/desired_velocity`` (v_d, ω), the rotation
centre ``/swarm/rotation_center`` (the live centroid of ``/swarm/poses`` or a
fixed point) and ``/swarm/enabled``, and the metrics ψ (E8), ψ_heading (E7)
and F (E9) on ``/swarm/alignment``, ``/swarm/heading_order`` and
``/swarm/total_force``, computed from ``/swarm/poses`` with the same core
functions as the offline simulator.

Start it::

    aes-supervisor --ros-args -p scenario:=combined -p num_robots:=16 \\
        -p publish_rate:=10.0 -p use_sim_time:=true

Steer at runtime (full ROS 2 install)::

    ros2 topic pub --once /swarm/cmd geometry_msgs/msg/Twist "{linear: {x: 0.0, y: 1.0}}"
    ros2 param set /supervisor rotation_rate 0.5
    ros2 service call /swarm/enable std_srvs/srv/SetBool "{data: false}"

Keep the swarm in a 3 m × 2 m arena (turn it back towards the centre near a wall)::

    aes-supervisor --ros-args -p scenario:=linear -p "arena:=[-1.5, 1.5, -1.0, 1.0]"
    ros2 param set /supervisor arena_policy stop
"""

from __future__ import annotations

import array
import sys
from dataclasses import replace
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, PoseArray, Twist, TwistStamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Bool, Float64
from std_srvs.srv import SetBool

from aes_ros.arena import KeeperState, arena_or_none, keep_in_arena
from aes_ros.metrics import alignment_order, heading_order, total_force
from aes_ros.model import GAIN_FIELDS, Gains, SwarmCommand, total_forces
from aes_ros.params import PARAMS, ParameterError
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.cdr import decode_pose_array
from aes_ros.ros.conversions import BadMessageError, drive_to_twist, twist_to_drive
from aes_ros.ros.node_tools import PublishCounter, ThrottledWarnings
from aes_ros.ros.qos import COMMAND, SENSOR
from aes_ros.ros.qos import LATCHED_WRITER as LATCHED
from aes_ros.ros.spin import run_node_process

#: Supervisor parameters checked against their PARAMS entry (some of another name).
_SPEC_OF = {
    "desired_direction": PARAMS["direction"],
    "rotation_rate": PARAMS["omega"],
    "rotation_center": PARAMS["rotation_center"],
    "arena": PARAMS["arena"],
    "arena_policy": PARAMS["arena_policy"],
    "arena_margin": PARAMS["arena_margin"],
}
_ARENA_NAMES = ("arena", "arena_policy", "arena_margin")
_COMMAND_NAMES = (
    "desired_direction",
    "rotation_rate",
    "rotation_center_mode",
    "rotation_center",
    "publish_rate",
    "enabled",
    *_ARENA_NAMES,
)


class SupervisorNode(Node):
    """The swarm's supervisor, node ``supervisor``.

    Parameters (runtime-settable unless read-only; invalid values are rejected
    with a reason and the old value stays):

    - ``desired_direction`` (double[2], default: the scenario's direction): v_d,
      world frame; its length scales the drive, [0, 0] switches it off.
    - ``rotation_rate`` (double [rad/s], default: the scenario's ω):
      counter-clockwise positive.
    - ``rotation_center_mode`` (string, ``centroid`` | ``fixed``, default: the
      scenario's): x_c is the live centroid of ``/swarm/poses`` or ``rotation_center``.
    - ``rotation_center`` (double[2] [m], default: the scenario's fixed centre or
      [0, 0]): the fixed x_c.
    - ``publish_rate`` (double [Hz], default 20.0): rate of the metrics.
    - ``enabled`` (bool, default true): false makes every robot publish zero
      ``cmd_vel``; also set by the ``/swarm/enable`` service.
    - ``arena`` (double[4] [m] x_min, x_max, y_min, y_max, or empty, default: the
      scenario's, empty): the rectangle in ``odom`` the arena keeper
      (:mod:`aes_ros.arena`) keeps the swarm in; empty switches the keeper off.
    - ``arena_policy`` (string, ``turn`` | ``stop``, default: the scenario's, ``turn``):
      when the command points out through a wall a robot is near, turn
      ``desired_direction`` towards the arena's centre, or set ``enabled`` false.
    - ``arena_margin`` (double [m], default: the scenario's, 0.17): distance from a
      wall at which the keeper acts.
    - ``alpha`` … ``d_theta`` (double, default: the scenario's): the gains used
      for the metrics' force (only k, w_l, w_r matter).
    - ``scenario`` (string, default ``combined``), ``num_robots`` (int, default 0),
      read-only: the sheet and defaults.

    ``/swarm/cmd`` (Twist: linear.{x,y} → v_d, angular.z → ω) sets
    ``desired_direction`` and ``rotation_rate`` like a parameter set, so
    ``ros2 param get`` agrees. In centroid mode ``/swarm/rotation_center`` is
    published for every ``/swarm/poses`` message, stamped with its stamp.

    With an ``arena`` the keeper looks at every ``/swarm/poses``; what it does goes
    through the parameters like any other set (so the command is published as
    usual, and ``ros2 param get`` agrees) and is logged as a
    :data:`~aes_ros.ros.interface.LOG_EVENT` line, which the launcher writes to the
    run's ``events.csv``.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.SUPERVISOR_NODE, **kwargs)
        self._warn = ThrottledWarnings(self.get_logger())
        scen = rp.declare_scenario(self)
        _, self._neighbors, self._rest = scen.sheet()
        rp.declare_model_parameters(self, GAIN_FIELDS, scen.values)
        command = scen.command
        self.declare_parameter(
            "desired_direction",
            [float(v) for v in command.direction],
            rp.descriptor(PARAMS["direction"]),
        )
        self.declare_parameter(
            "rotation_rate", float(command.omega), rp.descriptor(PARAMS["omega"])
        )
        self.declare_parameter(
            "rotation_center_mode",
            "centroid" if command.center is None else "fixed",
            rp.text_descriptor(
                "rotation centre x_c: the live centroid of /swarm/poses or rotation_center",
                names.CENTER_MODES,
            ),
        )
        self.declare_parameter(
            "rotation_center",
            [0.0, 0.0] if command.center is None else [float(v) for v in command.center],
            rp.array_descriptor(
                "fixed rotation centre x_c (rotation_center_mode: fixed)",
                "m",
                "two numbers, each in [-1e4, 1e4]",
            ),
        )
        self.declare_parameter(
            "publish_rate",
            20.0,
            rp.float_descriptor("rate of the metrics topics", "Hz", 0.01, 1000.0),
        )
        self.declare_parameter(
            "enabled", True, rp.bool_descriptor("false: every robot publishes zero cmd_vel")
        )
        self._declare_arena(scen.values)
        rp.guard_parameters(self, self._check, self._apply_parameters)

        #: Messages published so far, per topic.
        self.counter = PublishCounter()
        self._velocity_pub = self.create_publisher(TwistStamped, names.DESIRED_VELOCITY, LATCHED)
        self._center_pub = self.create_publisher(PointStamped, names.ROTATION_CENTER, LATCHED)
        self._enabled_pub = self.create_publisher(Bool, names.ENABLED, LATCHED)
        self._alignment_pub = self.create_publisher(Float64, names.ALIGNMENT, LATCHED)
        self._heading_pub = self.create_publisher(Float64, names.HEADING_ORDER, LATCHED)
        self._force_pub = self.create_publisher(Float64, names.TOTAL_FORCE, LATCHED)
        self.create_subscription(Twist, names.CMD, self.on_cmd, COMMAND)
        # Raw: the poses are read from the wire format with numpy (aes_ros.ros.cdr).
        self.create_subscription(PoseArray, names.POSES, self.on_poses, SENSOR, raw=True)
        self.create_service(SetBool, names.ENABLE, self.on_enable)

        self._poses: tuple[Any, np.ndarray, np.ndarray] | None = None
        self._poses_new = False
        self._timer = None
        self._state: dict[str, Any] = {}
        self._keeper = KeeperState()
        self._apply_parameters()

    def _declare_arena(self, scenario: dict[str, Any]) -> None:
        """``arena`` (dynamically typed: an empty array of any type or four numbers, as
        ``ros2 param set`` gives them), ``arena_policy``, ``arena_margin``."""
        descriptor = rp.descriptor(PARAMS["arena"])
        descriptor.dynamic_typing = True
        arena = self.declare_parameter("arena", [float(v) for v in scenario["arena"]], descriptor)
        if len(arena.value) == 0 and arena.type_ != Parameter.Type.DOUBLE_ARRAY:
            # an empty list declares a byte array; show an empty double array instead
            self.set_parameters([Parameter("arena", Parameter.Type.DOUBLE_ARRAY, [])])
        for name in ("arena_policy", "arena_margin"):
            spec = PARAMS[name]
            self.declare_parameter(name, rp.to_ros_value(spec, scenario[name]), rp.descriptor(spec))

    # --- parameters -------------------------------------------------------------------

    def _check(self, updates: dict[str, Any]) -> str | None:
        """Reason why the parameters with ``updates`` applied are invalid, or None."""

        def value(name: str) -> Any:
            return updates[name] if name in updates else self.get_parameter(name).value

        reason = rp.check([Parameter(n, value=value(n)) for n in GAIN_FIELDS])
        if reason is not None:
            return reason
        if not isinstance(value("arena"), list | tuple | array.array):
            return f"arena: {value('arena')!r} is not allowed; expected {PARAMS['arena'].allowed()}"
        for name, spec in _SPEC_OF.items():
            raw = value(name)
            try:
                spec.validate(list(raw) if isinstance(raw, list | tuple) else raw)
            except ParameterError as exc:
                return f"{name}: {str(exc).partition(': ')[2]}"
        return rp.choice_error(
            "rotation_center_mode", value("rotation_center_mode"), names.CENTER_MODES
        )

    def _apply_parameters(self) -> None:
        """Read the parameters; publish whatever part of the command changed."""
        p = {param.name: param.value for param in self.get_parameters(_COMMAND_NAMES)}
        self._gains = Gains(
            **{param.name: param.value for param in self.get_parameters(GAIN_FIELDS)}
        )
        old, self._state = self._state, p
        self._direction = (float(p["desired_direction"][0]), float(p["desired_direction"][1]))
        self._omega = float(p["rotation_rate"])
        self._fixed_center = (float(p["rotation_center"][0]), float(p["rotation_center"][1]))
        self._centroid_mode = p["rotation_center_mode"] == "centroid"
        if _changed(old, p, "desired_direction", "rotation_rate"):
            self._publish_velocity()
        if _changed(old, p, "rotation_center_mode", "rotation_center"):
            self._publish_center()
        if _changed(old, p, "enabled"):
            self.counter.publish(self._enabled_pub, Bool(data=bool(p["enabled"])))
        if _changed(old, p, "publish_rate"):
            if self._timer is not None:
                self.destroy_timer(self._timer)
            self._timer = self.create_timer(1.0 / p["publish_rate"], self.on_timer)
        if _changed(old, p, *_ARENA_NAMES):
            self._arena = arena_or_none(list(p["arena"]))
            self._keeper = KeeperState()

    def _publish_velocity(self) -> None:
        msg = TwistStamped()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = names.WORLD_FRAME
        msg.twist = drive_to_twist(self._direction, self._omega)
        self.counter.publish(self._velocity_pub, msg)

    def _publish_center(self) -> None:
        """Publish x_c: the fixed point now, or the centroid of the latest poses."""
        msg = PointStamped()
        msg.header.frame_id = names.WORLD_FRAME
        if self._centroid_mode:
            if self._poses is None:
                return
            stamp, xy, _ = self._poses
            msg.header.stamp = stamp
            msg.point.x, msg.point.y = (float(v) for v in xy.mean(axis=0))
        else:
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.point.x, msg.point.y = self._fixed_center
        self.counter.publish(self._center_pub, msg)

    # --- inputs -----------------------------------------------------------------------

    def on_cmd(self, msg: Twist) -> None:
        """``/swarm/cmd``: set desired_direction and rotation_rate (as parameters)."""
        try:
            direction, omega = twist_to_drive(msg)
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/cmd: {exc}")
            return
        result = self.set_parameters_atomically(
            [
                Parameter("desired_direction", Parameter.Type.DOUBLE_ARRAY, list(direction)),
                Parameter("rotation_rate", Parameter.Type.DOUBLE, omega),
            ]
        )
        if not result.successful:
            self._warn(f"ignored /swarm/cmd: {result.reason}")

    def on_enable(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        """``/swarm/enable``: false makes every robot stop, true lets them move again."""
        result = self.set_parameters([Parameter("enabled", Parameter.Type.BOOL, request.data)])[0]
        response.success = result.successful
        response.message = (
            ("enabled" if request.data else "disabled") if result.successful else (result.reason)
        )
        return response

    def on_poses(self, data: bytes) -> None:
        """Keep the latest poses; in centroid mode publish their centroid right away.

        A message that is not finite, has a coordinate beyond ±MAX_COORDINATE, is not in
        the world frame or has not one pose per robot is dropped with a throttled warning
        (the last good one stays).
        """
        try:
            # One pose per robot of the scenario, or none of them: a partial array
            # would give a wrong centroid.
            sec, nanosec, xy, yaw = decode_pose_array(
                data, expected=len(self._neighbors), frame_id=names.WORLD_FRAME
            )
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/poses: {exc}")
            return
        if self._poses is None:  # the launcher waits for this line (lockstep, recording)
            self.get_logger().info(names.SUPERVISOR_RECEIVING_POSES)
        self._poses = (Time(sec=sec, nanosec=nanosec), xy, yaw)
        self._poses_new = True
        if self._centroid_mode:
            self._publish_center()
        if self._arena is not None:
            self._keep_in_arena(xy)

    def _keep_in_arena(self, xy: np.ndarray) -> None:
        """The arena keeper (:func:`aes_ros.arena.keep_in_arena`): turn or stop the swarm
        before a robot leaves the arena, through the parameters; log what it did."""
        old = self._direction
        decision = keep_in_arena(
            xy,
            old,
            self._arena,
            self._keeper,
            policy=self._state["arena_policy"],
            margin=self._state["arena_margin"],
        )
        self._keeper = decision.state
        if decision.action == "turn":
            # |v_d| kept, but each component within its range
            new = np.asarray(decision.direction)
            new /= max(1.0, float(np.abs(new).max()) / PARAMS["direction"].high)
            decision = replace(decision, direction=(float(new[0]), float(new[1])))
            change = Parameter(
                "desired_direction", Parameter.Type.DOUBLE_ARRAY, list(decision.direction)
            )
        elif decision.action == "stop" and self._state["enabled"]:
            change = Parameter("enabled", Parameter.Type.BOOL, False)
        else:
            return
        result = self.set_parameters([change])[0]
        if not result.successful:
            self._warn(f"arena keeper: cannot set {change.name}: {result.reason}")
            return
        self.get_logger().warning(f"{names.LOG_EVENT} {decision.describe(old)}")

    def on_timer(self) -> None:
        """Publish ψ (E8), ψ_heading (E7) and F (E9) of the latest poses."""
        if not self._poses_new or self._poses is None:
            return
        self._poses_new = False
        _, xy, yaw = self._poses
        command = SwarmCommand(
            self._direction, self._omega, None if self._centroid_mode else self._fixed_center
        )
        forces = total_forces(xy, self._neighbors, self._rest, self._gains, command)
        self.counter.publish(self._alignment_pub, Float64(data=float(alignment_order(forces, yaw))))
        self.counter.publish(self._heading_pub, Float64(data=float(heading_order(yaw))))
        self.counter.publish(self._force_pub, Float64(data=float(total_force(forces))))

    def destroy_node(self) -> None:
        self.counter.log(self.get_fully_qualified_name())
        super().destroy_node()


def _changed(old: dict[str, Any], new: dict[str, Any], *names: str) -> bool:
    return any(name not in old or old[name] != new[name] for name in names)


def main(args: list[str] | None = None) -> int:
    """``aes-supervisor``."""
    return run_node_process(names.SUPERVISOR_NODE, args, SupervisorNode)


if __name__ == "__main__":
    sys.exit(main())

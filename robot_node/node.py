"""AES robot node: the controller of one Mona robot (SPEC §1.4, §7).

For every new pose of its robot the node computes the control law
:func:`aes_ros.model.robot_command` (E1–E6) and publishes exactly one
``cmd_vel`` (geometry_msgs/Twist) and, when anything subscribes to it, one
``aes_force`` (the noise-free force f_i, geometry_msgs/Vector3Stamped in ``odom``;
unheard, it would cost a third of the robot's CPU).

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
import time
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, PoseArray, Twist, TwistStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Bool

from aes_ros.model import Gains, RobotCommand, SwarmCommand, robot_command
from aes_ros.params import PARAMS, ParameterError
from aes_ros.ros import parameters as rp
from aes_ros.ros.conversions import (
    BadMessageError,
    odom_to_pose,
    point_to_array,
    poses_to_arrays,
    stamp_to_ns,
    twist_to_drive,
    unicycle_twist,
    vector3_stamped,
)
from aes_ros.ros.qos import COMMAND, COMMAND_KEPT, LATCHED, SENSOR
from aes_ros.ros.spin import run_node_process
from aes_ros.scenario import Scenario

NODE_NAME = "aes_robot"
#: Logs the message counts at shutdown (a logger of no node: no /rosout publisher).
COUNT_LOGGER = rclpy.logging.get_logger("published")
#: Δt [s] for the noise until the second own pose gives the real period (20 Hz).
DEFAULT_DT = 0.05
NEIGHBOR_SOURCES = ("poses", "odom")
#: A published rotation centre this close [m] to the centroid of the poses with
#: the same stamp means the supervisor follows the live centroid.
CENTROID_MATCH_TOL = 1e-9
#: How many recent poses messages' centroids a robot remembers.
CENTROID_MEMORY = 8
#: Seconds between repeated warnings about dropped messages.
WARN_PERIOD = 5.0
#: Allowed spring rest lengths [m] (a Mona is 8 cm across) and largest robot id.
REST_LENGTH_RANGE = (1e-3, 1e3)
MAX_ROBOT_ID = 1_000_000

#: Robot nodes alive in this process. A neighbour run by the same process is alive
#: as long as this node is, so only neighbours in other processes are listened to.
_LOCAL_ROBOTS: weakref.WeakSet[RobotNode] = weakref.WeakSet()

_MODEL_NAMES = rp.GAIN_NAMES + rp.LIMIT_NAMES
#: The runtime-settable parameters (scenario and num_robots are read-only).
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


def convert_poses(msg: PoseArray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (N, 2), headings (N,) and centroid (2,) of ``/swarm/poses``.

    Done once per message per process, then shared by every robot of the process.
    Raises BadMessageError for non-finite values.
    """
    xy, yaw = poses_to_arrays(msg)
    centroid = xy.mean(axis=0) if len(xy) else np.zeros(2)
    return xy, yaw, centroid


@dataclass
class ControlInput:
    """What the control law of one robot needs for one step (:func:`robot_command`'s
    arguments), and where its result goes."""

    robot: RobotNode
    stamp: Time
    position: np.ndarray  #: (2,) [m]
    heading: float  #: [rad]
    neighbor_positions: np.ndarray  #: (K, 2) [m], neighbours heard from
    rest_lengths: np.ndarray  #: (K,) [m]
    gains: Gains
    command: SwarmCommand  #: center set, or None for "own position" (no rotation force)
    dt: float  #: [s]
    rng: np.random.Generator | None  #: None: noise off
    limits: tuple[float, float] | None

    def arguments(self) -> tuple:
        """Positional arguments of :func:`aes_ros.model.robot_command`."""
        return (
            self.position, self.heading, self.neighbor_positions, self.rest_lengths,
            self.gains, self.command, self.dt, self.rng, self.limits,
        )  # fmt: skip


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
    - ``alpha``, ``beta``, ``k``, ``v0``, ``w_l``, ``w_r``, ``d_r``, ``d_theta``,
      ``max_linear_speed`` [m/s], ``max_angular_speed`` [rad/s] (double, default:
      the scenario's values; ranges from :data:`aes_ros.params.PARAMS`).
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

    Topics: subscribes ``/swarm/poses`` (``poses`` source) or ``odom`` and
    ``/mona_<j>/odom`` of every neighbour j (``odom`` source), ``/mona_<j>/aes_force``
    of every neighbour j run by another process (liveness), and
    ``/swarm/desired_velocity``, ``/swarm/rotation_center``, ``/swarm/enabled``;
    publishes ``cmd_vel`` and ``aes_force``.

    With ``shared_inputs=True`` (used by :mod:`robot_node.host`) the node does
    not subscribe to the ``/swarm/*`` topics itself: its host converts each
    message once and calls :meth:`on_swarm_poses`, :meth:`on_desired_velocity`,
    :meth:`on_rotation_center` and :meth:`on_enabled` for all its robots.
    """

    def __init__(
        self, *, scenario: Scenario | None = None, shared_inputs: bool = False, **kwargs: Any
    ) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._warned: dict[str, float] = {}
        self._shared = shared_inputs
        scen = rp.declare_scenario(self, scenario)
        rp.declare_model_parameters(self, _MODEL_NAMES, scen.values)
        match = re.fullmatch(r"/mona_(\d+)", self.get_namespace())
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
                NEIGHBOR_SOURCES,
            ),
        )
        self._fill_sheet(scen)
        rp.guard_parameters(self, self._check, self._apply_parameters)

        self._cmd_pub = self.create_publisher(Twist, "cmd_vel", COMMAND_KEPT)
        self._cmd_msg = unicycle_twist(0.0, 0.0)
        self._force_pub = self.create_publisher(Vector3Stamped, "aes_force", COMMAND)
        #: cmd_vel (and as many aes_force) messages published so far.
        self.published = 0

        # Swarm command: the scenario's until the supervisor speaks.
        command = scen.command
        self._direction = tuple(command.direction)
        self._omega = float(command.omega)
        self._enabled = True
        self._center_point = None if command.center is None else np.asarray(command.center)
        self._center_stamp = -1
        self._follow_centroid = command.center is None
        self._center_pending = False
        self._centroids: dict[int, np.ndarray] = {}
        self._last_poses_stamp: int | None = None

        self._last_stamp: int | None = None
        self._dt = DEFAULT_DT
        self._nb_odom: dict[int, tuple[int, float, float]] = {}
        self._poses_sub = None
        self._odom_sub = None
        self._nb_subs: dict[int, Any] = {}
        # Liveness: stamp [ns] of each neighbour's latest aes_force, and the ids left out.
        self._heard: dict[int, int] = {}
        self._silent: set[int] = set()
        self._alive_subs: dict[int, Any] = {}
        self._applied: dict[str, Any] = {}
        self._apply_parameters()
        _LOCAL_ROBOTS.add(self)
        _mark_liveness_dirty(self.context)

        if not shared_inputs:
            self.create_subscription(
                TwistStamped, "/swarm/desired_velocity", self.on_desired_velocity, LATCHED
            )
            self.create_subscription(
                PointStamped, "/swarm/rotation_center", self.on_rotation_center, LATCHED
            )
            self.create_subscription(Bool, "/swarm/enabled", self.on_enabled, LATCHED)

    @property
    def uses_poses(self) -> bool:
        """True when the neighbour source is ``/swarm/poses``."""
        return self._source == "poses"

    # --- parameters -----------------------------------------------------------------

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
        robot_id = value("robot_id")
        neighbors = list(value("neighbors") or [])
        rest = list(value("rest_lengths") or [])
        if any(not 0 <= j <= MAX_ROBOT_ID for j in neighbors):
            return f"neighbors: {neighbors} has an id outside [0, {MAX_ROBOT_ID}]"
        if len(set(neighbors)) != len(neighbors):
            return f"neighbors: {neighbors} repeats an id"
        if robot_id in neighbors:
            return f"neighbors: {neighbors} contains the robot's own id {robot_id}"
        if rest and len(rest) != len(neighbors):
            return (
                f"rest_lengths: {len(rest)} values for {len(neighbors)} neighbors; "
                "give one per neighbour, or none to latch them"
            )
        low, high = REST_LENGTH_RANGE
        if not all(low <= r <= high for r in rest):  # also false for NaN
            return f"rest_lengths: {rest} must all be in [{low:g}, {high:g}] m"
        return rp.choice_error("neighbor_source", value("neighbor_source"), NEIGHBOR_SOURCES)

    def _apply_parameters(self) -> None:
        """Read the parameters into the controller's state (and fix subscriptions)."""
        p = {param.name: param.value for param in self.get_parameters(_APPLIED_NAMES)}
        self._gains = Gains(**{name: p[name] for name in rp.GAIN_NAMES})
        self._limits = (p["max_linear_speed"], p["max_angular_speed"]) if p["clip"] else None
        self._timeout_ns = int(p["neighbor_timeout"] * 1e9)
        sheet = (tuple(p["neighbors"]), tuple(p["rest_lengths"]))
        if sheet != self._applied.get("sheet"):
            self._neighbors = np.array(sheet[0], dtype=np.int64)
            # NaN marks a rest length still to be latched from the first distance seen.
            self._rest = np.array(sheet[1] or [np.nan] * len(sheet[0]), dtype=float)
            self._max_neighbor = int(self._neighbors.max()) if self._neighbors.size else -1
            self._all_latched = not np.isnan(self._rest).any()
        seeding = (p["seed"], p["robot_id"])
        if seeding != self._applied.get("seeding"):
            seed = p["seed"]
            self._rng = np.random.default_rng(None if seed < 0 else [seed, p["robot_id"]])
        self._robot_id = p["robot_id"]
        self._source = p["neighbor_source"]
        self._applied = {"sheet": sheet, "seeding": seeding}
        self._sync_subscriptions()
        _mark_liveness_dirty(self.context)

    def _sync_subscriptions(self) -> None:
        """Subscribe to what the neighbour source needs, and to nothing else."""
        want_poses = self._source == "poses" and not self._shared
        if want_poses and self._poses_sub is None:
            self._poses_sub = self.create_subscription(
                PoseArray, "/swarm/poses", self.on_poses, SENSOR
            )
        elif not want_poses and self._poses_sub is not None:
            self.destroy_subscription(self._poses_sub)
            self._poses_sub = None
        want_odom = self._source == "odom"
        if want_odom and self._odom_sub is None:
            self._odom_sub = self.create_subscription(Odometry, "odom", self.on_odom, SENSOR)
        elif not want_odom and self._odom_sub is not None:
            self.destroy_subscription(self._odom_sub)
            self._odom_sub = None
        wanted = set(self._neighbors.tolist()) if want_odom else set()
        for j in set(self._nb_subs) - wanted:
            self.destroy_subscription(self._nb_subs.pop(j))
            self._nb_odom.pop(j, None)
        for j in sorted(wanted - set(self._nb_subs)):
            self._nb_subs[j] = self.create_subscription(
                Odometry, f"/mona_{j}/odom", lambda msg, j=j: self.on_neighbor_odom(j, msg), SENSOR
            )

    def _sync_liveness(self) -> None:
        """Listen to the ``aes_force`` of every neighbour not run by this process."""
        self._liveness_dirty = False
        local = {r._robot_id for r in list(_LOCAL_ROBOTS) if r.context is self.context}
        wanted = set(self._neighbors.tolist()) - local
        for j in set(self._alive_subs) - wanted:
            self.destroy_subscription(self._alive_subs.pop(j))
            self._heard.pop(j, None)
            self._silent.discard(j)
        for j in sorted(wanted - set(self._alive_subs)):
            self._alive_subs[j] = self.create_subscription(
                Vector3Stamped,
                f"/mona_{j}/aes_force",
                lambda msg, j=j: self.on_neighbor_force(j, msg),
                COMMAND,
            )

    def _alive(self, ids: np.ndarray, stamp_ns: int) -> np.ndarray:
        """Mask of the neighbours ``ids`` heard from within neighbor_timeout of stamp_ns."""
        keep = np.ones(len(ids), dtype=bool)
        if not self._heard:
            return keep
        for slot, j in enumerate(ids.tolist()):
            heard = self._heard.get(j)
            silent = heard is not None and stamp_ns - heard > self._timeout_ns
            keep[slot] = not silent
            if silent and j not in self._silent:
                self._silent.add(j)
                self.get_logger().warning(
                    f"neighbour {j} silent for {(stamp_ns - heard) * 1e-9:.2f} s: left out"
                )
            elif not silent and j in self._silent:
                self._silent.discard(j)
                self.get_logger().info(f"neighbour {j} heard again: back in the sum")
        return keep

    # --- inputs -----------------------------------------------------------------------

    def on_neighbor_force(self, j: int, msg: Vector3Stamped) -> None:
        """A neighbour's ``aes_force``: it is alive at its stamp."""
        self._heard[j] = stamp_to_ns(msg.header.stamp)

    def on_poses(self, msg: PoseArray) -> None:
        """Own ``/swarm/poses`` subscription (single robot per process)."""
        try:
            xy, yaw, centroid = convert_poses(msg)
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/poses: {exc}")
            return
        self.on_swarm_poses(msg.header.stamp, xy, yaw, centroid)

    def on_swarm_poses(
        self, stamp: Time, positions: np.ndarray, headings: np.ndarray, centroid: np.ndarray
    ) -> None:
        """One ``/swarm/poses`` message, already converted: act if the source is poses."""
        self._act(self.control_input(stamp, positions, headings, centroid))

    def control_input(
        self, stamp: Time, positions: np.ndarray, headings: np.ndarray, centroid: np.ndarray
    ) -> ControlInput | None:
        """The inputs of the control law for one ``/swarm/poses`` message (None: no
        command this time). A host evaluates those of all its robots at once."""
        if self._source != "poses":
            return None
        stamp_ns = stamp_to_ns(stamp)
        self._remember_centroid(stamp_ns, centroid)
        i, n = self._robot_id, len(positions)
        if i >= n:
            self._warn(f"dropped /swarm/poses: {n} poses, no pose for robot_id {i}")
            return None
        neighbors = self._neighbors
        slots = None
        if self._max_neighbor >= n:
            self._warn(f"/swarm/poses has {n} poses: neighbours {neighbors.tolist()} left out")
            slots = np.flatnonzero(neighbors < n)
            neighbors = neighbors[slots]
        return self._control_input(
            stamp, stamp_ns, positions[i], headings[i], slots, positions[neighbors], centroid
        )

    def on_odom(self, msg: Odometry) -> None:
        """Own odometry (``odom`` source): act with the neighbours heard from recently."""
        try:
            stamp_ns, x, y, yaw = odom_to_pose(msg)
        except BadMessageError as exc:
            self._warn(f"dropped odom: {exc}")
            return
        slots, positions = [], []
        for slot, j in enumerate(self._neighbors.tolist()):
            heard = self._nb_odom.get(j)
            if heard is not None and stamp_ns - heard[0] <= self._timeout_ns:
                slots.append(slot)
                positions.append(heard[1:])
        self._act(
            self._control_input(
                msg.header.stamp,
                stamp_ns,
                np.array([x, y]),
                yaw,
                np.array(slots, dtype=np.int64),
                np.array(positions, dtype=float).reshape(-1, 2),
                None,
            )
        )

    def on_neighbor_odom(self, j: int, msg: Odometry) -> None:
        try:
            stamp_ns, x, y, _ = odom_to_pose(msg)
        except BadMessageError as exc:
            self._warn(f"dropped /mona_{j}/odom: {exc}")
            return
        self._nb_odom[j] = (stamp_ns, x, y)

    def on_desired_velocity(self, msg: TwistStamped) -> None:
        """The swarm command, checked against the ranges of ``direction`` and ``omega``."""
        try:
            direction, omega = twist_to_drive(msg.twist)
            PARAMS["direction"].validate(list(direction))
            PARAMS["omega"].validate(omega)
        except (BadMessageError, ParameterError) as exc:
            self._warn(f"dropped /swarm/desired_velocity: {exc}")
            return
        self._direction, self._omega = direction, omega

    def on_rotation_center(self, msg: PointStamped) -> None:
        try:
            point = point_to_array(msg.point)
        except BadMessageError as exc:
            self._warn(f"dropped /swarm/rotation_center: {exc}")
            return
        self._center_point = point
        self._center_stamp = stamp_to_ns(msg.header.stamp)
        centroid = self._centroids.get(self._center_stamp)
        if centroid is not None:
            self._follow_centroid = _same_point(centroid, point)
            self._center_pending = False
        elif self._last_poses_stamp is not None and self._center_stamp > self._last_poses_stamp:
            self._center_pending = True  # arrived before its poses: decide when they come
        else:
            self._follow_centroid = False
            self._center_pending = False

    def on_enabled(self, msg: Bool) -> None:
        self._enabled = bool(msg.data)

    # --- the control law ----------------------------------------------------------------

    def _remember_centroid(self, stamp_ns: int, centroid: np.ndarray) -> None:
        """Keep recent centroids to recognise a supervisor publishing the live centroid.

        Then the robot uses the centroid of the very poses it acts on instead of the
        (one message late) published copy: the same x_c as the offline simulator.
        """
        self._centroids[stamp_ns] = centroid
        if len(self._centroids) > CENTROID_MEMORY:
            del self._centroids[next(iter(self._centroids))]
        self._last_poses_stamp = stamp_ns
        if self._center_pending and stamp_ns >= self._center_stamp:
            same_stamp = stamp_ns == self._center_stamp
            self._follow_centroid = same_stamp and _same_point(centroid, self._center_point)
            self._center_pending = False

    def _control_input(
        self,
        stamp: Time,
        stamp_ns: int,
        position: np.ndarray,
        heading: float,
        slots: np.ndarray | None,
        neighbor_positions: np.ndarray,
        centroid: np.ndarray | None,
    ) -> ControlInput:
        """The control law's inputs for one new own pose (liveness, latched rest
        lengths, rotation centre and Δt applied)."""
        if self._last_stamp is not None:
            if stamp_ns > self._last_stamp:
                self._dt = (stamp_ns - self._last_stamp) * 1e-9
            elif stamp_ns < self._last_stamp:
                # The clock went back (a restarted simulator): what was heard before
                # belongs to the old time line.
                self._heard.clear()
                self._nb_odom.clear()
        self._last_stamp = stamp_ns
        if self._liveness_dirty:
            self._sync_liveness()
        if self._heard:
            ids = self._neighbors if slots is None else self._neighbors[slots]
            keep = self._alive(ids, stamp_ns)
            if not keep.all():
                slots = np.flatnonzero(keep) if slots is None else slots[keep]
                neighbor_positions = neighbor_positions[keep]
        rest = self._rest if slots is None else self._rest[slots]
        if not self._all_latched and (unset := np.isnan(rest)).any():
            # latch l_ij = the distance at first sight
            dist = np.hypot(*(neighbor_positions[unset] - position).T)
            rest = rest.copy()
            rest[unset] = dist
            if slots is None:
                self._rest = rest
            else:
                self._rest[slots] = rest
            self._all_latched = not np.isnan(self._rest).any()
        if self._follow_centroid and centroid is not None:
            center = centroid
        else:
            center = self._center_point
        command = SwarmCommand(
            self._direction, self._omega, None if center is None else tuple(center.tolist())
        )
        gains = self._gains
        rng = self._rng if (gains.d_r > 0.0 or gains.d_theta > 0.0) else None
        return ControlInput(
            self, stamp, position, heading, neighbor_positions, rest, gains, command,
            self._dt, rng, self._limits,
        )  # fmt: skip

    def _act(self, job: ControlInput | None) -> None:
        """Evaluate the control law for one input and publish the command."""
        if job is not None:
            self.publish_command(job, robot_command(*job.arguments()))

    def publish_command(self, job: ControlInput, result: RobotCommand) -> None:
        """Publish ``cmd_vel`` (and ``aes_force`` if heard) for one evaluated input."""
        force = result.force
        if not (
            math.isfinite(result.linear)
            and math.isfinite(result.angular)
            and math.isfinite(force[0])
            and math.isfinite(force[1])
        ):  # cannot happen with inputs that passed the conversions; never publish it
            stamp_ns = stamp_to_ns(job.stamp)
            self._warn(f"no command at t={stamp_ns * 1e-9:.2f} s: the control law is not finite")
            return
        # One Twist per robot, refilled: building a fresh message costs a third of
        # publishing it (bench/bench_ros.py, py-spy).
        cmd = self._cmd_msg
        cmd.linear.x, cmd.angular.z = (
            (result.linear, result.angular) if self._enabled else (0.0, 0.0)
        )
        self._cmd_pub.publish(cmd)
        if self._force_pub.get_subscription_count():  # for inspection: skip when unheard
            self._force_pub.publish(vector3_stamped(force, job.stamp, "odom"))
        self.published += 1

    def _warn(self, text: str) -> None:
        """A warning at most every WARN_PERIOD s per kind (the text before its first
        colon): rclpy's own throttle would let one kind silence all the others."""
        kind = text.partition(":")[0]
        now = time.monotonic()
        if now - self._warned.get(kind, -math.inf) >= WARN_PERIOD:
            self._warned[kind] = now
            self.get_logger().warning(text)

    def destroy_node(self) -> None:
        # Counted at the publisher, so that a recording can be checked for losses. Not
        # the node's logger: the context may be gone, and with it /rosout.
        COUNT_LOGGER.info(
            f"{self.get_namespace()}: published {self.published} cmd_vel and aes_force messages"
        )
        _LOCAL_ROBOTS.discard(self)
        _mark_liveness_dirty(self.context)
        super().destroy_node()


def _mark_liveness_dirty(context: Any) -> None:
    """The set of robots in this process or a sheet changed: re-check liveness
    subscriptions at each robot's next command."""
    for robot in list(_LOCAL_ROBOTS):
        if robot.context is context:
            robot._liveness_dirty = True


def _same_point(a: np.ndarray, b: np.ndarray | None) -> bool:
    return b is not None and bool(np.all(np.abs(a - b) <= CENTROID_MATCH_TOL))


def main(args: list[str] | None = None) -> int:
    """``aes-robot-node``: one robot in this process."""
    return run_node_process(NODE_NAME, args, RobotNode)


if __name__ == "__main__":
    sys.exit(main())

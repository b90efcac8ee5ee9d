"""The state of one robot's controller between messages (pure: no rclpy).

:class:`RobotController` turns what a robot hears (the poses of the swarm or
odometry, the swarm command) into the inputs of the control law
(:class:`aes_ros.robot_batch.RobotInput`, evaluated by :func:`aes_ros.robot_batch.evaluate_robots`):
the robot's sheet with rest lengths latched at first sight where none were given,
the neighbours still alive (:mod:`robot_node.liveness`), the rotation centre
(:mod:`robot_node.rotation_center`), Δt from the stamps, the noise generator, the
latest IR ranges (:mod:`robot_node.ir_readings`).
The ROS node (:mod:`robot_node.node`) only converts messages and parameters for it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from aes_ros.model import Gains, SwarmCommand
from aes_ros.robot_batch import RobotInput
from robot_node.ir_readings import IrReadings
from robot_node.liveness import NeighborLiveness
from robot_node.rotation_center import RotationCenterRule

#: Δt [s] for the noise until the second own pose gives the real period (20 Hz).
DEFAULT_DT = 0.05
#: Allowed spring rest lengths [m] (a Mona is 8 cm across) and largest robot id.
REST_LENGTH_RANGE = (1e-3, 1e3)
MAX_ROBOT_ID = 1_000_000


@dataclass(frozen=True)
class RobotSettings:
    """A robot's parameters (docs/design.md#ros-interface), as the controller uses them.

    rest_lengths : one per neighbour [m], or empty: latch them at first sight.
    limits : (max_linear_speed [m/s], max_angular_speed [rad/s]) or None: no clipping.
    neighbor_timeout : [s] of the robot's own stamps.
    seed : noise seed, combined with robot_id; -1: random.
    """

    robot_id: int
    neighbors: tuple[int, ...]
    rest_lengths: tuple[float, ...]
    gains: Gains
    limits: tuple[float, float] | None
    neighbor_timeout: float
    seed: int
    neighbor_source: str


def sheet_error(robot_id: int, neighbors: list[int], rest_lengths: list[float]) -> str | None:
    """Why ``neighbors`` and ``rest_lengths`` are not a valid sheet row, or None."""
    if any(not 0 <= j <= MAX_ROBOT_ID for j in neighbors):
        return f"neighbors: {neighbors} has an id outside [0, {MAX_ROBOT_ID}]"
    if len(set(neighbors)) != len(neighbors):
        return f"neighbors: {neighbors} repeats an id"
    if robot_id in neighbors:
        return f"neighbors: {neighbors} contains the robot's own id {robot_id}"
    if rest_lengths and len(rest_lengths) != len(neighbors):
        return (
            f"rest_lengths: {len(rest_lengths)} values for {len(neighbors)} neighbors; "
            "give one per neighbour, or none to latch them"
        )
    low, high = REST_LENGTH_RANGE
    if not all(low <= r <= high for r in rest_lengths):  # also false for NaN
        return f"rest_lengths: {rest_lengths} must all be in [{low:g}, {high:g}] m"
    return None


class RobotController:
    """Inputs of the control law of one robot, from its messages.

    Parameters
    ----------
    settings : the robot's parameters (:meth:`configure` changes them later).
    command : the swarm command until the supervisor speaks (the scenario's).
    warn : called with a warning about an input that was dropped or degraded.
    info : called with a note (a neighbour heard again).
    center : the rotation-centre rule x_c is read from; whoever hands the robot its
        messages feeds it (:class:`robot_node.swarm_inputs.SwarmInputs`: one rule for the
        robots of a process, fed once per poses and centre message).
    """

    def __init__(
        self,
        settings: RobotSettings,
        command: SwarmCommand,
        warn: Callable[[str], object] = lambda _text: None,
        info: Callable[[str], object] = lambda _text: None,
        *,
        center: RotationCenterRule,
    ) -> None:
        self._warn, self._info = warn, info
        self.direction = tuple(command.direction)
        self.omega = float(command.omega)
        self.enabled = True
        self.center = center
        self.liveness = NeighborLiveness(0)
        self.ir = IrReadings()
        self.dt = DEFAULT_DT
        self._last_stamp: int | None = None
        self._neighbor_odom: dict[int, tuple[int, float, float]] = {}
        self._settings: RobotSettings | None = None
        self.configure(settings)

    @property
    def settings(self) -> RobotSettings:
        return self._settings

    @property
    def neighbors(self) -> np.ndarray:
        """Neighbour ids j of S_i, (K,)."""
        return self._neighbors

    def configure(self, settings: RobotSettings) -> None:
        """Apply new parameters; a changed sheet starts latching again, a changed seed
        or robot_id restarts the noise generator."""
        old = self._settings
        self._settings = settings
        self.liveness.timeout_ns = int(settings.neighbor_timeout * 1e9)
        if old is None or (old.neighbors, old.rest_lengths) != (
            settings.neighbors,
            settings.rest_lengths,
        ):
            self._neighbors = np.array(settings.neighbors, dtype=np.int64)
            self._neighbor_ids = tuple(settings.neighbors)
            # NaN marks a rest length still to be latched from the first distance seen.
            rest = settings.rest_lengths or (np.nan,) * len(settings.neighbors)
            self._rest = np.array(rest, dtype=float)
            self._max_neighbor = int(self._neighbors.max()) if self._neighbors.size else -1
            self._all_latched = not np.isnan(self._rest).any()
        if old is None or (old.seed, old.robot_id) != (settings.seed, settings.robot_id):
            seed = None if settings.seed < 0 else [settings.seed, settings.robot_id]
            self._rng = np.random.default_rng(seed)

    # --- what the robot hears -------------------------------------------------------

    def set_drive(self, direction: tuple[float, float], omega: float) -> None:
        """The supervisor's v_d and ω (already checked against their ranges)."""
        self.direction, self.omega = direction, omega

    def heard_force(self, neighbor: int, stamp_ns: int) -> None:
        """A neighbour's ``aes_force``: it is alive at its stamp."""
        self.liveness.heard(neighbor, stamp_ns)

    def neighbor_odom(self, neighbor: int, stamp_ns: int, x: float, y: float) -> None:
        """A neighbour's odometry (``odom`` source): its position at its stamp."""
        self._neighbor_odom[neighbor] = (stamp_ns, x, y)

    def forget_neighbor(self, neighbor: int) -> None:
        """No longer listened to: drop its stamps and odometry."""
        self.liveness.forget(neighbor)
        self._neighbor_odom.pop(neighbor, None)

    # --- inputs of the control law ----------------------------------------------------

    def poses_input(
        self, stamp_ns: int, positions: np.ndarray, headings: np.ndarray, centroid: np.ndarray
    ) -> RobotInput | None:
        """The control law's inputs for one ``/swarm/poses`` message: positions (N, 2)
        [m], headings (N,) [rad], centroid (2,). None: no command this time (the
        source is odom, or the message has no pose for this robot)."""
        if self._settings.neighbor_source != "poses":
            return None
        i, n = self._settings.robot_id, len(positions)
        if i >= n:
            self._warn(f"dropped /swarm/poses: {n} poses, no pose for robot_id {i}")
            return None
        neighbors = self._neighbors
        slots = None
        if self._max_neighbor >= n:
            self._warn(f"/swarm/poses has {n} poses: neighbours {neighbors.tolist()} left out")
            slots = np.flatnonzero(neighbors < n)
            neighbors = neighbors[slots]
        return self._input(
            stamp_ns, positions[i], headings[i], slots, positions[neighbors], centroid
        )

    def odom_input(self, stamp_ns: int, x: float, y: float, yaw: float) -> RobotInput:
        """The control law's inputs for one own odometry message (``odom`` source), with
        the neighbours whose odometry is no older than ``neighbor_timeout``."""
        oldest = stamp_ns - self.liveness.timeout_ns
        heard = [self._neighbor_odom.get(j) for j in self._neighbor_ids]
        fresh = [h is not None and h[0] >= oldest for h in heard]
        if all(fresh):  # the usual case: every slot, in order (no index arrays)
            slots = None
        else:
            slots = np.flatnonzero(fresh)
            heard = [heard[k] for k in slots.tolist()]
        positions = np.array([h[1:] for h in heard], dtype=float).reshape(-1, 2)
        return self._input(stamp_ns, np.array([x, y]), yaw, slots, positions, None)

    def _input(
        self,
        stamp_ns: int,
        position: np.ndarray,
        heading: float,
        slots: np.ndarray | None,
        neighbor_positions: np.ndarray,
        centroid: np.ndarray | None,
    ) -> RobotInput:
        """Inputs for one new own pose: liveness, latched rest lengths, the rotation
        centre and Δt applied. ``slots`` are the sheet slots of ``neighbor_positions``
        (None: all of them, in order)."""
        if self._last_stamp is not None:
            if stamp_ns > self._last_stamp:
                self.dt = (stamp_ns - self._last_stamp) * 1e-9
            elif stamp_ns < self._last_stamp:
                # The clock went back (a restarted simulator): what was heard before
                # belongs to the old time line.
                self.liveness.clear()
                self._neighbor_odom.clear()
                self.ir.clear()
        self._last_stamp = stamp_ns
        if self.liveness:
            ids = self._neighbors if slots is None else self._neighbors[slots]
            keep, changes = self.liveness.alive(ids, stamp_ns)
            for change in changes:
                if change.silent and change.seconds != change.seconds:  # NaN: lost
                    self._warn(f"neighbour {change.neighbor} lost by the tracker: left out")
                elif change.silent:
                    self._warn(
                        f"neighbour {change.neighbor} silent for {change.seconds:.2f} s: left out"
                    )
                else:
                    self._info(f"neighbour {change.neighbor} heard again: back in the sum")
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
        center = self.center.center(centroid)
        command = SwarmCommand(
            self.direction, self.omega, None if center is None else tuple(center.tolist())
        )
        s = self._settings
        rng = self._rng if (s.gains.d_r > 0.0 or s.gains.d_theta > 0.0) else None
        ir_ranges = self.ir.ranges(stamp_ns) if s.gains.w_o > 0.0 else None
        return RobotInput(
            position, heading, neighbor_positions, rest, s.gains, command, self.dt, rng, s.limits,
            ir_ranges,
        )  # fmt: skip

"""AES robot host: K robot nodes in one process on one EventsExecutor (SPEC §7).

Each robot is its own rclpy node (``/mona_<i>/aes_robot``: own parameters,
``cmd_vel`` and ``aes_force``), but the process subscribes once to each
``/swarm/*`` input and fans the converted message out to its robots, so a
``/swarm/poses`` message is turned into arrays once per process, not once per
robot. In the ``odom`` source every robot subscribes to its neighbours' odometry
itself.

Robots 0–7 of the 16-robot linear scenario, neighbours from the scenario::

    aes-robot-host --ros-args -p scenario:=linear -p num_robots:=16 \\
        -p robot_ids:=[0,1,2,3,4,5,6,7] -p use_sim_time:=true

``-p name:=value`` without a node prefix applies to every node of the process,
so ``-p alpha:=0.1 -p d_r:=0.0`` changes all robots of this host.
"""

from __future__ import annotations

import sys
from dataclasses import fields
from functools import lru_cache
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, PoseArray, TwistStamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Bool

from aes_ros.model import Gains, RobotCommand, draw_noise, robot_command, robot_commands
from aes_ros.params import ParameterError
from aes_ros.ros import parameters as rp
from aes_ros.ros.cdr import decode_pose_array
from aes_ros.ros.conversions import BadMessageError
from aes_ros.ros.qos import LATCHED, SENSOR
from aes_ros.ros.spin import run_node_process
from aes_ros.scenario import Scenario
from robot_node.node import NEIGHBOR_SOURCES, ControlInput, RobotNode

NODE_NAME = "robot_host"


class RobotHostNode(Node):
    """Creates and feeds the robot nodes of one process (node ``robot_host``).

    Parameters (read at start):

    - ``scenario`` (string, default ``combined``): setup name or YAML path.
    - ``num_robots`` (int, default 0 = the scenario's formation).
    - ``robot_ids`` (int[], default empty = every robot of the scenario).
    - ``neighbor_source`` (string, ``poses`` | ``odom``, default ``poses``).

    Each robot ``i`` is a :class:`robot_node.node.RobotNode` in namespace
    ``/mona_<i>`` with ``robot_id``, ``neighbors``, ``rest_lengths`` from the
    scenario's sheet; its gains come from the scenario unless overridden by
    ``-p``. The robots are in :attr:`robots`; spin them with the host.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        scen = rp.declare_scenario(self)
        ids = self.declare_parameter(
            "robot_ids",
            Parameter.Type.INTEGER_ARRAY,
            rp.array_descriptor(
                "ids of the robots this process runs (empty = all)",
                "",
                "distinct ids of the scenario's robots",
            ),
        ).value
        source = self.declare_parameter(
            "neighbor_source",
            "poses",
            rp.text_descriptor(
                "where neighbour positions come from: /swarm/poses or the neighbours' odom",
                NEIGHBOR_SOURCES,
            ),
        ).value
        _, table, rest_table = scen.sheet()
        n = len(table)
        ids = list(range(n)) if not ids else list(ids)
        bad = [i for i in ids if not 0 <= i < n]
        if bad or len(set(ids)) != len(ids):
            raise ParameterError(f"robot_ids: {ids} must be distinct ids in [0, {n - 1}]")
        if (reason := rp.choice_error("neighbor_source", source, NEIGHBOR_SOURCES)) is not None:
            raise ParameterError(reason)
        self.robots: list[RobotNode] = []
        for i in ids:
            keep = table[i] >= 0
            self.robots.append(
                make_robot(
                    scen,
                    self.get_parameter("scenario").value,
                    self.get_parameter("num_robots").value,
                    i,
                    table[i][keep].tolist(),
                    rest_table[i][keep].tolist(),
                    source,
                )
            )

        for robot in self.robots:
            self._share_clock(robot)

        # Raw: the poses are read from the wire format with numpy (aes_ros.ros.cdr).
        self.create_subscription(PoseArray, "/swarm/poses", self.on_poses, SENSOR, raw=True)
        self.create_subscription(
            TwistStamped, "/swarm/desired_velocity", self.on_desired_velocity, LATCHED
        )
        self.create_subscription(
            PointStamped, "/swarm/rotation_center", self.on_rotation_center, LATCHED
        )
        self.create_subscription(Bool, "/swarm/enabled", self.on_enabled, LATCHED)
        self.get_logger().info(
            f"{len(self.robots)} robots ({ids[0]}…{ids[-1]}), neighbour source {source}"
        )

    def _share_clock(self, robot: RobotNode) -> None:
        """With use_sim_time, drive the robot's clock from this node's ``/clock``.

        Every node subscribes to ``/clock`` on its own otherwise: measured 18 % of a
        core at 50 Hz for 100 robots in one process, for time the robots hardly use.
        rclpy has no public API for sharing a time source, hence the private
        ``_time_source`` (rclpy 7.1).
        """
        if not robot.get_parameter("use_sim_time").value:
            return
        robot._time_source.detach_node()  # drops the robot's own /clock subscription
        self._time_source.attach_clock(robot.get_clock())

    def on_poses(self, data: bytes) -> None:
        """Decode ``/swarm/poses`` once and hand it to every robot of this process."""
        if not any(robot.uses_poses for robot in self.robots):
            return
        try:
            sec, nanosec, xy, yaw = decode_pose_array(data)
        except BadMessageError as exc:
            self.get_logger().warning(f"dropped /swarm/poses: {exc}", throttle_duration_sec=5.0)
            return
        centroid = xy.mean(axis=0) if len(xy) else np.zeros(2)
        stamp = Time(sec=sec, nanosec=nanosec)
        jobs = [robot.control_input(stamp, xy, yaw, centroid) for robot in self.robots]
        jobs = [job for job in jobs if job is not None]
        for job, result in zip(jobs, evaluate(jobs), strict=True):
            job.robot.publish_command(job, result)

    def on_desired_velocity(self, msg: TwistStamped) -> None:
        for robot in self.robots:
            robot.on_desired_velocity(msg)

    def on_rotation_center(self, msg: PointStamped) -> None:
        for robot in self.robots:
            robot.on_rotation_center(msg)

    def on_enabled(self, msg: Bool) -> None:
        for robot in self.robots:
            robot.on_enabled(msg)

    def destroy_node(self) -> None:
        for robot in self.robots:
            robot.destroy_node()
        super().destroy_node()


_GAIN_FIELDS = tuple(f.name for f in fields(Gains))


@lru_cache(maxsize=256)
def _gain_values(gains: Gains) -> tuple[float, ...]:
    return tuple(getattr(gains, name) for name in _GAIN_FIELDS)


def evaluate(jobs: list[ControlInput]) -> list[RobotCommand]:
    """The control law of every job, in one :func:`aes_ros.model.robot_commands` call.

    The robots of a host all act on the same ``/swarm/poses`` message; evaluated
    together the numpy work is done once per message instead of once per robot
    (bench/bench_ros.py). Each robot's noise is still drawn from its own
    generator in the same order, so the commands are those of
    :func:`aes_ros.model.robot_command` for each job, bit for bit.
    """
    if len(jobs) <= 1:
        return [robot_command(*job.arguments()) for job in jobs]
    r = len(jobs)
    k = max(len(job.rest_lengths) for job in jobs)
    positions, headings = np.empty((r, 2)), np.empty(r)
    neighbors, rest = np.zeros((r, k, 2)), np.zeros((r, k))  # rest 0 = padding
    gain_rows = np.empty((r, len(_GAIN_FIELDS)))
    directions, omegas, centers = np.empty((r, 2)), np.empty(r), np.empty((r, 2))
    dt, limits = np.empty(r), np.full((r, 2), np.inf)
    noise = (np.zeros(r), np.zeros(r), np.zeros(r))
    for row, job in enumerate(jobs):
        n = len(job.rest_lengths)
        positions[row] = job.position
        headings[row] = job.heading
        neighbors[row, :n] = job.neighbor_positions
        rest[row, :n] = job.rest_lengths
        gain_rows[row] = _gain_values(job.gains)
        command = job.command
        directions[row] = command.direction
        omegas[row] = command.omega
        centers[row] = job.position if command.center is None else command.center
        dt[row] = job.dt
        if job.limits is not None:
            limits[row] = job.limits
        if job.rng is not None:
            xi = draw_noise(job.rng)
            noise[0][row], noise[1][row], noise[2][row] = xi[0], xi[1], xi[2]
    gains = Gains(**{name: gain_rows[:, col] for col, name in enumerate(_GAIN_FIELDS)})
    u, turn_rate, forces = robot_commands(
        positions, headings, neighbors, rest, gains, directions, omegas, centers, dt, noise, limits
    )
    return [
        RobotCommand(linear, angular, force)
        for linear, angular, force in zip(u.tolist(), turn_rate.tolist(), forces, strict=True)
    ]


def make_robot(
    scen: Scenario,
    scenario_name: str,
    num_robots: int,
    robot_id: int,
    neighbors: list[int],
    rest: list[float],
    source: str,
) -> RobotNode:
    """Robot node ``/mona_<robot_id>/aes_robot`` fed by its host.

    The explicit overrides below win over the process-wide ``-p`` ones (which
    still set the gains of every robot).
    """
    overrides = [
        Parameter("scenario", Parameter.Type.STRING, scenario_name),
        Parameter("num_robots", Parameter.Type.INTEGER, num_robots),
        Parameter("robot_id", Parameter.Type.INTEGER, robot_id),
        Parameter("neighbors", Parameter.Type.INTEGER_ARRAY, neighbors),
        Parameter("rest_lengths", Parameter.Type.DOUBLE_ARRAY, rest),
        Parameter("neighbor_source", Parameter.Type.STRING, source),
        # ~type_description is a service per node that no tool of this system
        # needs; creating it is over half the cost of a robot node (200 robots:
        # 5.2 s -> 2.9 s), and the cost per node grows with the process's node count.
        Parameter("start_type_description_service", Parameter.Type.BOOL, False),
    ]
    return RobotNode(
        scenario=scen,
        shared_inputs=True,
        namespace=f"/mona_{robot_id}",
        parameter_overrides=overrides,
    )


def main(args: list[str] | None = None) -> int:
    """``aes-robot-host``: the robots of ``robot_ids`` in this process."""
    return run_node_process(NODE_NAME, args, RobotHostNode, lambda host: [host, *host.robots])


if __name__ == "__main__":
    sys.exit(main())

"""AES robot host: K robot nodes in one process on one EventsExecutor.

See docs/design.md#processes.

Each robot is its own rclpy node (``/mona_<i>/aes_robot``: own parameters,
``cmd_vel`` and ``aes_force``), but the process reads each ``/swarm/*`` input once
(:class:`robot_node.swarm_inputs.SwarmInputs`) and evaluates the control law of
all its robots acting on a poses message in one call. In the ``odom`` source
every robot subscribes to its neighbours' odometry itself.

Robots 0–7 of the 16-robot linear scenario, neighbours from the scenario::

    aes-robot-host --ros-args -p scenario:=linear -p num_robots:=16 \\
        -p robot_ids:=[0,1,2,3,4,5,6,7] -p use_sim_time:=true

``-p name:=value`` without a node prefix applies to every node of the process,
so ``-p alpha:=0.1 -p d_r:=0.0`` changes all robots of this host.
"""

from __future__ import annotations

import functools
import math
import os
import sys
from collections.abc import Sequence
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from aes_ros.params import ParameterError
from aes_ros.ros import discovery as dds
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.spin import run_node_process
from robot_node.node import RobotNode
from robot_node.swarm_inputs import SwarmInputs

#: Robots per DDS participant when the host is a client of a discovery server
#: (``robots_per_participant`` 0). Fast DDS pairs each endpoint it learns of with every
#: endpoint of its own participant, and rmw sends a participant's whole graph at each
#: endpoint it makes; a server passes on only the endpoints of the topics a participant
#: uses, so smaller participants cut both. Under simple discovery every participant hears
#: of everything, so there the host keeps one. Measured: docs/performance.md#starting-1000-robots
#: (``bench/bench_startup.py --profile launch``).
ROBOTS_PER_PARTICIPANT = 100


class RobotHostNode(Node):
    """Creates and feeds the robot nodes of one process (node ``robot_host``).

    Parameters (read at start):

    - ``scenario`` (string, default ``combined``): setup name or YAML path.
    - ``num_robots`` (int, default 0 = the scenario's formation).
    - ``robot_ids`` (int[], default empty = every robot of the scenario).
    - ``neighbor_source`` (string, ``poses`` | ``odom``, default ``poses``).
    - ``robots_per_participant`` (int, default 0 = :data:`ROBOTS_PER_PARTICIPANT` when
      ``ROS_DISCOVERY_SERVER`` is set, else all in one): the robots share DDS
      participants (rclpy contexts) of at most this many robots. Under simple discovery
      participants of one process discover each other like any others, so one is best.

    Each robot ``i`` is a :class:`robot_node.node.RobotNode` in namespace
    ``/mona_<i>`` with ``robot_id``, ``neighbors``, ``rest_lengths`` from the
    scenario's sheet; its gains come from the scenario unless overridden by
    ``-p``. The robots are in :attr:`robots`; spin them with the host.
    """

    def __init__(self, *, args: Sequence[str] | None = None, **kwargs: Any) -> None:
        """``args``: the process's command line (None: ``sys.argv``), for the robots'
        participants beyond the first (each an rclpy context, given the same
        ``--ros-args``)."""
        super().__init__(names.ROBOT_HOST_NODE, **kwargs)
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
                names.NEIGHBOR_SOURCES,
            ),
        ).value
        per_participant = self.declare_parameter(
            "robots_per_participant",
            0,
            rp.int_descriptor(
                "robots per DDS participant (0: "
                f"{ROBOTS_PER_PARTICIPANT} with a discovery server, else all in one)",
                0,
                read_only=True,
            ),
        ).value
        _, table, rest_table = scen.sheet()
        n = len(table)
        ids = list(range(n)) if not ids else list(ids)
        bad = [i for i in ids if not 0 <= i < n]
        if bad or len(set(ids)) != len(ids):
            raise ParameterError(f"robot_ids: {ids} must be distinct ids in [0, {n - 1}]")
        reason = rp.choice_error("neighbor_source", source, names.NEIGHBOR_SOURCES)
        if reason is not None:
            raise ParameterError(reason)
        self.inputs = SwarmInputs(self, scen.command)
        shared = [
            Parameter("scenario", Parameter.Type.STRING, self.get_parameter("scenario").value),
            Parameter("num_robots", Parameter.Type.INTEGER, self.get_parameter("num_robots").value),
            Parameter("neighbor_source", Parameter.Type.STRING, source),
            # ~type_description is a service per node that no tool of this system
            # needs; creating it is over half the cost of a robot node, and the cost per
            # node grows with the process's node count.
            Parameter("start_type_description_service", Parameter.Type.BOOL, False),
            # Sim time comes from this node (_share_clock): made with it, every robot
            # would subscribe to /clock only to drop the subscription again.
            Parameter("use_sim_time", Parameter.Type.BOOL, False),
        ]
        sim_time = bool(self.get_parameter("use_sim_time").value)
        # the contexts beyond this node's are its own to shut down, after the robots
        self._own_contexts = self._more_participants(len(ids), per_participant, args)
        contexts = [self.context, *self._own_contexts]
        self.robots: list[RobotNode] = []
        for k, i in enumerate(ids):
            keep = table[i] >= 0
            # These overrides win over the process-wide -p ones (which still set the
            # gains of every robot).
            overrides = [*shared, Parameter("robot_id", Parameter.Type.INTEGER, i)]
            if keep.any():  # rclpy takes an empty list override for a BYTE_ARRAY
                overrides += [
                    Parameter("neighbors", Parameter.Type.INTEGER_ARRAY, table[i][keep].tolist()),
                    Parameter(
                        "rest_lengths", Parameter.Type.DOUBLE_ARRAY, rest_table[i][keep].tolist()
                    ),
                ]
            robot = RobotNode(
                scenario=scen,
                inputs=self.inputs,
                namespace=names.robot_namespace(i),
                parameter_overrides=overrides,
                context=contexts[k * len(contexts) // len(ids)],
            )
            if sim_time:
                self._share_clock(robot)
            self.robots.append(robot)
        self.get_logger().info(
            f"{names.ROBOTS_READY} {len(self.robots)} robots ({ids[0]}…{ids[-1]}), "
            f"neighbour source {source}, {len(contexts)} DDS participant(s)"
        )

    def _more_participants(
        self, robots: int, per_participant: int, args: Sequence[str] | None
    ) -> list[Context]:
        """The contexts the robots need beyond this node's: as many as ``per_participant``
        asks (0: :data:`ROBOTS_PER_PARTICIPANT` under a discovery server, else none)."""
        if per_participant == 0:
            server = os.environ.get(dds.SERVER_VARIABLE)
            per_participant = ROBOTS_PER_PARTICIPANT if server else max(robots, 1)
        contexts = [Context() for _ in range(math.ceil(robots / per_participant) - 1)]
        for context in contexts:
            rclpy.init(args=args, context=context, signal_handler_options=SignalHandlerOptions.NO)
        return contexts

    def _share_clock(self, robot: RobotNode) -> None:
        """Put the robot on sim time: its clock is this node's, driven by this node's ``/clock``.

        Every node subscribes to ``/clock`` on its own otherwise: measured 18 % of a
        core at 50 Hz for 100 robots in one process, for time the robots hardly use
        (the stamps of their parameter events); one clock rather than one per robot
        kept in step, as setting 100 clocks at each ``/clock`` was 3 % of a host. The
        robot was made with ``use_sim_time`` false, and creating its own ``/clock``
        subscription and dropping it again was a sixth of a host's start (500 robots);
        with its time source detached, setting ``use_sim_time`` true makes
        ``ros2 param get`` tell the truth and subscribes to nothing. So a host's
        ``use_sim_time`` holds for all its robots. rclpy has no public API for sharing
        a time source or a clock, hence the private ``_time_source`` and ``_clock``
        (rclpy 7.1; ``get_clock()`` returns ``_clock``).
        """
        robot._time_source.detach_node()
        robot._clock = self.get_clock()
        robot.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])

    def destroy_node(self) -> None:
        # Every robot's counts first: rmw destroys a node's endpoints at a cost that
        # grows with the nodes of the process (docs/performance.md#starting-1000-robots), so a
        # large host is SIGKILLed at the launch's stop timeout before its last robots
        # are destroyed, and their counts must not go with them.
        for robot in self.robots:
            robot.log_counts()
        for robot in self.robots:
            robot.destroy_node()
        for context in self._own_contexts:
            rclpy.try_shutdown(context=context)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """``aes-robot-host``: the robots of ``robot_ids`` in this process."""
    return run_node_process(
        names.ROBOT_HOST_NODE,
        args,
        functools.partial(RobotHostNode, args=args),
        lambda host: [host, *host.robots],
    )


if __name__ == "__main__":
    sys.exit(main())

"""The straightforward ROS 2 swarm design, as a baseline for ``bench/bench_ros.py``.

What many ROS swarm packages do, written plainly and without handicaps: one rclpy node
per robot, the nodes of a process on one ``SingleThreadedExecutor``, each robot
subscribing to its own and its neighbours' ``nav_msgs/Odometry`` (message objects) and
to the supervisor's ``/swarm/desired_velocity`` and ``/swarm/rotation_center``, and
publishing a ``geometry_msgs/Twist`` on ``cmd_vel`` each time its own odometry arrives.
The control law is the project's own :func:`aes_ros.model.robot_command` (E1–E6), so
only the ROS plumbing differs from ``aes-robot-host``.

Usage (one process per block of robots, next to ``aes-sim-bridge`` and ``aes-supervisor``)::

    python bench/naive_swarm.py --scenario scenario.yaml --ids 0:10
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import rclpy
from geometry_msgs.msg import PointStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from aes_ros import scenario as scenario_mod
from aes_ros.model import SwarmCommand, robot_command
from aes_ros.ros import interface as names
from aes_ros.ros.conversions import pose_to_array
from aes_ros.ros.qos import COMMAND, LATCHED, SENSOR


class NaiveRobot(Node):
    """Robot ``i``: odometry in, the control law, ``cmd_vel`` out."""

    def __init__(self, i: int, neighbors: np.ndarray, rest: np.ndarray, sc) -> None:
        super().__init__(names.ROBOT_NODE, namespace=names.robot_namespace(i))
        self.gains, self.dt = sc.gains, sc.dt
        self.command = sc.command
        self.neighbors = [int(j) for j in neighbors if j >= 0]
        self.rest = rest[: len(self.neighbors)]
        self.heard: dict[int, np.ndarray] = {}
        self.rng = np.random.default_rng(i)
        self.pub = self.create_publisher(Twist, names.robot_topic(i, names.CMD_VEL), COMMAND)
        self.create_subscription(Odometry, names.robot_topic(i, names.ODOM), self.on_odom, SENSOR)
        for j in self.neighbors:
            self.create_subscription(
                Odometry,
                names.robot_topic(j, names.ODOM),
                lambda msg, j=j: self.heard.__setitem__(
                    j, np.array([msg.pose.pose.position.x, msg.pose.pose.position.y])
                ),
                SENSOR,
            )
        self.create_subscription(TwistStamped, names.DESIRED_VELOCITY, self.on_desired, LATCHED)
        self.create_subscription(PointStamped, names.ROTATION_CENTER, self.on_center, LATCHED)

    def on_desired(self, msg: TwistStamped) -> None:
        t = msg.twist
        self.command = SwarmCommand((t.linear.x, t.linear.y), t.angular.z, self.command.center)

    def on_center(self, msg: PointStamped) -> None:
        center = (msg.point.x, msg.point.y)
        self.command = SwarmCommand(self.command.direction, self.command.omega, center)

    def on_odom(self, msg: Odometry) -> None:
        x, y, yaw = pose_to_array(msg.pose.pose)
        ids = [j for j in self.neighbors if j in self.heard]
        rest = np.array([self.rest[self.neighbors.index(j)] for j in ids])
        out = robot_command(
            np.array([x, y]), yaw, np.array([self.heard[j] for j in ids]).reshape(-1, 2), rest,
            self.gains, self.command, self.dt, self.rng,
        )  # fmt: skip
        twist = Twist()
        twist.linear.x = out.linear
        twist.angular.z = out.angular
        self.pub.publish(twist)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", required=True, help="the scenario file of the launch")
    parser.add_argument("--ids", required=True, help="robot ids FIRST:STOP of this process")
    args = parser.parse_args(argv)
    sc = scenario_mod.load(args.scenario)
    _, neighbors, rest = sc.sheet()
    first, stop = (int(v) for v in args.ids.split(":"))
    rclpy.init()
    executor = SingleThreadedExecutor()
    robots = [NaiveRobot(i, neighbors[i], rest[i], sc) for i in range(first, stop)]
    for robot in robots:
        executor.add_node(robot)
    print(f"naive robots {first}..{stop - 1} ready", flush=True)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for robot in robots:
            robot.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())

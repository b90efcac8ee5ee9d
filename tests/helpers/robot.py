"""Robot 1 between robots 0 and 2, as the robot-node tests start it, and the command
it must publish (the control law of :func:`aes_ros.model.robot_command`)."""

from __future__ import annotations

import numpy as np
import pytest
from geometry_msgs.msg import Twist, Vector3Stamped

from aes_ros.model import RobotCommand, robot_command
from aes_ros.ros.interface import AES_FORCE, CMD_VEL, WORLD_FRAME, robot_topic
from aes_ros.ros.qos import COMMAND

#: Robot 1 in its namespace, neighbours 0 and 2.
ROBOT_1 = ["-r", "__ns:=/mona_1", "-p", "robot_id:=1", "-p", "neighbors:=[0,2]"]
#: Its node.
NODE_1 = "/mona_1/aes_robot"
#: The rest lengths of its springs to robots 0 and 2 [m].
REST_1 = [0.2, 0.25]
#: Noise and clipping off: the command is a function of the inputs alone.
NOISE_OFF = ["-p", "d_r:=0.0", "-p", "d_theta:=0.0", "-p", "clip:=false"]


def robot_1(*args: str, rest_lengths: str = "[0.2,0.25]") -> list[str]:
    """The ``aes-robot-node`` command line of robot 1 (``args`` after its ROS arguments)."""
    return ["aes-robot-node", "--ros-args", *ROBOT_1, "-p", f"rest_lengths:={rest_lengths}", *args]


def record_outputs(probe, robot_id: int) -> tuple[list[Twist], list[Vector3Stamped]]:
    """The ``cmd_vel`` and ``aes_force`` messages of a robot, as ``probe`` receives them."""
    return (
        probe.record(Twist, robot_topic(robot_id, CMD_VEL), COMMAND),
        probe.record(Vector3Stamped, robot_topic(robot_id, AES_FORCE), COMMAND),
    )


def expected(xy, yaw, i, neighbors, rest, gains, command, dt=0.05) -> RobotCommand:
    """The command of robot ``i`` at positions ``xy`` and headings ``yaw``."""
    xy = np.asarray(xy, dtype=float)
    return robot_command(xy[i], yaw[i], xy[neighbors], np.asarray(rest), gains, command, dt)


def same_force(msg: Vector3Stamped, want) -> bool:
    """The published force equals ``want`` (x, y) to 1e-12."""
    return (msg.vector.x, msg.vector.y) == pytest.approx(tuple(want), abs=1e-12)


def assert_command(cmd: Twist, force: Vector3Stamped, want: RobotCommand) -> None:
    """``cmd_vel`` and ``aes_force`` are ``want``: a unicycle command, the force in the
    world frame."""
    assert cmd.linear.x == pytest.approx(want.linear, abs=1e-12)
    assert cmd.angular.z == pytest.approx(want.angular, abs=1e-12)
    assert (cmd.linear.y, cmd.linear.z, cmd.angular.x, cmd.angular.y) == (0, 0, 0, 0)
    assert (force.vector.x, force.vector.y) == pytest.approx(tuple(want.force), abs=1e-12)
    assert force.header.frame_id == WORLD_FRAME

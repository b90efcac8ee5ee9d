"""The ROS parameters of the ``sim_bridge`` node, declared with the shared descriptors."""

from __future__ import annotations

from rclpy.node import Node

from aes_ros.params import ParameterError
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from sim_bridge.ir_sensors import declare_ir_parameters
from sim_bridge.lockstep import DEFAULT_TIMEOUT


def declare_bridge_parameters(node: Node, ir_rate: float = 20.0) -> None:
    """Declare every bridge parameter but ``scenario``/``num_robots`` (those come from
    :func:`aes_ros.ros.parameters.declare_scenario`, as in every node); ``ir_rate`` [Hz] is
    the scenario's, the default of the IR sensors' rate."""
    node.declare_parameter(
        "seed",
        0,
        rp.int_descriptor(
            "seed of the initial state (Scenario.initial_state; read at start)",
            0,
            2**31 - 1,
            read_only=True,
        ),
    )
    node.declare_parameter(
        "resume_from",
        "",
        rp.text_descriptor(
            "a world state file (.npz: t, positions, headings) to start from instead of "
            "the seed's initial state, its sim time included; empty = t = 0 (read at start)",
            read_only=True,
        ),
    )
    node.declare_parameter(
        "mode",
        "kinematic",
        rp.text_descriptor(
            "kinematic: bodies follow cmd_vel exactly; dynamic: wheel motors, friction "
            "and collisions (read at start)",
            names.MODES,
            read_only=True,
        ),
    )
    node.declare_parameter(
        "physics_rate",
        240.0,
        rp.float_descriptor(
            "pybullet step rate in dynamic mode", "Hz", 1.0, 10000.0, read_only=True
        ),
    )
    node.declare_parameter(
        "publish_rate",
        20.0,
        rp.float_descriptor(
            "control rate: world steps, /clock, poses and odom", "Hz", 0.1, 1000.0, read_only=True
        ),
    )
    node.declare_parameter(
        "real_time_factor",
        1.0,
        rp.float_descriptor(
            "sim seconds per wall second; 0 = as fast as possible", "", 0.0, 1000.0
        ),
    )
    node.declare_parameter(
        "lockstep", False, rp.bool_descriptor("wait for every robot's cmd_vel before each step")
    )
    node.declare_parameter(
        "lockstep_timeout",
        DEFAULT_TIMEOUT,
        rp.float_descriptor(
            "lockstep: a robot (or the recorder) silent for longer leaves the barrier until "
            "it answers again (wall time)",
            "s",
            0.01,
            1e6,
        ),
    )
    node.declare_parameter(
        "wait_for_recorder",
        False,
        rp.bool_descriptor(
            "lockstep: also wait until the recorder has written each state "
            f"({names.RECORDER_PROGRESS})"
        ),
    )
    node.declare_parameter(
        "pause_at",
        0.0,
        rp.float_descriptor(
            "the world pauses (its clock too) once its sim time reaches this, and publishes "
            "nothing until it is set later or to 0; 0 = never (a launch sets it to the run's end)",
            "s",
            0.0,
            1e9,
        ),
    )
    node.declare_parameter(
        "cmd_timeout",
        0.5,
        rp.float_descriptor("a robot whose last cmd_vel is older stops (sim time)", "s", 0.0, 1e6),
    )
    node.declare_parameter(
        "clip",
        True,
        rp.bool_descriptor(
            "clip commands to the scenario's max_linear_speed and max_angular_speed"
        ),
    )
    node.declare_parameter(
        "gui", False, rp.bool_descriptor("open the pybullet GUI (read at start)", read_only=True)
    )
    declare_ir_parameters(node, ir_rate)
    reason = rp.choice_error("mode", node.get_parameter("mode").value, names.MODES)
    if reason is not None:
        raise ParameterError(reason)

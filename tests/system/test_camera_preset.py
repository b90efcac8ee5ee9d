"""The overhead camera node's realism options (sim_bridge.camera_node with
sim_bridge.camera_effects): the ``realistic`` preset, a parameter over it, a preset it does
not know. A node in the test's own ROS domain; the effects themselves:
tests/unit/test_camera_effects.py."""

from __future__ import annotations

import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter

from aes_ros import scenario
from aes_ros.params import ParameterError
from aes_ros.ros.launch import LaunchConfig
from aes_ros.ros.launch.commands import tracking_commands
from sim_bridge import camera_effects as fx
from sim_bridge.camera_node import ArenaCameraNode


def test_the_camera_node_takes_the_preset_and_an_override(ros_env, tmp_path) -> None:
    """``preset:=realistic`` sets the effects' defaults; a parameter given overrides one;
    frames differ from the plain render; a preset it does not know is named."""
    config = LaunchConfig(scenario.load("combined"), tracking="camera", camera_preset="realistic")
    camera_cmd = tracking_commands(config, tmp_path / "arena.yaml")[0]
    assert "preset:=realistic" in camera_cmd.argv

    context = rclpy.Context()
    rclpy.init(args=[], context=context)
    try:
        small = [Parameter("width", value=320), Parameter("height", value=240)]
        node = ArenaCameraNode(
            context=context,
            parameter_overrides=[
                *small,
                Parameter("preset", value="realistic"),
                Parameter("read_noise", value=20.0),
            ],
        )
        assert node.effects == fx.Effects(**{**vars(fx.REALISTIC), "read_noise": 20.0})
        xy, yaw = np.array([[0.1, 0.0]]), np.zeros(1)
        node.last_pose = (0, xy - [0.002, 0.0], yaw)
        frame = node.expose(20_000_000, xy, yaw)
        plain = node.renderer.render(xy, yaw)
        assert frame.shape == plain.shape and frame.dtype == np.uint8
        assert frame[0, 0] < plain[0, 0] - 20  # a dark corner (vignetting)
        node.destroy_node()
        with pytest.raises(ParameterError, match="preset"):
            ArenaCameraNode(context=context, parameter_overrides=[Parameter("preset", value="x")])
    finally:
        rclpy.try_shutdown(context=context)

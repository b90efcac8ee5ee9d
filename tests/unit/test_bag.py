"""The MCAP bag's message schemas (no DDS: the bags themselves are written by the
system tests, tests/system/test_recording.py)."""

from __future__ import annotations

from aes_ros.ros.bag import message_definition


def test_bag_schemas_are_complete_ros2msg_definitions() -> None:
    """A schema holds the type's .msg text and every type it uses (rosbag2 layout)."""
    text = message_definition("geometry_msgs/msg/PoseArray")
    assert text.startswith("# An array of poses")
    for dep in ("std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/Pose",
                "geometry_msgs/Point", "geometry_msgs/Quaternion"):  # fmt: skip
        assert f"MSG: {dep}\n" in text
        assert text.count(f"MSG: {dep}\n") == 1

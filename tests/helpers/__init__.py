"""Helpers shared by the tests (importable as ``helpers`` thanks to ``pythonpath =
["tests"]`` in pyproject.toml).

- :mod:`helpers.ros_env`: a ROS domain of one's own, the test's processes
  (:class:`~helpers.ros_env.Processes` over the launcher's ProcessSet), waiting,
  orphan checks;
- :mod:`helpers.probe`: the one rclpy node of the system tests;
- :mod:`helpers.messages`: messages built by the tests;
- :mod:`helpers.robot`: the robot node as the node tests start it, and the command
  it must publish;
- :mod:`helpers.netns` and :mod:`helpers.stranger`: scripts (also run as
  ``python <path>``) for the multi-host and isolation tests.
"""

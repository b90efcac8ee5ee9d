"""``aes-swarm launch``: the whole ROS system as separate processes.

- :mod:`~aes_ros.ros.launch.plan`: the configuration, the parameter files and
  every process's command line (pure);
- :mod:`~aes_ros.ros.launch.processes`: process groups, logs, clean stops;
- :mod:`~aes_ros.ros.launch.monitor`: the launcher's rclpy node (poses, services);
- :mod:`~aes_ros.ros.launch.launcher`: the orchestration (:func:`launch`).
"""

from aes_ros.ros.launch.launcher import Launcher, LaunchResult, launch
from aes_ros.ros.launch.plan import LaunchConfig, LaunchError

__all__ = ["LaunchConfig", "LaunchError", "LaunchResult", "Launcher", "launch"]

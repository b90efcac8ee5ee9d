"""``aes-swarm launch``: the whole ROS system as separate processes.

- :mod:`~aes_ros.ros.launch.config`: the configuration and its validation;
- :mod:`~aes_ros.ros.launch.param_files`, :mod:`~aes_ros.ros.launch.commands`: the
  files written before the start and every process's command line (pure);
- :mod:`~aes_ros.ros.launch.processes`: process groups, logs, clean stops;
- :mod:`~aes_ros.ros.launch.monitor`: the launcher's rclpy node (poses, services);
- :mod:`~aes_ros.ros.launch.launcher`: the orchestration, step by step (:class:`Launcher`);
- :mod:`~aes_ros.ros.launch.run`: one whole launch (:func:`launch`).
"""

from aes_ros.ros.launch.config import LaunchConfig
from aes_ros.ros.launch.launcher import Launcher
from aes_ros.ros.launch.run import LaunchResult, launch
from aes_ros.ros.programs import LaunchError

__all__ = ["LaunchConfig", "LaunchError", "LaunchResult", "Launcher", "launch"]

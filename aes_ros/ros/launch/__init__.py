"""``aes-swarm launch``: the whole ROS system as separate processes.

- :mod:`~aes_ros.ros.launch.config`: the configuration and its validation;
- :mod:`~aes_ros.ros.launch.param_files`, :mod:`~aes_ros.ros.launch.commands`: the
  files written before the start and every process's command line (pure);
- :mod:`~aes_ros.ros.launch.processes`: process groups, logs, clean stops;
- :mod:`~aes_ros.ros.launch.monitor`: the launcher's rclpy node (poses, services);
- :mod:`~aes_ros.ros.launch.launcher`: the orchestration, step by step (:class:`Launcher`);
- :mod:`~aes_ros.ros.launch.run`: one whole launch (:func:`launch`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from aes_ros.ros.launch.config import LaunchConfig
    from aes_ros.ros.launch.launcher import Launcher
    from aes_ros.ros.launch.run import LaunchResult, launch
    from aes_ros.ros.programs import LaunchError

__all__ = ["LaunchConfig", "LaunchError", "LaunchResult", "Launcher", "launch"]

#: Where each name of ``__all__`` lives: imported at first use, so that a small module of
#: this package run on its own (``python -m aes_ros.ros.launch.reaper``, started with
#: every launch) does not load the launcher, rclpy and numba first (0.5 s).
_HOMES = {
    "LaunchConfig": "aes_ros.ros.launch.config",
    "LaunchError": "aes_ros.ros.programs",
    "LaunchResult": "aes_ros.ros.launch.run",
    "Launcher": "aes_ros.ros.launch.launcher",
    "launch": "aes_ros.ros.launch.run",
}


def __getattr__(name: str) -> Any:
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_HOMES[name]), name)

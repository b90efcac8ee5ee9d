"""The files a launch writes before it starts anything: the effective scenario, the
robots' parameter file (standard ``node: ros__parameters:`` layout, so it works with
``--params-file`` anywhere), the arena layout of a tracking launch, and the
``-p name:=value`` syntax of the command lines."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from aes_ros.arena_layout import corner_layout, save_layout
from aes_ros.model import GAIN_FIELDS
from aes_ros.ros import interface as names
from aes_ros.ros.launch.config import LaunchConfig
from aes_ros.ros.launch.tracking_arena import tracking_arena
from aes_ros.ros.parameters import LIMIT_NAMES
from aes_ros.scenario import Scenario


def ros_value(value: Any) -> str:
    """A value in ``-p name:=value`` syntax (YAML; floats keep a decimal point)."""
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, float | np.floating):
        return repr(float(value))
    if isinstance(value, list | tuple | np.ndarray):
        return "[" + ",".join(ros_value(v) for v in value) + "]"
    if isinstance(value, str) and value == "":
        return "''"  # rcl cannot parse `name:=` with nothing after it
    return str(value)


def ros_args(params: dict[str, Any], *extra: str) -> list[str]:
    """``--ros-args -p name:=value …`` for ``params``, then ``extra``."""
    out = ["--ros-args"]
    for name, value in params.items():
        out += ["-p", f"{name}:={ros_value(value)}"]
    return out + list(extra)


def _plain(value: Any) -> Any:
    if isinstance(value, tuple | list | np.ndarray):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def work_directory(config: LaunchConfig) -> Path:
    """Where scenario.yaml, robots.yaml and logs/ go (made if need be): ``work_dir``,
    else ``out_dir``, else a new temporary directory."""
    if config.work_dir is not None:
        path = Path(config.work_dir)
    elif config.out_dir is not None:
        path = Path(config.out_dir)
    else:
        path = Path(tempfile.mkdtemp(prefix="aes-launch-"))
    path.mkdir(parents=True, exist_ok=True)
    return path


def write_scenario(scenario: Scenario, path: Path) -> Path:
    """The scenario as a flat YAML file that :func:`aes_ros.scenario.load` reads back."""
    values = {k: _plain(v) for k, v in scenario.values.items()}
    if values.get("formation_file"):
        values["formation_file"] = str(Path(values["formation_file"]).resolve())
    path.write_text(
        "# Effective scenario of this launch (setup, --set overrides, robot count).\n"
        + yaml.safe_dump(values, sort_keys=False)
    )
    return path


def robot_parameters(
    config: LaunchConfig,
    i: int,
    sheet: tuple[np.ndarray, np.ndarray],
    scenario_file: Path | None = None,
) -> dict[str, Any]:
    """The parameters of robot i (docs/design.md#ros-interface) for a stand-alone
    ``aes-robot-node``; ``sheet`` is the (neighbours, rest lengths) table of
    ``config.scenario.sheet()``."""
    sc = config.scenario
    neighbors, rest = sheet
    valid = neighbors[i] >= 0
    params: dict[str, Any] = {
        "use_sim_time": config.sim_time,
        **({"scenario": str(scenario_file), "num_robots": 0} if scenario_file else {}),
        "robot_id": i,
        "neighbors": [int(j) for j in neighbors[i][valid]],
        "rest_lengths": [float(v) for v in rest[i][valid]],
        **{name: float(sc.values[name]) for name in (*GAIN_FIELDS, *LIMIT_NAMES)},
        "neighbor_source": config.neighbor_source,
    }
    if config.clip is not None:
        params["clip"] = bool(config.clip)
    params["seed"] = config.robot_seed_value
    params.update(config.robot_params)
    return params


def write_robot_params(config: LaunchConfig, path: Path, scenario_file: Path) -> Path:
    """One ROS 2 parameter file with a ``/mona_<i>/aes_robot`` section per robot."""
    # The sheet once for all robots: once per robot was quadratic, 1000 robots
    # spent over a minute here before any process started.
    _, neighbors, rest = config.scenario.sheet()
    doc = {
        f"{names.robot_namespace(i)}/{names.ROBOT_NODE}": {
            "ros__parameters": _plain(robot_parameters(config, i, (neighbors, rest), scenario_file))
        }
        for i in range(config.num_robots)
    }
    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return path


def write_layout(config: LaunchConfig, path: Path) -> Path:
    """The arena layout of a tracking launch (reference markers off the corners of
    :func:`tracking_arena`) written to ``path``, for the camera and the tracker."""
    if config.simulated_camera:
        save_layout(corner_layout(tracking_arena(config.scenario)), path)
    return path

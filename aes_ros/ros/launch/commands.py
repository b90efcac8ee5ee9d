"""The command line of every process of a launch, in the order the launcher starts them
(:func:`start_order`; pure: no processes, no rclpy). The launcher
(:mod:`aes_ros.ros.launch.launcher`) starts them; tests and scripts can run the same
command lines elsewhere (tests/system/test_multihost.py runs them in network
namespaces).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any, NamedTuple

from aes_ros.obstacles import format_obstacles
from aes_ros.ros import discovery as dds
from aes_ros.ros import interface as names
from aes_ros.ros.launch.config import LaunchConfig
from aes_ros.ros.launch.layout import resolved_layout, robot_process_count, split_robots
from aes_ros.ros.launch.param_files import ros_args
from aes_ros.ros.launch.tracking_arena import tracking_arena


class ProcessSpec(NamedTuple):
    """One node process: its name (also its log file's) and its command line.

    ``argv[0]`` is a console script name (``aes-sim-bridge``, …) or a path.
    """

    name: str
    argv: list[str]


def bridge_command(config: LaunchConfig, scenario_file: Path) -> ProcessSpec:
    """``aes-sim-bridge`` with the scenario, seed, mode, rate and stepping of ``config``."""
    params = {
        "scenario": str(scenario_file),
        "num_robots": 0,
        "seed": int(config.seed),
        "mode": config.mode,
        "publish_rate": 1.0 / float(config.scenario.dt),
        "real_time_factor": float(config.real_time_factor),
        "lockstep": bool(config.lockstep),
        "gui": bool(config.gui),
    }
    if config.lockstep:
        params["lockstep_timeout"] = float(config.lockstep_timeout)
        # A recording in lockstep is lossless: the bridge waits for the recorder too.
        params["wait_for_recorder"] = config.record is not None
    if config.clip is not None:
        params["clip"] = bool(config.clip)
    params.update(config.bridge_params)
    # Tracked: the exact poses are for evaluation only; /swarm/poses is the tracker's.
    remap = ["-r", f"{names.POSES}:={names.GROUND_TRUTH_POSES}"] if config.simulated_camera else []
    return ProcessSpec(names.SIM_BRIDGE_NODE, ["aes-sim-bridge", *ros_args(params, *remap)])


def supervisor_command(config: LaunchConfig, scenario_file: Path) -> ProcessSpec:
    """``aes-supervisor`` on the scenario, with sim time."""
    params = {
        "scenario": str(scenario_file),
        "num_robots": 0,
        "use_sim_time": config.sim_time,
        **config.supervisor_params,
    }
    return ProcessSpec(names.SUPERVISOR_NODE, ["aes-supervisor", *ros_args(params)])


def robot_commands(
    config: LaunchConfig, scenario_file: Path, robots_file: Path
) -> list[ProcessSpec]:
    """The robot processes of the layout: one ``aes-robot-node`` per robot
    (``per-robot``) or ``aes-robot-host`` processes (``single``: one; ``per-core``:
    one per core, robots split evenly, hosts named ``robot_host_<h>``)."""
    n = config.num_robots
    layout = resolved_layout(config)
    if layout == "per-robot":
        files = ["--params-file", str(robots_file)]
        return [
            ProcessSpec(
                f"robot_{i}",
                ["aes-robot-node", "--ros-args", "-r", f"__ns:={names.robot_namespace(i)}", *files],
            )
            for i in range(n)
        ]
    blocks = split_robots(n, robot_process_count(config))
    out = []
    for h, ids in enumerate(blocks):
        params: dict[str, Any] = {
            "scenario": str(scenario_file),
            "num_robots": 0,
            "use_sim_time": config.sim_time,
            "neighbor_source": config.neighbor_source,
            "seed": config.robot_seed_value,
        }
        if len(blocks) > 1:
            params["robot_ids"] = ids
        if config.clip is not None:
            params["clip"] = bool(config.clip)
        params.update(config.robot_params)
        name = f"{names.ROBOT_HOST_NODE}_{h}"
        extra = ["-r", f"{names.ROBOT_HOST_NODE}:__node:={name}"] if len(blocks) > 1 else []
        out.append(ProcessSpec(name, ["aes-robot-host", *ros_args(params, *extra)]))
    return out


def node_commands(
    config: LaunchConfig, scenario_file: Path, robots_file: Path
) -> list[ProcessSpec]:
    """Every node process in start order: bridge (none in a real arena), supervisor,
    then the robots."""
    return [
        *([bridge_command(config, scenario_file)] if config.world != "none" else []),
        supervisor_command(config, scenario_file),
        *robot_commands(config, scenario_file, robots_file),
    ]


def tracking_commands(config: LaunchConfig, layout_file: Path) -> list[ProcessSpec]:
    """The simulated overhead camera and the tracker of a ``--tracking camera`` launch
    (none otherwise), on sim time; ``layout_file``: the arena's reference markers."""
    if config.tracking == "none":
        return []
    tracker: dict[str, Any] = {"num_robots": config.num_robots, "use_sim_time": config.sim_time}
    if config.world == "none":  # a real camera, calibrated beforehand
        tracker["calibration"] = str(Path(config.calibration).resolve())
        source = ["--source", str(config.camera_source)]
        return [ProcessSpec(names.TRACKER_NODE, ["aes-tracker", *source, *ros_args(tracker)])]
    tracker["layout"] = str(layout_file)
    width, height = config.camera_size
    camera = {
        "arena": list(tracking_arena(config.scenario)),
        "width": int(width),
        "height": int(height),
        "rate": float(config.camera_rate),
        "layout": str(layout_file),
        "seed": int(config.seed),
        "use_sim_time": config.sim_time,
    }
    if config.camera_preset != "none":
        camera["preset"] = config.camera_preset
    if config.scenario.walls:  # the scenario's walls and obstacles in the picture
        camera["walls"] = ",".join(repr(float(v)) for v in config.scenario.walls)
    if config.scenario.obstacles:
        camera["obstacles"] = format_obstacles(config.scenario.obstacles)
    return [
        ProcessSpec(names.CAMERA_NODE, ["aes-arena-camera", *ros_args(camera)]),
        ProcessSpec(names.TRACKER_NODE, ["aes-tracker", *ros_args(tracker)]),
    ]


def _describe_tracking(config: LaunchConfig) -> str:
    if config.world == "none":
        return (
            f", no simulated world: positions from the camera {config.camera_source} "
            f"(calibration {config.calibration}), wall-clock time"
        )
    if config.tracking == "none":
        return ""
    width, height = config.camera_size
    return (
        f", positions from the overhead camera ({width}x{height} px, "
        f"{config.camera_rate:g} Hz) over the arena {list(tracking_arena(config.scenario))} m"
    )


def describe(config: LaunchConfig, hosts: int, discovery: dds.Discovery | None = None) -> str:
    """One line on what a launch runs (``hosts``: its robot processes; ``discovery``:
    how they find each other, None: simple)."""
    found = "simple discovery"
    if discovery is not None and discovery.address is not None:
        found = f"discovery server {discovery.address}"
    return (
        f"{config.num_robots} robots, layout {resolved_layout(config)} ({hosts} robot "
        f"process{'es' if hosts != 1 else ''}), neighbours from {config.neighbor_source}, "
        f"{config.mode} mode{', lockstep' if config.lockstep else ''}, "
        f"real-time factor {config.real_time_factor:g}, on failure {config.on_failure}, "
        f"{found}" + _describe_tracking(config)
    )


def dashboard_command(config: LaunchConfig, scenario_file: Path) -> ProcessSpec:
    """``aes-dashboard`` on 127.0.0.1 at ``config.dashboard``, with sim time; its token
    is not on this command line (the launcher hands it over by environment)."""
    params = {
        "scenario": str(scenario_file),
        "host": "127.0.0.1",
        "port": int(config.dashboard or 0),
        "label": config.label,
        "use_sim_time": config.sim_time,
    }
    return ProcessSpec(names.DASHBOARD_NODE, ["aes-dashboard", *ros_args(params)])


def recorder_command(
    bag: Path,
    num_robots: int,
    python: str,
    images_rate: float = 0.0,
    split: str | None = None,
    keep: int | None = None,
) -> ProcessSpec:
    """The MCAP recorder (:mod:`aes_ros.ros.recorder`) of the recording ``bag`` run by
    ``python``; ``images_rate``: the camera's frames a second it also records (0: none);
    ``split``, ``keep``: its ``--split`` and ``--keep`` (None: one segment, all kept). A
    restarted recorder adds ``--segment`` and ``--after``, the earlier segments
    (:class:`~aes_ros.ros.launch.recovery.RestartCommands`)."""
    argv = [python, "-m", "aes_ros.ros.recorder", str(bag), "--robots", str(num_robots)]
    if images_rate > 0:
        argv += ["--images", repr(float(images_rate))]
    if split is not None:
        argv += ["--split", split]
    if keep is not None:
        argv += ["--keep", str(int(keep))]
    return ProcessSpec("recorder", argv)


def discovery_server_command(discovery: dds.Discovery, python: str) -> ProcessSpec | None:
    """The discovery server a launch starts (:func:`aes_ros.ros.discovery.serve` run by
    ``python``); None when it uses an existing server or simple discovery."""
    if not discovery.starts_server:
        return None
    argv = dds.server_argv(discovery.port, discovery.listen, python)
    return ProcessSpec(dds.SERVER_PROCESS, argv)


class StartOrder(NamedTuple):
    """A launch's processes in the order the launcher starts them (:func:`start_order`).

    discovery_server : the discovery server, before anything else (None: simple
        discovery, or an existing server).
    recorder : the MCAP recorder, first of the nodes (None without ``record``).
    bridge : ``aes-sim-bridge`` (None in a real arena, ``world="none"``).
    tracking : with ``tracking="camera"`` the simulated overhead camera (none in a real
        arena) and the tracker (:func:`tracking_commands`).
    supervisor : ``aes-supervisor``; robots : the robot processes of the layout.
    dashboard : ``aes-dashboard``, last (None without ``dashboard``).
    """

    recorder: ProcessSpec | None
    bridge: ProcessSpec | None
    tracking: list[ProcessSpec]
    supervisor: ProcessSpec
    robots: list[ProcessSpec]
    dashboard: ProcessSpec | None
    discovery_server: ProcessSpec | None = None

    @property
    def first(self) -> list[ProcessSpec]:
        """What starts after the recorder and before the supervisor: the bridge, the camera,
        the tracker; the first of them publishes the poses the launcher waits for (the
        bridge, or a real arena's tracker)."""
        return [self.bridge, *self.tracking] if self.bridge is not None else list(self.tracking)

    @property
    def by_name(self) -> dict[str, ProcessSpec]:
        """Every process by its name."""
        specs = (
            self.discovery_server, *self.first, self.supervisor, *self.robots, self.recorder,
            self.dashboard,
        )  # fmt: skip
        return {spec.name: spec for spec in specs if spec is not None}


def start_order(
    config: LaunchConfig,
    scenario_file: Path,
    robots_file: Path,
    layout_file: Path,
    discovery: dds.Discovery | None = None,
) -> StartOrder:
    """Every process of a launch in start order; ``layout_file``: the arena's reference
    markers (:func:`write_layout`); ``discovery``: how they find each other (None:
    simple discovery)."""
    recorder = dashboard = None
    if config.record is not None:
        bag = Path(config.record).resolve()
        recorder = recorder_command(
            bag,
            config.num_robots,
            sys.executable,
            images_rate=config.record_images,
            split=config.bag_split,
            keep=config.bag_keep,
        )
    if config.dashboard is not None:
        dashboard = dashboard_command(config, scenario_file)
    return StartOrder(
        recorder,
        bridge_command(config, scenario_file) if config.world != "none" else None,
        tracking_commands(config, layout_file),
        supervisor_command(config, scenario_file),
        robot_commands(config, scenario_file, robots_file),
        dashboard,
        discovery_server_command(discovery, sys.executable) if discovery is not None else None,
    )

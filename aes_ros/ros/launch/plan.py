"""What a launch runs, decided before anything starts (pure: no processes, no rclpy).

From a :class:`LaunchConfig` this module makes the effective scenario file, the
robots' parameter file (standard ``node: ros__parameters:`` layout, so it works
with ``--params-file`` anywhere) and the command line of every node process in
the chosen layout (:func:`node_commands`; :func:`executable` finds their programs),
in the order the launcher starts them (:func:`start_order`).
The launcher (:mod:`aes_ros.ros.launch.launcher`) starts them; tests and scripts can
run the same command lines elsewhere (tests/system/test_multihost.py runs them in
network namespaces).
"""

from __future__ import annotations

import math
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml

from aes_ros.model import GAIN_FIELDS
from aes_ros.perception import PerceptionSettings
from aes_ros.ros import discovery as dds
from aes_ros.ros import interface as names
from aes_ros.ros.bag import SPLIT_FORMS, parse_split
from aes_ros.ros.parameters import LIMIT_NAMES
from aes_ros.scenario import Scenario

#: What ``--on-failure`` may ask for (:mod:`aes_ros.ros.launch.supervision`).
ON_FAILURE = ("respawn", "continue", "stop")
#: Where the robots' neighbour positions come from (``--tracking``): the bridge's exact
#: poses, or an overhead camera and the tracker (SPEC §8).
TRACKING = ("none", "camera")
#: The world (``--world``): the pybullet bridge, or none (a real arena's robots).
WORLDS = ("pybullet", "none")
#: Floor [m] around the formation that a tracking launch's arena adds when the
#: scenario gives none, and the smallest arena (the issue's 2.0 × 1.5 m at 1280 × 960).
TRACKING_ROOM = 0.5
TRACKING_MIN_ARENA = (2.0, 1.5)


class LaunchError(RuntimeError):
    """The system did not start, or a process died during the run."""


@dataclass
class LaunchConfig:
    """Everything ``aes-swarm launch`` decides.

    scenario : formation, gains, command and Δt (the bridge's control period).
    duration : run length in sim time [s] after every robot moves; None = the
        scenario's ``duration``; 0 = until SIGINT/SIGTERM (or ``Launcher.request_stop``).
    clip : clip commands to Mona's limits in the robots and the bridge (None:
        the nodes' defaults).
    robot_seed : the robots' noise ``seed`` parameter, combined by each robot with
        its robot_id (None: ``seed``).
    work_dir : where scenario.yaml, robots.yaml and logs/ go (default: out_dir,
        else a temporary directory removed after a successful run).
    on_failure : what to do when a process dies during the run: ``respawn`` it,
        ``continue`` without it, or ``stop`` the run
        (:mod:`aes_ros.ros.launch.supervision`).
    lockstep_timeout : wall seconds after which a silent robot (or recorder) leaves
        the lockstep barrier (:mod:`sim_bridge.lockstep`).
    dashboard : start the browser dashboard (:mod:`dashboard_node`) on this port of
        127.0.0.1 (0: any free port); None: no dashboard.
    tracking : ``camera``: the robots take their neighbours' positions from the
        simulated overhead camera and the tracker, and the bridge's exact poses go to
        ``/sim/ground_truth/poses`` (what the launcher's outputs are made of);
        ``none``: from the bridge. camera_size [px] and camera_rate [Hz] of the camera.
    record_images : with ``record``, also the camera's frames, at most this many a
        second (0: none; a 1280 × 960 frame is 1.2 MB).
    bag_split : with ``record``, go on in the next bag segment (``run_1.mcap``, …)
        once a segment has this size on disk or spans this wall time: ``1GiB``,
        ``500MiB``, ``10min``, ``30s`` (:func:`aes_ros.ros.bag.parse_split`); None: one
        segment (more only if the recorder is restarted).
    bag_keep : with ``bag_split``, keep only the newest K >= 1 segments (None: all).
    world : ``pybullet`` (the bridge), or ``none``: a real arena, no bridge and no
        simulated camera, every node on wall-clock time, the tracker reading
        ``camera_source`` (a device or a video file) with ``calibration`` (a file of
        ``aes-swarm calibrate``); needs ``tracking="camera"``.
    discovery : ``simple`` (Fast DDS's default), ``server`` (the processes are clients
        of a discovery server; :mod:`aes_ros.ros.discovery`) or ``auto`` (a server from
        :data:`~aes_ros.ros.discovery.DISCOVERY_SERVER_FROM` robots, or with
        ``discovery_server`` or ``discovery_port``). discovery_server :
        ``HOST:PORT`` of an existing server to use (e.g. on another host); without it a
        server mode launch starts its own, on ``discovery_port`` (None: a free UDP port).
    overwrite : replace an earlier run's outputs in ``out_dir`` and an earlier recording
        at ``record`` (removed before anything starts); without it a launch where they
        are is refused (:func:`aes_ros.ros.launch.preflight.earlier_run`).
    """

    scenario: Scenario
    label: str = "launch"
    layout: str = "auto"
    neighbor_source: str = "poses"
    mode: str = "kinematic"
    duration: float | None = None
    seed: int = 0
    robot_seed: int | None = None
    record: Path | None = None
    out_dir: Path | None = None
    gui: bool = False
    lockstep: bool = False
    real_time_factor: float = 1.0
    clip: bool | None = None
    cores: int | None = None
    start_timeout: float = 180.0
    stall_timeout: float = 60.0
    stop_timeout: float = 10.0
    work_dir: Path | None = None
    progress_every: float = 5.0
    on_failure: str = "respawn"
    lockstep_timeout: float = 2.0
    dashboard: int | None = None
    tracking: str = "none"
    camera_size: tuple[int, int] = (1280, 960)
    camera_rate: float = 20.0
    world: str = "pybullet"
    record_images: float = 0.0
    bag_split: str | None = None
    bag_keep: int | None = None
    camera_source: str | None = None
    calibration: Path | None = None
    discovery: str = "auto"
    discovery_server: str | None = None
    discovery_port: int | None = None
    overwrite: bool = False
    bridge_params: dict[str, Any] = field(default_factory=dict)
    robot_params: dict[str, Any] = field(default_factory=dict)
    supervisor_params: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        checks = [
            ("layout", self.layout in names.LAYOUTS, _one_of(names.LAYOUTS)),
            (
                "neighbor_source",
                self.neighbor_source in names.NEIGHBOR_SOURCES,
                _one_of(names.NEIGHBOR_SOURCES),
            ),
            ("mode", self.mode in names.MODES, _one_of(names.MODES)),
            ("tracking", self.tracking in TRACKING, _one_of(TRACKING)),
            ("world", self.world in WORLDS, _one_of(WORLDS)),
            (
                "world",
                self.world == "pybullet"
                or (self.tracking == "camera" and self.camera_source and self.calibration),
                "none needs --tracking camera, --camera-source and --calibration",
            ),
            (
                "camera_source",
                self.camera_source is None or self.world == "none",
                "only with --world none (in simulation the camera is simulated)",
            ),
            (
                "lockstep",
                not (self.lockstep and self.tracking != "none"),
                "not with --tracking camera (a camera frame is not a control step)",
            ),
            (
                "tracking",
                not (self.perceived and self.tracking != "none"),
                "not with perception error (perception_*): the model stands in for a camera",
            ),
            (
                "neighbor_source",
                not (self.perceived and self.neighbor_source != "poses"),
                "with perception error (perception_*) the robots read /swarm/poses",
            ),
            ("on_failure", self.on_failure in ON_FAILURE, _one_of(ON_FAILURE)),
            (
                "discovery",
                self.discovery in dds.DISCOVERY_MODES,
                _one_of(dds.DISCOVERY_MODES),
            ),
            (
                "discovery_server",
                self.discovery_server is None or _is_address(self.discovery_server),
                "expected HOST:PORT, e.g. 192.168.1.10:11811",
            ),
            (
                "discovery_server",
                self.discovery_server is None or self.discovery != "simple",
                "simple discovery uses no server",
            ),
            (
                "discovery_port",
                self.discovery_port is None
                or (self.discovery_server is None and 1 <= self.discovery_port <= 65535),
                "a UDP port 1 … 65535 of the server this launch starts (none with an "
                "existing server)",
            ),
            (
                "discovery_port",
                self.discovery_port is None or self.discovery != "simple",
                "simple discovery uses no server",
            ),
            (
                "lockstep_timeout",
                math.isfinite(self.lockstep_timeout) and self.lockstep_timeout > 0,
                "need a number > 0",
            ),
            (
                "duration",
                self.duration is None or (math.isfinite(self.duration) and self.duration >= 0),
                "need a number >= 0",
            ),
            (
                "real_time_factor",
                math.isfinite(self.real_time_factor) and self.real_time_factor >= 0,
                "need a number >= 0",
            ),
            (
                "bag_split",
                self.bag_split is None or _is_split(self.bag_split),
                f"need {SPLIT_FORMS}",
            ),
            ("bag_split", self.bag_split is None or self.record is not None, "only with --record"),
            (
                "bag_keep",
                self.bag_keep is None or (isinstance(self.bag_keep, int) and self.bag_keep >= 1),
                "need an integer >= 1",
            ),
            (
                "bag_keep",
                self.bag_keep is None or self.bag_split is not None,
                "only with --bag-split (else there is one segment)",
            ),
        ]
        for name, ok, hint in checks:
            if not ok:
                raise ValueError(f"{name}: {getattr(self, name)!r} is not allowed; {hint}")
        if self.simulated_camera and not self.scenario.arena:
            # what the camera sees is what the supervisor's arena keeper keeps them in
            arena = list(tracking_arena(self.scenario))
            self.scenario = self.scenario.with_overrides({"arena": arena}, "--tracking")

    @property
    def sim_time(self) -> bool:
        """The nodes run on the bridge's /clock (False in a real arena: wall time)."""
        return self.world != "none"

    @property
    def simulated_camera(self) -> bool:
        """The bridge's world seen by the simulated camera, the robots on the tracker."""
        return self.tracking != "none" and self.world != "none"

    @property
    def perceived(self) -> bool:
        """The robots see the world through the perception model (the scenario's
        ``perception_*``; the bridge applies it to /swarm/poses)."""
        return PerceptionSettings.from_mapping(self.scenario.values).enabled(self.scenario.dt)

    @property
    def poses_topic(self) -> str:
        """The poses the launcher samples and the outputs are made of: the bridge's exact
        ones (``/sim/ground_truth/poses`` when the robots read the tracker's or perceived
        ones), or in a real arena the tracker's (``/swarm/poses``)."""
        if self.simulated_camera or (self.world != "none" and self.perceived):
            return names.GROUND_TRUTH_POSES
        return names.POSES

    @property
    def num_robots(self) -> int:
        return len(self.scenario.nominal_positions())

    @property
    def run_time(self) -> float:
        return float(self.scenario.duration if self.duration is None else self.duration)

    @property
    def robot_seed_value(self) -> int:
        """The robots' ``seed`` parameter (each robot combines it with its robot_id)."""
        return int(self.seed if self.robot_seed is None else self.robot_seed)


def _is_split(text: str) -> bool:
    try:
        parse_split(text)
    except ValueError:
        return False
    return True


def _one_of(choices: tuple[str, ...]) -> str:
    return f"allowed: {', '.join(choices)}"


def _is_address(text: str) -> bool:
    try:
        dds.parse_address(text)
    except ValueError:
        return False
    return True


def resolved_discovery(config: LaunchConfig) -> str:
    """``simple`` or ``server``: what the launch's ``discovery`` means
    (:func:`aes_ros.ros.discovery.resolved_mode`; a given port means a server too)."""
    given = config.discovery_server or config.discovery_port is not None
    mode = "server" if config.discovery == "auto" and given else config.discovery
    return dds.resolved_mode(mode, config.num_robots, config.discovery_server)


class ProcessSpec(NamedTuple):
    """One node process: its name (also its log file's) and its command line.

    ``argv[0]`` is a console script name (``aes-sim-bridge``, …) or a path.
    """

    name: str
    argv: list[str]


def executable(name: str) -> str:
    """A console script of this environment (next to the interpreter), else from PATH;
    a path is returned as it is."""
    if os.sep in name:
        return name
    local = Path(sys.executable).parent / name
    if local.exists():
        return str(local)
    found = shutil.which(name)
    if found is None:
        raise LaunchError(f"{name}: console script not found (is aes-swarm installed?)")
    return found


# ----------------------------------------------------------------------------- values


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


# ----------------------------------------------------------------------------- files


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
    """SPEC §7 parameters of robot i for a stand-alone ``aes-robot-node``; ``sheet`` is
    the (neighbours, rest lengths) table of ``config.scenario.sheet()``."""
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


# ----------------------------------------------------------------------------- commands


def split_robots(n: int, parts: int) -> list[list[int]]:
    """Robot ids 0..n-1 in ``parts`` contiguous, nearly equal blocks (no empty block)."""
    parts = max(1, min(parts, n))
    return [list(map(int, block)) for block in np.array_split(np.arange(n), parts)]


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


#: ``auto`` runs all robots in one host process up to this many robot-steps per second
#: (robots × control rate), and beyond it too on a machine of two cores or fewer.
AUTO_SINGLE_STEPS = 20000.0


def resolved_layout(config: LaunchConfig) -> str:
    """The layout ``auto`` stands for (:func:`auto_layout`); any other layout as it is."""
    if config.layout != "auto":
        return config.layout
    return auto_layout(config.num_robots, config.scenario.dt, config.cores)


def robot_process_count(config: LaunchConfig) -> int:
    """How many processes run the robots (:func:`robot_commands`)."""
    layout, n = resolved_layout(config), config.num_robots
    if layout == "per-robot":
        return n
    return 1 if layout == "single" else min(n, config.cores or os.cpu_count() or 1)


def auto_layout(num_robots: int, dt: float, cores: int | None = None) -> str:
    """``single`` or ``per-core``: what ``auto`` means for ``num_robots`` robots at a
    control period of ``dt`` [s] on ``cores`` cores (None: this machine's)
    (``scripts/start_swarm.sh`` uses it for its default host count too).

    ``single`` up to AUTO_SINGLE_STEPS robot-steps per second, and always with two
    cores or fewer; ``per-core`` above it on a bigger machine. Why: every extra robot
    process reads every swarm message, runs its own executor, and must discover the
    other processes' robots endpoint by endpoint. Two cores, same code, same hour
    (bench/bench_ros.py, docs/performance.md), one host against two, answered rate
    and CPU per robot-step: 400 robots at 50 Hz 49.9 Hz / 64 µs against 44.7 Hz /
    100 µs; 1000 at 20 Hz 19.8 Hz / 72 µs against 12.3-12.9 Hz / 151-158 µs, and every
    robot moving after 32 s against 62-80 s; 1000 at 50 Hz, more than either carries,
    13.0 against 11.9 Hz. One host's Python runs on one core, which is about 20000
    robot-steps per second here (400 at 50 Hz, 1000 at 20 Hz): beyond that, more cores
    than two give the other hosts cores of their own (not measured here).
    """
    steps = num_robots / dt
    cores = os.cpu_count() if cores is None else cores
    return "single" if steps <= AUTO_SINGLE_STEPS or (cores or 1) <= 2 else "per-core"


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


def tracking_arena(scenario: Scenario) -> tuple[float, float, float, float]:
    """The arena a tracking launch's camera sees, ``(x_min, x_max, y_min, y_max)`` [m]:
    the scenario's ``arena`` (which the supervisor's arena keeper also keeps the swarm
    in; a tracking LaunchConfig sets it to this when the scenario has none), else the
    initial formation with :data:`TRACKING_ROOM` around it, at least
    :data:`TRACKING_MIN_ARENA` and 4:3 like the camera's picture."""
    if scenario.arena:
        return tuple(float(v) for v in scenario.arena)  # type: ignore[return-value]
    xy = scenario.nominal_positions()
    (x0, y0), (x1, y1) = xy.min(axis=0), xy.max(axis=0)
    w = max(x1 - x0 + 2 * TRACKING_ROOM, TRACKING_MIN_ARENA[0])
    h = max(y1 - y0 + 2 * TRACKING_ROOM, TRACKING_MIN_ARENA[1])
    w, h = max(w, h * 4 / 3), max(h, w * 3 / 4)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    return tuple(round(float(v), 3) for v in (cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2))


def write_layout(config: LaunchConfig, path: Path) -> Path:
    """The arena layout of a tracking launch (reference markers off the corners of
    :func:`tracking_arena`) written to ``path``, for the camera and the tracker."""
    if config.simulated_camera:
        from tracker_node.calibration import corner_layout, save_layout

        save_layout(corner_layout(tracking_arena(config.scenario)), path)
    return path


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

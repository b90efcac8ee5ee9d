"""What ``aes-swarm launch`` is asked to run (:class:`LaunchConfig`), validated field by
field: a value that is not allowed raises ValueError naming the field and what is."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aes_ros.perception import PerceptionSettings
from aes_ros.ros import discovery as dds
from aes_ros.ros import interface as names
from aes_ros.ros.bag import SPLIT_FORMS, parse_split
from aes_ros.ros.launch.tracking_arena import tracking_arena
from aes_ros.scenario import Scenario

#: What ``--on-failure`` may ask for (:mod:`aes_ros.ros.launch.supervision`).
ON_FAILURE = ("respawn", "continue", "stop")
#: Where the robots' neighbour positions come from (``--tracking``): the bridge's exact
#: poses, or an overhead camera and the tracker (docs/design.md#tracking).
TRACKING = ("none", "camera")
#: The world (``--world``): the pybullet bridge, or none (a real arena's robots).
WORLDS = ("pybullet", "none")
#: ``--firmware``: none (the wheels follow ``cmd_vel``), or sil: the real firmware on
#: simulated MCUs (:mod:`aes_ros.ros.launch.firmware`).
FIRMWARES = ("none", "sil")


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
        ``none``: from the bridge. camera_size [px] and camera_rate [Hz] of the camera,
        camera_preset its effects (:data:`sim_bridge.camera_node.PRESETS`).
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
    firmware : ``sil``: each robot's wheels driven by the real firmware on a simulated
        MCU through ``aes-mona-driver`` (:mod:`aes_ros.ros.launch.firmware`; needs
        ``make -C firmware``, the bridge, real time, no lockstep); ``none``: from
        ``cmd_vel``.
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
    camera_preset: str = "none"
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
    firmware: str = "none"

    def _firmware_checks(self) -> list[tuple[str, bool, str]]:
        if self.firmware != "sil":
            return [("firmware", self.firmware in FIRMWARES, _one_of(FIRMWARES))]
        from aes_ros.ros.launch import firmware  # it imports this module

        missing = firmware.missing_build()
        return [
            (
                "firmware",
                self.world != "none",
                "not with --world none (real robots have real firmware)",
            ),
            ("firmware", missing is None, missing or ""),
            ("firmware", not self.lockstep, "not with --lockstep (an MCU runs on the wall clock)"),
            (
                "firmware",
                self.real_time_factor == 1.0,
                "only at --real-time-factor 1 (an MCU runs on the wall clock)",
            ),
            (
                "firmware",
                self.num_robots <= firmware.MAX_ROBOTS,
                f"at most {firmware.MAX_ROBOTS} robots",
            ),
        ]

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
        checks += self._firmware_checks()
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

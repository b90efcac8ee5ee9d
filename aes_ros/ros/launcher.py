"""Start the whole ROS system as separate processes, run it, stop it cleanly.

What ``aes-swarm launch`` does (SPEC §7 "Processes and performance design"):

1. writes the effective scenario (setup or file, ``--set`` overrides, robot
   count) to ``<work>/scenario.yaml`` and the per-robot parameters to
   ``<work>/robots.yaml`` (standard ``node: ros__parameters:`` layout), so every
   process reads the same values;
2. starts, each in its own process group with the caller's ROS environment:
   the recorder (with ``record``), ``aes-sim-bridge``, ``aes-supervisor`` and
   the robots in the chosen layout — ``single`` (one ``aes-robot-host``),
   ``per-core`` (one host per core, robots split evenly; the default) or
   ``per-robot`` (one ``aes-robot-node`` per robot, as on real Monas); all at
   once, except in lockstep or when recording, where the robots start only
   after the bridge's first poses have reached the launcher, the supervisor
   and the recorder, and with a recording the bridge is paused until the
   recorder has found every robot's and the supervisor's publishers;
3. watches ``/swarm/poses`` until every robot has moved, then runs for
   ``duration`` seconds of sim time (``/clock``; 0 = until SIGINT/SIGTERM);
4. stops every process (SIGINT to its group, SIGKILL after ``stop_timeout``),
   the recorder last so that the bag is complete and closed, and cleans Fast
   DDS shared memory left by killed processes;
5. writes ``trajectory.npz``, ``metrics.csv``, ``snapshots.png`` and
   ``metrics.png`` with :func:`aes_ros.report.write_run_outputs` from the poses
   sampled over the run (times are sim times [s]; the first sample is the last
   one before every robot had moved).

SIGINT or SIGTERM to the launcher ends the run early the same way (processes
stopped, bag closed, outputs written from what was sampled).

Example::

    from aes_ros import scenario
    from aes_ros.ros.launcher import LaunchConfig, launch
    result = launch(LaunchConfig(scenario.load("linear").with_robots(16), duration=20.0,
                                 lockstep=True, real_time_factor=0.0, out_dir=Path("out")))
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from aes_ros import metrics
from aes_ros.scenario import Scenario

LAYOUTS = ("single", "per-core", "per-robot")
NEIGHBOR_SOURCES = ("poses", "odom")
MODES = ("kinematic", "dynamic")
#: A robot has moved once its position changed by more than this [m] or its heading [rad].
MOVE_EPS = 1e-6
#: Tolerance on sim-time comparisons [s].
TIME_EPS = 1e-6


class LaunchError(RuntimeError):
    """The system did not start or died during the run."""


@dataclass
class LaunchConfig:
    """Everything ``aes-swarm launch`` decides.

    scenario : formation, gains, command and Δt (the bridge's control period).
    duration : run length in sim time [s] after every robot moves; None = the
        scenario's ``duration``; 0 = until SIGINT/SIGTERM (or :meth:`Launcher.request_stop`).
    clip : clip commands to Mona's limits in the robots and the bridge (None:
        the nodes' defaults).
    robot_seed : the robots' noise ``seed`` parameter, combined by each robot with
        its robot_id (None: ``seed``).
    work_dir : where scenario.yaml, robots.yaml and logs/ go (default: out_dir,
        else a temporary directory removed after a successful run).
    """

    scenario: Scenario
    label: str = "launch"
    layout: str = "per-core"
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
    bridge_params: dict[str, Any] = field(default_factory=dict)
    robot_params: dict[str, Any] = field(default_factory=dict)
    supervisor_params: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        checks = [
            ("layout", self.layout in LAYOUTS, f"allowed: {', '.join(LAYOUTS)}"),
            (
                "neighbor_source",
                self.neighbor_source in NEIGHBOR_SOURCES,
                f"allowed: {', '.join(NEIGHBOR_SOURCES)}",
            ),
            ("mode", self.mode in MODES, f"allowed: {', '.join(MODES)}"),
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
        ]
        for name, ok, hint in checks:
            if not ok:
                raise ValueError(f"{name}: {getattr(self, name)!r} is not allowed; {hint}")

    @property
    def num_robots(self) -> int:
        return len(self.scenario.nominal_positions())

    @property
    def run_time(self) -> float:
        return float(self.scenario.duration if self.duration is None else self.duration)


@dataclass
class LaunchResult:
    """What a run produced.

    times : (T,) sim time [s]; positions : (T, N, 2) [m]; headings : (T, N) [rad].
    t_go : sim time [s] of the first sample (the last one before every robot moved).
    stopped_by : None when the run lasted ``duration``, else the signal's name.
    summary : the one-line summary of write_run_outputs ("" when nothing was written).
    killed : processes that had to be SIGKILLed at the end.
    exit_codes : every process's exit code (0 = clean shutdown).
    """

    times: np.ndarray
    positions: np.ndarray
    headings: np.ndarray
    t_go: float
    wall_time: float
    stopped_by: str | None = None
    summary: str = ""
    killed: list[str] = field(default_factory=list)
    exit_codes: dict[str, int] = field(default_factory=dict)


# ----------------------------------------------------------------------------- processes


def executable(name: str) -> str:
    """A console script of this environment (next to the interpreter), else from PATH."""
    local = Path(sys.executable).parent / name
    if local.exists():
        return str(local)
    found = shutil.which(name)
    if found is None:
        raise LaunchError(f"{name}: console script not found (is aes-swarm installed?)")
    return found


@dataclass
class Child:
    name: str
    cmd: list[str]
    proc: subprocess.Popen
    log: Path

    def tail(self, chars: int = 2000) -> str:
        try:
            text = self.log.read_text(errors="replace")
        except OSError:
            return ""
        return text[-chars:]


class ProcessSet:
    """Child processes, each in its own session/process group, logging to files."""

    def __init__(self, log_dir: Path, env: dict[str, str] | None = None) -> None:
        self.log_dir = log_dir
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = {**os.environ, **(env or {}), "PYTHONUNBUFFERED": "1"}
        self.children: list[Child] = []

    def start(self, name: str, cmd: Sequence[str]) -> Child:
        log = self.log_dir / f"{name}.log"
        with open(log, "w") as fh:
            proc = subprocess.Popen(
                list(cmd),
                env=self.env,
                stdin=subprocess.DEVNULL,
                stdout=fh,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                preexec_fn=_die_with_parent,
            )
        child = Child(name, list(cmd), proc, log)
        self.children.append(child)
        return child

    def dead(self) -> list[Child]:
        return [c for c in self.children if c.proc.poll() is not None]

    def stop(self, children: Sequence[Child], timeout: float) -> list[str]:
        """SIGINT each child's process group, SIGKILL the groups still alive after
        ``timeout`` s. Returns the names of the killed ones."""
        for c in children:
            if c.proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(c.proc.pid, signal.SIGINT)
        deadline = time.monotonic() + timeout
        killed = []
        for c in children:
            try:
                c.proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                killed.append(c.name)
            # Anything left in the group (a grandchild, or the child itself) goes now.
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(c.proc.pid, signal.SIGKILL)
            c.proc.wait()
        return killed

    def stop_all(self, timeout: float, last: Sequence[Child] = ()) -> list[str]:
        """Stop every child; those in ``last`` only after all others have exited."""
        first = [c for c in self.children if c not in last]
        killed = self.stop(first, timeout) + self.stop(list(last), timeout)
        clean_shared_memory()
        return killed


def _die_with_parent() -> None:
    """In the child before exec: get SIGTERM if the launcher dies (Linux), so that
    even a SIGKILLed launcher leaves no orphans behind."""
    with contextlib.suppress(Exception):
        import ctypes

        PR_SET_PDEATHSIG = 1
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


def clean_shared_memory() -> None:
    """``fastdds shm clean``: remove Fast DDS segments whose processes are gone."""
    try:
        tool = executable("fastdds")
    except LaunchError:
        return
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        subprocess.run([tool, "shm", "clean"], capture_output=True, timeout=30, check=False)


# ----------------------------------------------------------------------------- parameters


def ros_value(value: Any) -> str:
    """A value in ``-p name:=value`` syntax (YAML; floats keep a decimal point)."""
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, float | np.floating):
        return repr(float(value))
    if isinstance(value, list | tuple | np.ndarray):
        return "[" + ",".join(ros_value(v) for v in value) + "]"
    return str(value)


def ros_args(params: dict[str, Any], *extra: str) -> list[str]:
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


GAIN_NAMES = ("alpha", "beta", "k", "v0", "w_l", "w_r", "d_r", "d_theta")


def robot_parameters(
    config: LaunchConfig, i: int, scenario_file: Path | None = None
) -> dict[str, Any]:
    """SPEC §7 parameters of robot i for a stand-alone ``aes-robot-node``."""
    sc = config.scenario
    _, neighbors, rest = sc.sheet()
    valid = neighbors[i] >= 0
    params: dict[str, Any] = {
        "use_sim_time": True,
        **({"scenario": str(scenario_file), "num_robots": 0} if scenario_file else {}),
        "robot_id": i,
        "neighbors": [int(j) for j in neighbors[i][valid]],
        "rest_lengths": [float(v) for v in rest[i][valid]],
        **{name: float(sc.values[name]) for name in GAIN_NAMES},
        "max_linear_speed": float(sc.max_linear_speed),
        "max_angular_speed": float(sc.max_angular_speed),
        "neighbor_source": config.neighbor_source,
    }
    if config.clip is not None:
        params["clip"] = bool(config.clip)
    params["seed"] = robot_seed(config)
    params.update(config.robot_params)
    return params


def robot_seed(config: LaunchConfig) -> int:
    """The robots' ``seed`` parameter (each robot combines it with its robot_id)."""
    return int(config.seed if config.robot_seed is None else config.robot_seed)


def write_robot_params(config: LaunchConfig, path: Path, scenario_file: Path) -> Path:
    """One ROS 2 parameter file with a ``/mona_<i>/aes_robot`` section per robot."""
    doc = {
        f"/mona_{i}/aes_robot": {
            "ros__parameters": _plain(robot_parameters(config, i, scenario_file))
        }
        for i in range(config.num_robots)
    }
    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return path


def split_robots(n: int, parts: int) -> list[list[int]]:
    """Robot ids 0..n-1 in ``parts`` contiguous, nearly equal blocks (no empty block)."""
    parts = max(1, min(parts, n))
    return [list(map(int, block)) for block in np.array_split(np.arange(n), parts)]


def commands(config: LaunchConfig, scenario_file: Path, robots_file: Path) -> list[tuple]:
    """(name, argv) of every node process, in start order."""
    n = config.num_robots
    common = {"scenario": str(scenario_file), "num_robots": 0}
    bridge = {
        **common,
        "seed": int(config.seed),
        "mode": config.mode,
        "publish_rate": 1.0 / float(config.scenario.dt),
        "real_time_factor": float(config.real_time_factor),
        "lockstep": bool(config.lockstep),
        "gui": bool(config.gui),
    }
    if config.clip is not None:
        bridge["clip"] = bool(config.clip)
    bridge.update(config.bridge_params)
    supervisor = {**common, "use_sim_time": True, **config.supervisor_params}
    out = [
        ("sim_bridge", [executable("aes-sim-bridge"), *ros_args(bridge)]),
        ("supervisor", [executable("aes-supervisor"), *ros_args(supervisor)]),
    ]
    if config.layout == "per-robot":
        for i in range(n):
            argv = [
                executable("aes-robot-node"),
                "--ros-args",
                "-r",
                f"__ns:=/mona_{i}",
                "--params-file",
                str(robots_file),
            ]
            out.append((f"robot_{i}", argv))
        return out
    parts = 1 if config.layout == "single" else (config.cores or os.cpu_count() or 1)
    blocks = split_robots(n, parts)
    for h, ids in enumerate(blocks):
        host = {
            **common,
            "use_sim_time": True,
            "neighbor_source": config.neighbor_source,
            "seed": robot_seed(config),
        }
        if len(blocks) > 1:
            host["robot_ids"] = ids
        if config.clip is not None:
            host["clip"] = bool(config.clip)
        host.update(config.robot_params)
        extra = ["-r", f"robot_host:__node:=robot_host_{h}"] if len(blocks) > 1 else []
        out.append((f"robot_host_{h}", [executable("aes-robot-host"), *ros_args(host, *extra)]))
    return out


# ----------------------------------------------------------------------------- monitor


class _Monitor:
    """An rclpy node in its own context sampling ``/swarm/poses`` and ``/clock``."""

    def __init__(self, n_robots: int) -> None:
        import rclpy
        from geometry_msgs.msg import PoseArray
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rclpy.signals import SignalHandlerOptions
        from rosgraph_msgs.msg import Clock

        self.n = n_robots
        self.context = rclpy.Context()
        # The launcher handles SIGINT/SIGTERM itself (it must stop the children first).
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("aes_launcher", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        stream = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.node.create_subscription(PoseArray, "/swarm/poses", self.on_poses, stream, raw=True)
        self.node.create_subscription(
            Clock,
            "/clock",
            self.on_clock,
            QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT),
        )
        self.times: list[float] = []
        self.positions: list[np.ndarray] = []
        self.headings: list[np.ndarray] = []
        self.clock = 0.0
        self.bad = 0

    def on_poses(self, data: bytes) -> None:
        from aes_ros.ros.cdr import decode_pose_array
        from aes_ros.ros.conversions import BadMessageError

        try:
            sec, nanosec, pos, head = decode_pose_array(data, self.n)
        except BadMessageError:
            self.bad += 1
            return
        t = sec + nanosec * 1e-9
        if self.times and t <= self.times[-1] + TIME_EPS * 1e-3:
            if t < self.times[-1] - TIME_EPS:  # the bridge was reset: start over
                self.times.clear()
                self.positions.clear()
                self.headings.clear()
            else:
                return
        self.times.append(t)
        self.positions.append(pos)
        self.headings.append(head)

    def on_clock(self, msg) -> None:
        self.clock = msg.clock.sec + msg.clock.nanosec * 1e-9

    def spin_once(self, timeout: float) -> None:
        self.executor.spin_once(timeout_sec=timeout)

    def pause_bridge(self, paused: bool, timeout: float) -> None:
        """Call the bridge's ``/sim/pause``; raises LaunchError if it does not answer."""
        from std_srvs.srv import SetBool

        client = self.node.create_client(SetBool, "/sim/pause")
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise LaunchError(f"sim_bridge offers no /sim/pause within {timeout:.0f} s")
            future = client.call_async(SetBool.Request(data=paused))
            deadline = time.monotonic() + timeout
            while not future.done():
                if time.monotonic() > deadline:
                    raise LaunchError(f"/sim/pause did not answer within {timeout:.0f} s")
                self.spin_once(0.05)
        finally:
            self.node.destroy_client(client)

    def close(self) -> None:
        import rclpy

        with contextlib.suppress(Exception):
            self.executor.shutdown()
            self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


# ----------------------------------------------------------------------------- launcher


class Launcher:
    """Runs one launch: :meth:`start`, :meth:`wait_until_moving`, :meth:`run`, :meth:`stop`.

    :func:`launch` does all four; the steps are separate so that a test or a
    script can act on the running system in between (e.g. call services while
    :meth:`run` is not active, or run with ``duration=0`` and :meth:`request_stop`).
    """

    def __init__(self, config: LaunchConfig, say: Callable[[str], None] = print) -> None:
        self.config = config
        self.say = say
        self._own_work_dir = config.work_dir is None and config.out_dir is None
        if config.work_dir is not None:
            self.work_dir = Path(config.work_dir)
        elif config.out_dir is not None:
            self.work_dir = Path(config.out_dir)
        else:
            self.work_dir = Path(tempfile.mkdtemp(prefix="aes-launch-"))
        self.work_dir.mkdir(parents=True, exist_ok=True)
        self.procs = ProcessSet(self.work_dir / "logs")
        self.recorder: Child | None = None
        self.monitor: _Monitor | None = None
        self.stop_reason: str | None = None
        self.t_go: float | None = None
        self.go_index = 0
        self._wall_start = time.monotonic()
        self._stopped = False
        self.killed: list[str] = []
        self.exit_codes: dict[str, int] = {}

    # -- signals -------------------------------------------------------------------------

    def request_stop(self, reason: str = "stop requested") -> None:
        """End :meth:`wait_until_moving` / :meth:`run` at the next poll."""
        self.stop_reason = reason

    @contextlib.contextmanager
    def signals_stop(self):
        """While active, SIGINT/SIGTERM end the run instead of killing the launcher."""
        if threading_is_main():
            handler = lambda signum, _frame: self.request_stop(signal.Signals(signum).name)  # noqa: E731
            old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
            try:
                yield
            finally:
                for s, h in old.items():
                    signal.signal(s, h)
        else:
            yield

    # -- steps ---------------------------------------------------------------------------

    def start(self) -> None:
        cfg = self.config
        n = cfg.num_robots
        scenario_file = write_scenario(cfg.scenario, self.work_dir / "scenario.yaml")
        robots_file = write_robot_params(cfg, self.work_dir / "robots.yaml", scenario_file)
        self.monitor = _Monitor(n)
        if cfg.record is not None:
            record = Path(cfg.record).resolve()
            self.recorder = self.procs.start(
                "recorder",
                [sys.executable, "-m", "aes_ros.ros.recorder", str(record), "--robots", str(n)],
            )
            self._wait_log(self.recorder, "recording to", 30.0)
        nodes = commands(cfg, scenario_file, robots_file)
        bridge = self.procs.start(*nodes[0])
        if cfg.lockstep or self.recorder is not None:
            # The bridge and the supervisor first: the robots start only once the
            # launcher, the supervisor (and the recorder) receive /swarm/poses, so
            # that no step of a deterministic run and no message of a recording is
            # missed (at full speed a run can be over before a late reader matches).
            from supervisor_node.node import RECEIVING_POSES

            supervisor = self.procs.start(*nodes[1])
            self._wait_first_poses(bridge)
            self._wait_log(supervisor, RECEIVING_POSES, cfg.start_timeout)
            if self.recorder is not None:
                self._wait_log(self.recorder, "receiving /swarm/poses", cfg.start_timeout)
                # Paused until the recorder has found every robot's and the
                # supervisor's publishers: on a loaded machine discovery can take
                # seconds, and what a writer sends before the reader knows it is
                # lost for the bag (only its last few are kept for late readers).
                self.monitor.pause_bridge(True, cfg.start_timeout)
            for name, argv in nodes[2:]:
                self.procs.start(name, argv)
            if self.recorder is not None:
                from aes_ros.ros.recorder import MATCHED_ALL

                self._wait_log(self.recorder, MATCHED_ALL, cfg.start_timeout)
                self.monitor.pause_bridge(False, cfg.start_timeout)
        else:
            # Everything at once: each process spends ~1 s starting Python and
            # building its nodes, and discovery overlaps; robots move at their first
            # poses, and the run starts at the last sample before all of them moved.
            for name, argv in nodes[1:]:
                self.procs.start(name, argv)
            self._wait_first_poses(bridge)
        hosts = len(self.procs.children) - 2 - (self.recorder is not None)
        self.say(
            f"launch: {n} robots, layout {cfg.layout} ({hosts} robot process"
            f"{'es' if hosts != 1 else ''}), neighbours from {cfg.neighbor_source}, "
            f"{cfg.mode} mode{', lockstep' if cfg.lockstep else ''}, "
            f"real-time factor {cfg.real_time_factor:g}; logs in {self.procs.log_dir}"
        )

    def _wait_first_poses(self, bridge: Child) -> None:
        deadline = time.monotonic() + self.config.start_timeout
        while not self.monitor.times and self.stop_reason is None:
            self.monitor.spin_once(0.05)
            if bridge.proc.poll() is not None:
                raise LaunchError(
                    f"sim_bridge exited with code {bridge.proc.returncode}:\n{bridge.tail()}"
                )
            if time.monotonic() > deadline:
                raise LaunchError(
                    f"no /swarm/poses from sim_bridge within {self.config.start_timeout:.0f} s"
                )

    def _wait_log(self, child: Child, text: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in child.tail(100_000) or self.stop_reason is not None:
                return
            if child.proc.poll() is not None:
                raise LaunchError(
                    f"{child.name} exited with {child.proc.returncode}:\n{child.tail()}"
                )
            time.sleep(0.05)
        raise LaunchError(f"{child.name} did not start within {timeout:.0f} s")

    def _check_children(self) -> None:
        dead = self.procs.dead()
        if dead:
            c = dead[0]
            raise LaunchError(
                f"{c.name} exited with code {c.proc.returncode} during the run; "
                f"its log ({c.log}) ends:\n{c.tail()}"
            )

    def wait_until_moving(self) -> float:
        """Block until every robot has moved from its first sampled pose.

        Returns the sim time of the last sample before that (the run's start),
        or raises LaunchError after ``start_timeout`` s of wall time.
        """
        mon = self.monitor
        assert mon is not None, "start() first"
        deadline = time.monotonic() + self.config.start_timeout
        checked = 0
        moved = np.zeros(mon.n, dtype=bool)
        last_unmoved = 0
        while self.stop_reason is None:
            mon.spin_once(0.05)
            self._check_children()
            while checked < len(mon.times):
                p0, h0 = mon.positions[0], mon.headings[0]
                dp = np.linalg.norm(mon.positions[checked] - p0, axis=-1)
                dh = np.abs(np.angle(np.exp(1j * (mon.headings[checked] - h0))))
                moved |= (dp > MOVE_EPS) | (dh > MOVE_EPS)
                if not moved.all():
                    last_unmoved = checked
                checked += 1
                if moved.all():
                    self.go_index = last_unmoved
                    self.t_go = mon.times[last_unmoved]
                    self.say(
                        f"launch: all {mon.n} robots moving at sim time "
                        f"{mon.times[checked - 1]:.2f} s "
                        f"(wall {time.monotonic() - self._wall_start:.1f} s)"
                    )
                    return self.t_go
            if time.monotonic() > deadline:
                stuck = np.flatnonzero(~moved).tolist()
                raise LaunchError(
                    f"not every robot moved within {self.config.start_timeout:.0f} s "
                    f"({len(mon.times)} pose samples; still at rest: {stuck[:20]})"
                )
        self.t_go = mon.times[last_unmoved] if mon.times else 0.0
        return self.t_go

    def run(self, duration: float | None = None) -> None:
        """Sample poses until ``duration`` s of sim time after the start (0: until stopped)."""
        mon = self.monitor
        assert mon is not None and self.t_go is not None, "wait_until_moving() first"
        duration = self.config.run_time if duration is None else duration
        t_end = self.t_go + duration if duration > 0 else math.inf
        next_report = self.t_go + self.config.progress_every
        last_count, last_new = len(mon.times), time.monotonic()
        while self.stop_reason is None:
            mon.spin_once(0.05)
            self._check_children()
            if len(mon.times) != last_count:
                last_count, last_new = len(mon.times), time.monotonic()
            elif time.monotonic() - last_new > self.config.stall_timeout:
                raise LaunchError(
                    f"no /swarm/poses for {self.config.stall_timeout:.0f} s "
                    f"(sim time {mon.clock:.2f} s)"
                )
            now = mon.times[-1] if mon.times else 0.0
            if now >= next_report - TIME_EPS and now < t_end - TIME_EPS:
                self._progress(now)
                next_report += self.config.progress_every
            if now >= t_end - TIME_EPS:
                return

    def _progress(self, t: float) -> None:
        mon = self.monitor
        pos, head = mon.positions[-1], mon.headings[-1]
        c = pos.mean(axis=0)
        order = float(metrics.heading_order(head))
        wall = time.monotonic() - self._wall_start
        self.say(
            f"  t = {t:6.1f} s  centroid ({c[0]:+.2f}, {c[1]:+.2f}) m  "
            f"heading order {order:.3f}  [wall {wall:.1f} s]"
        )

    def stop(self) -> list[str]:
        """Stop every process (idempotent); returns the names of SIGKILLed ones."""
        if self._stopped:
            return self.killed
        self._stopped = True
        last = [self.recorder] if self.recorder is not None else []
        self.killed = self.procs.stop_all(self.config.stop_timeout, last=last)
        if self.monitor is not None:
            self.monitor.close()
        if self.recorder is not None:
            lines = self.recorder.tail(300).strip().splitlines()
            self.say(f"launch: {lines[-1] if lines else 'recorder wrote nothing'}")
        self.exit_codes = {c.name: c.proc.returncode for c in self.procs.children}
        unclean = {k: v for k, v in self.exit_codes.items() if v != 0 and k not in self.killed}
        if unclean:
            names = ", ".join(f"{k} ({v})" for k, v in unclean.items())
            self.say(
                f"launch: exit codes other than 0 (-N: ended by signal N before its node "
                f"was up): {names}; logs in {self.procs.log_dir}"
            )
        else:
            self.say(f"launch: all {len(self.exit_codes)} processes stopped cleanly")
        return self.killed

    def samples(self, t_end: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(times (T,), positions (T, N, 2), headings (T, N)) from the run's start to t_end."""
        mon = self.monitor
        times = np.asarray(mon.times[self.go_index :])
        pos = np.asarray(mon.positions[self.go_index :]).reshape(len(times), mon.n, 2)
        head = np.asarray(mon.headings[self.go_index :]).reshape(len(times), mon.n)
        if t_end is not None and len(times):
            keep = times <= t_end + TIME_EPS
            keep[: max(1, int(keep.sum()))] = True
            times, pos, head = times[keep], pos[keep], head[keep]
        return times, pos, head

    def cleanup(self, ok: bool) -> None:
        """Remove the temporary work directory of a successful run without out_dir."""
        if ok and self._own_work_dir:
            shutil.rmtree(self.work_dir, ignore_errors=True)
        elif not ok:
            self.say(f"launch: process logs kept in {self.procs.log_dir}")


def threading_is_main() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def launch(config: LaunchConfig, say: Callable[[str], None] = print) -> LaunchResult:
    """Start, wait until every robot moves, run ``duration`` s of sim time, stop, write outputs.

    Raises LaunchError when the system does not start or a process dies; every
    process is stopped in any case.
    """
    launcher = Launcher(config, say)
    ok = False
    with launcher.signals_stop():
        try:
            launcher.start()
            launcher.wait_until_moving()
            launcher.run()
            ok = True
        finally:
            killed = launcher.stop()
            if killed:
                say(f"launch: had to SIGKILL {', '.join(killed)}")
            launcher.cleanup(ok and not killed and not any(launcher.exit_codes.values()))
    t_end = None if config.run_time == 0 else launcher.t_go + config.run_time
    times, pos, head = launcher.samples(t_end)
    result = LaunchResult(
        times, pos, head, float(launcher.t_go), time.monotonic() - launcher._wall_start,
        stopped_by=launcher.stop_reason, killed=killed, exit_codes=launcher.exit_codes,
    )  # fmt: skip
    if launcher.stop_reason is not None:
        t_last = times[-1] if len(times) else 0.0
        say(f"launch: stopped by {launcher.stop_reason} at sim time {t_last:.2f} s")
    if config.out_dir is not None and len(times) >= 2:
        result.summary = write_outputs(config, result)
    return result


def write_outputs(config: LaunchConfig, result: LaunchResult) -> str:
    from aes_ros.report import write_run_outputs

    return write_run_outputs(
        Path(config.out_dir), result.times, result.positions, result.headings, config.scenario,
        label=config.label,
    )  # fmt: skip

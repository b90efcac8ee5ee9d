"""Start the whole ROS system as separate processes, run it, stop it cleanly.

What ``aes-swarm launch`` does (docs/design.md#processes):

1. writes the effective scenario to ``<work>/scenario.yaml`` and the per-robot
   parameters to ``<work>/robots.yaml`` (:mod:`aes_ros.ros.launch.param_files`), so every
   process reads the same values;
2. starts, each in its own process group with the caller's ROS environment
   (:mod:`aes_ros.ros.launch.processes`), in the order of
   :func:`~aes_ros.ros.launch.commands.start_order`: with a discovery server of its own
   (``discovery``; :mod:`aes_ros.ros.discovery`) that server, whose address every other
   process gets and which ``ros_env.sh`` gives a user's shell; the recorder (with ``record``),
   ``aes-sim-bridge``, with ``--tracking camera`` the overhead camera and the tracker,
   ``aes-supervisor`` and the robots in the chosen layout; all at once, except in
   lockstep or when recording, where the robots start only after the first poses
   have reached the launcher, the supervisor and the recorder, and with a recording
   the bridge is paused until the recorder has found every robot's and the
   supervisor's publishers. With ``--world none`` (a real arena) there is no bridge
   and no simulated camera: the tracker's poses are the ones waited for;
3. watches the poses (:mod:`aes_ros.ros.launch.monitor`; the bridge's exact ones when
   tracked in simulation) until every robot has moved, then runs for ``duration``
   seconds of sim time (0 = until SIGINT/SIGTERM), streaming ``metrics.csv`` and the
   trajectory to ``out_dir`` as it goes (:mod:`aes_ros.run_writer`, flushed every wall
   second) and handling processes that die as ``on_failure`` says
   (:mod:`aes_ros.ros.launch.supervision`; every fault and recovery in ``events.csv``);
4. stops every process (SIGINT to its group, SIGKILL after ``stop_timeout``), the
   recorder last so that the bag is complete and closed, and cleans Fast DDS
   shared memory left by killed processes;
5. completes ``trajectory.h5`` and ``metrics.csv`` and draws ``snapshots.png`` and
   ``metrics.png`` from the disk (:func:`aes_ros.report.finish_run_outputs`, in memory
   bounded whatever the run's length; times are sim times [s], in a real
   arena seconds from the first tracked pose; the first sample is the last one before
   every robot had moved).

Before it starts anything it checks (:mod:`aes_ros.ros.launch.preflight`) that no
earlier run's outputs or recording are where it would write (refused, or with
``overwrite`` removed: :mod:`aes_ros.previous_run`), that the outputs can be written
and have room, and that no other swarm is active in this
ROS domain (not with a discovery server of its own, whose only clients are its
processes). SIGINT or SIGTERM to the launcher ends the run early the same way
(processes stopped, bag closed, outputs written from what was sampled). If the
launcher itself is killed, its children get SIGTERM from the kernel, a reaper
process (:mod:`aes_ros.ros.launch.reaper`) removes Fast DDS's shared memory, and
the outputs on disk hold everything up to the last flush (``aes-swarm report DIR``
writes the rest).
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import threading
import time
from collections.abc import Callable
from pathlib import Path

from aes_ros.previous_run import OVERWRITE, EarlierRunError, remove
from aes_ros.ros import dashboard_token
from aes_ros.ros import discovery as dds
from aes_ros.ros import interface as names
from aes_ros.ros.launch import preflight
from aes_ros.ros.launch.commands import ProcessSpec, describe, start_order
from aes_ros.ros.launch.config import LaunchConfig, resolved_discovery
from aes_ros.ros.launch.events import EventLog
from aes_ros.ros.launch.firmware import start_firmware, with_firmware
from aes_ros.ros.launch.monitor import DISCOVERY_WAIT, TIME_EPS, Monitor
from aes_ros.ros.launch.param_files import (
    work_directory,
    write_layout,
    write_robot_params,
    write_scenario,
)
from aes_ros.ros.launch.processes import (
    Child,
    ProcessSet,
    fastdds_environment,
    images_environment,
)
from aes_ros.ros.launch.reaper import STOPPED, start_reaper
from aes_ros.ros.launch.recovery import Backoff, RestartCommands
from aes_ros.ros.launch.supervision import Supervision
from aes_ros.ros.programs import LaunchError
from aes_ros.ros.qos import OUTPUT_DEPTH
from aes_ros.ros.spin import stop_signals
from aes_ros.run_summary import progress
from aes_ros.run_writer import RunWriter


class Launcher:
    """Runs one launch: :meth:`start`, :meth:`wait_until_moving`, :meth:`run`, :meth:`stop`.

    :func:`launch` does all four; the steps are separate so that a test, a script
    or a benchmark can act on the running system in between (e.g. call services
    with :attr:`monitor` while :meth:`run` is not active, keep it going with
    :meth:`spin_for`, or run with ``duration=0`` and :meth:`request_stop`).
    """

    def __init__(self, config: LaunchConfig, say: Callable[[str], None] = print) -> None:
        self.config = config
        self.say = say
        try:
            earlier = preflight.earlier_run(config)
        except EarlierRunError as exc:
            raise LaunchError(str(exc)) from None
        if earlier:
            gone = ", ".join(str(path) for path in remove(earlier))
            say(f"launch: {OVERWRITE}: removed the earlier run's {gone}")
        self._own_work_dir = config.work_dir is None and config.out_dir is None
        self.work_dir = work_directory(config)
        logs = self.work_dir / "logs"
        logs.mkdir(exist_ok=True)
        self.procs = ProcessSet(logs, fastdds_environment(dict(os.environ)), pid_file=logs / "pids")
        self.procs.env_for[names.CAMERA_NODE] = images_environment(os.environ)
        self.recorder: Child | None = None
        self.monitor: Monitor | None = None
        self.events: EventLog | None = None
        self.supervision: Supervision | None = None
        self.restart: RestartCommands | None = None
        self.writer: RunWriter | None = None
        self.stop_reason: str | None = None
        #: Why the run could not go on, or why its outputs are incomplete.
        self.failure: str | None = None
        self.t_go: float | None = None
        self.go_index = 0
        self._wall_start = time.monotonic()
        self._stopped = False
        self.killed: list[str] = []
        self.exit_codes: dict[str, int] = {}
        self._specs: dict[str, ProcessSpec] = {}
        self._streamed = 0
        self._t_end = math.inf
        self._reaper_pipe: int | None = None

    @property
    def wall_time(self) -> float:
        """Wall seconds since the launcher was made."""
        return time.monotonic() - self._wall_start

    # -- signals -------------------------------------------------------------------------

    def request_stop(self, reason: str = "stop requested") -> None:
        """End :meth:`wait_until_moving` / :meth:`run` at the next poll."""
        self.stop_reason = reason

    def signals_stop(self) -> contextlib.AbstractContextManager[None]:
        """While active, SIGINT/SIGTERM end the run instead of killing the launcher."""
        if threading.current_thread() is not threading.main_thread():
            return contextlib.nullcontext()
        return stop_signals(self.request_stop)

    # -- steps ---------------------------------------------------------------------------

    def start(self) -> None:
        """Check, write the parameter files and start every process (module docstring)."""
        cfg = self.config
        n = cfg.num_robots
        for warning in preflight.check_outputs(cfg):
            self.say(f"launch: warning: {warning}")
        scenario_file = write_scenario(cfg.scenario, self.work_dir / "scenario.yaml")
        robots_file = write_robot_params(cfg, self.work_dir / "robots.yaml", scenario_file)
        self.events = EventLog(self.work_dir / "events.csv", self.say)
        self._reaper_pipe = start_reaper(self.procs.pid_file, self.procs.log_dir / "reaper.log")
        self.discovery = dds.plan(
            resolved_discovery(cfg), n, dict(os.environ), cfg.discovery_server, cfg.discovery_port
        )
        layout_file = write_layout(cfg, self.work_dir / "arena.yaml")
        order = start_order(cfg, scenario_file, robots_file, layout_file, self.discovery)
        if cfg.firmware == "sil":
            order = with_firmware(order, n)
        self._specs = order.by_name
        self._start_discovery(order.discovery_server)
        self.monitor = Monitor(
            n, cfg.poses_topic, wall_clock=not cfg.sim_time, discovery=self.discovery
        )
        if not self.discovery.starts_server:
            # (a server of its own, on a port just taken, has no other clients to find:
            # the wait, DISCOVERY_WAIT s of every start, would be for nothing)
            preflight.refuse_other_swarm(self.monitor.other_swarm(DISCOVERY_WAIT))
        if cfg.firmware == "sil":  # the MCUs, their driver and loop before the bridge
            specs = start_firmware(self.procs, n, cfg.start_timeout, self._stopping)
            self._specs.update({spec.name: spec for spec in specs})
        if order.recorder is not None:
            self.recorder = self.procs.start(*order.recorder)
            self.recorder.wait_for(names.RECORDER_STARTED, 30.0, self._stopping)
        # the first process that publishes poses: the bridge, or a real arena's tracker
        bridge, *_ = [self.procs.start(*spec) for spec in order.first]
        if cfg.lockstep or self.recorder is not None:
            # The bridge and the supervisor first: the robots start only once the
            # launcher, the supervisor (and the recorder) receive /swarm/poses, so
            # that no step of a deterministic run and no message of a recording is
            # missed (at full speed a run can be over before a late reader matches).
            supervisor = self.procs.start(*order.supervisor)
            self._wait_first_poses(bridge)
            supervisor.wait_for(names.SUPERVISOR_RECEIVING_POSES, cfg.start_timeout, self._stopping)
            if self.recorder is not None:
                receiving = names.recorder_receiving(names.POSES)
                self.recorder.wait_for(receiving, cfg.start_timeout, self._stopping)
                # Paused until the recorder has found every robot's and the
                # supervisor's publishers: on a loaded machine discovery can take
                # seconds, and what a writer sends before the reader knows it is
                # lost for the bag (only its last few are kept for late readers).
                if order.bridge is not None:
                    self.monitor.pause_bridge(True, cfg.start_timeout)
            for spec in order.robots:
                self.procs.start(*spec)
            if self.recorder is not None:
                self.recorder.wait_for(
                    names.RECORDER_MATCHED_ALL, cfg.start_timeout, self._stopping
                )
                if order.bridge is not None:
                    self.monitor.pause_bridge(False, cfg.start_timeout)
        else:
            # Everything at once: each process spends ~1 s starting Python and
            # building its nodes, and discovery overlaps; robots move at their first
            # poses, and the run starts at the last sample before all of them moved.
            for spec in (order.supervisor, *order.robots):
                self.procs.start(*spec)
            self._wait_first_poses(bridge)
        if order.dashboard is not None:  # and its URL, from its ready line
            # the token by environment (argv is public), in the URL on this terminal only
            try:
                token = dashboard_token.given_token(os.environ) or dashboard_token.new_token()
            except dashboard_token.TokenError as exc:
                raise LaunchError(str(exc)) from None
            self.procs.env_for[order.dashboard.name] = {dashboard_token.TOKEN_VARIABLE: token}
            dashboard = self.procs.start(*order.dashboard)
            dashboard.wait_for(names.DASHBOARD_READY, 30.0, self._sampling)
            if (url := dashboard.line_after(names.DASHBOARD_READY)) is not None:
                self.say(f"launch: dashboard at {dashboard_token.with_token(url, token)}")
        state = self.procs.log_dir / "world_state.npz"
        self.restart = RestartCommands(
            self._specs, self.monitor, state, cfg.record, n, images_rate=cfg.record_images
        )
        self.supervision = Supervision(
            self.procs, self.events, cfg.on_failure, self.restart, self.monitor.sim_time,
            # a server that died comes back once its clients have forgotten it
            backoff_for={dds.SERVER_PROCESS: Backoff(first=dds.SERVER_RESTART_DELAY)},
        )  # fmt: skip
        described = describe(cfg, len(order.robots), self.discovery)
        self.say(f"launch: {described}; logs in {self.procs.log_dir}")

    def _start_discovery(self, server: ProcessSpec | None) -> None:
        """Point every process at the discovery server (starting it first if it is this
        launch's: ``server``) or at none; the recorder as a super client, since it
        subscribes to the topics it finds. Write the lines a shell needs for ``ros2``
        commands to ``ros_env.sh`` (and print them, with a server)."""
        found = self.discovery
        caller = os.environ.get(dds.SERVER_VARIABLE)
        if caller and (found.address is None or found.starts_server):
            why = "simple discovery" if found.address is None else "this launch starts its own"
            self.say(
                f"launch: {dds.SERVER_VARIABLE}={caller} of the environment is not used "
                f"({why}; --discovery-server {caller} would use that server)"
            )
        self.procs.env = found.client_environment(self.procs.env)
        if found.address is not None:
            self.procs.env_for["recorder"] = {dds.SUPER_CLIENT_VARIABLE: "true"}
        if server is not None:
            self.procs.start(*server).wait_for(dds.SERVER_READY, 30.0, self._stopping)
        path = Path(self.config.out_dir or self.work_dir) / "ros_env.sh"
        path.write_text(found.script(dict(os.environ)))
        if found.address is not None:
            where = "started here" if found.starts_server else "an existing one"
            lines = "".join(f"\n  {line}" for line in found.shell_lines(dict(os.environ)))
            self.say(
                f"launch: discovery server {found.address} ({where}); ros2 commands on this "
                f"swarm need (also in {path}):{lines}"
            )

    def _stopping(self) -> bool:
        return self.stop_reason is not None

    def _sampling(self) -> bool:
        """A wait's poll once the poses flow: take every sample that came, for 50 ms,
        then True once the launch is stopping. Without it the monitor's queue (keep the
        last 100: 2 s at 50 Hz) overflowed while the dashboard started on a loaded
        machine, a hole at the start of metrics.csv; one sample a poll (one ``spin_once``)
        kept it full and took one sample in five."""
        self.monitor.spin_for(0.05)
        return self._stopping()

    def _check_start(self) -> None:
        """Early on: a second swarm that discovery shows only now (before any fault:
        a dead process stays in the graph for a while)."""
        if not (self.events is not None and self.events.events):
            preflight.refuse_other_swarm(self.monitor.late_second_swarm(self.wall_time))

    def _wait_first_poses(self, source: Child) -> None:
        checks, timeout = (self._check_start, source.check_running), self.config.start_timeout
        self.monitor.wait_first_poses(source.name, timeout, checks, self._stopping)

    def spin_for(self, seconds: float) -> None:
        """Keep sampling (and looking after the processes) for ``seconds`` of wall time."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.monitor.spin_once(0.05)
            self._supervise()

    def _supervise(self) -> None:
        """Apply ``on_failure`` to processes that died; stream new samples to disk."""
        self._check_start()
        if self.supervision is not None:
            self.supervision.check()
        self._stream()

    def _stream(self) -> None:
        """Hand the samples taken since the last call to the output writer."""
        mon, writer = self.monitor, self.writer
        if self.t_go is not None and writer is None:  # nothing to write: keep the newest
            mon.release(mon.count)
        if writer is None:
            return
        held = mon.offset
        self._streamed = held + writer.add_from(
            mon.times, mon.positions, mon.headings, self._streamed - held, self._t_end
        )
        mon.release(self._streamed)
        if writer.error is not None and self.failure is None:
            self.failure = f"the outputs are incomplete: {writer.error}"
            self.events.record(
                "launcher", "cannot write the outputs", action="the swarm runs on; "
                f"{self.config.out_dir} holds what was written up to sim time "
                f"{writer.t_written or 0.0:.2f} s", sim_time=mon.sim_time(),
            )  # fmt: skip

    def wait_until_moving(self) -> float:
        """Block until every robot has moved from its first sampled pose.

        Returns the sim time of the last sample before that (the run's start),
        or raises LaunchError after ``start_timeout`` s of wall time.
        """
        mon = self.monitor
        assert mon is not None, "start() first"
        checks = (self.procs.check_alive, self._check_start)
        moved_at = mon.wait_all_moving(self.config.start_timeout, checks, self._stopping)
        self.t_go = mon.sample(mon.last_unmoved)[0] if mon.count else 0.0
        if moved_at is not None:
            self.go_index = mon.last_unmoved
            self._pause_bridge_at_end()
            self._begin_outputs()
            self.say(
                f"launch: all {mon.n} robots moving at sim time "
                f"{mon.sample(moved_at)[0]:.2f} s (wall {self.wall_time:.1f} s)"
            )
        return self.t_go

    def _pause_bridge_at_end(self) -> None:
        """Have the bridge wait half a step past the run's end (its ``pause_at``, a
        restarted bridge's too): at full speed it would otherwise run on while a launcher
        held up by a loaded machine falls so far behind that the samples it missed are
        gone from the bridge's history, and the outputs end early (seen in a test)."""
        duration = self.config.run_time
        if names.SIM_BRIDGE_NODE not in self._specs or duration <= 0 or self.t_go is None:
            return
        at = self.t_go + duration + 0.5 * self.config.scenario.dt
        if self.restart is not None:
            self.restart.pause_at = at
        try:
            self.monitor.pause_bridge_at(at, self.config.start_timeout)
        except LaunchError as exc:
            self.say(f"launch: {exc}; the bridge runs on past the run's end")

    def _begin_outputs(self) -> None:
        """From the run's start on, samples go to disk as they come."""
        cfg = self.config
        self._streamed = self.go_index
        duration = cfg.run_time
        self._t_end = self.t_go + duration + TIME_EPS if duration > 0 else math.inf
        if cfg.out_dir is not None:
            self.writer = RunWriter(Path(cfg.out_dir), cfg.scenario, cfg.label)

    def run(self, duration: float | None = None) -> None:
        """Sample poses until ``duration`` s of sim time after the start (0: until stopped)."""
        mon = self.monitor
        assert mon is not None and self.t_go is not None, "wait_until_moving() first"
        duration = self.config.run_time if duration is None else duration
        t_end = self.t_go + duration if duration > 0 else math.inf
        next_report = self.t_go + self.config.progress_every

        def report() -> None:  # a progress line every progress_every s of sim time
            nonlocal next_report
            now = mon.times[-1] if mon.times else 0.0
            if now >= next_report - TIME_EPS and now < t_end - TIME_EPS:
                line = progress(now, mon.positions[-1], mon.headings[-1])
                self.say(f"  {line}  [wall {self.wall_time:.1f} s]")
                next_report += self.config.progress_every

        mon.run_until(t_end, self.config.stall_timeout, (self._supervise, report), self._stopping)
        gap = self.writer.end_gap(t_end) if self.writer is not None else 0.0
        if gap > 0 and not self._stopping() and self.failure is None:
            # the samples in between were gone from the bridge's history when the
            # launcher (held up) asked for them again, and the next one was past the end
            self.failure = (
                f"the outputs end {gap:.2f} s of sim time before the run's end: the "
                f"launcher fell more than {OUTPUT_DEPTH} pose messages behind"
            )

    def stop(self) -> list[str]:
        """Stop every process (idempotent); returns the names of SIGKILLed ones."""
        if self._stopped:
            return self.killed
        self._stopped = True
        # The recorder after the others (the bag complete), and the discovery server: the
        # others' goodbyes go through it, without which their writers wait for
        # acknowledgements from readers that are gone (3 s each at the end).
        last = [c for c in self.procs.children if c.name in ("recorder", dds.SERVER_PROCESS)]
        recorders = [c for c in last if c.name == "recorder"]
        self.killed = self.procs.stop_all(self.config.stop_timeout, last=last)
        if self.monitor is not None:
            self.monitor.close()
        if self._reaper_pipe is not None:
            if not self.killed:  # every process said goodbye: the reaper need not linger
                os.write(self._reaper_pipe, STOPPED)
            os.close(self._reaper_pipe)
            self._reaper_pipe = None
        if self.recorder is not None:
            self.say(f"launch: {recorders[-1].last_line() or 'recorder wrote nothing'}")
        self.exit_codes = self.procs.exit_codes()
        self.say(f"launch: {self.procs.stop_summary(self.killed)}")
        return self.killed

    def cleanup(self, ok: bool) -> None:
        """Remove the temporary work directory of a successful run without out_dir."""
        if ok and self._own_work_dir:
            shutil.rmtree(self.work_dir, ignore_errors=True)
        elif not ok:
            self.say(f"launch: process logs kept in {self.procs.log_dir}")

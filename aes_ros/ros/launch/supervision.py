"""What the launcher does when one of its processes dies (``--on-failure``).

- ``respawn`` (default): restart it after a back-off (:class:`RestartPolicy`:
  0.5 s doubling to 8 s, at most 5 restarts a minute, then the run goes on
  without it); the launcher decides *how* (:attr:`Supervision.command_for`: the
  bridge from the last world state, the recorder into a new bag segment, the
  supervisor with the last swarm command);
- ``continue``: go on without it;
- ``stop``: end the run (its outputs are written; the exit code says it did not
  complete).

The run cannot go on without the bridge: when it is given up on (or with
``continue``/``stop``) :class:`RunCannotContinueError` ends the run. Every death, restart
and recovery (the restarted process printed its ready signal) goes to the
:class:`~aes_ros.ros.launch.events.EventLog`, and so do the events the supervisor
reports in its log (:class:`~aes_ros.ros.launch.events.LogEvents`: the arena
keeper turning or stopping the swarm).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from aes_ros.ros import discovery as dds
from aes_ros.ros import interface as names
from aes_ros.ros.launch import firmware
from aes_ros.ros.launch.events import EventLog, LogEvents, exit_text
from aes_ros.ros.launch.processes import Child, ProcessSet
from aes_ros.ros.launch.recovery import Backoff, RestartPolicy
from aes_ros.ros.programs import LaunchError


class RunCannotContinueError(LaunchError):
    """A process the run needs is gone for good (or ``--on-failure stop``)."""


def ready_signal(name: str) -> str:
    """What process ``name`` prints once it works again (:mod:`aes_ros.ros.interface`)."""
    if name == names.SIM_BRIDGE_NODE:
        return names.BRIDGE_READY
    if name == names.SUPERVISOR_NODE:
        return names.SUPERVISOR_RECEIVING_POSES
    if name == "recorder":
        return names.recorder_receiving(names.POSES)
    if name == names.DASHBOARD_NODE:
        return names.DASHBOARD_READY
    if name == dds.SERVER_PROCESS:
        return dds.SERVER_READY
    return firmware.ready_signal(name) or names.ROBOTS_READY


@dataclass
class _Recovering:
    child: Child
    died_at: float


@dataclass
class Supervision:
    """Watches the processes of :attr:`procs` and applies ``on_failure``.

    command_for : name -> the command line to restart that process with.
    sim_time : the latest sim time the launcher has seen (for the event log).
    """

    procs: ProcessSet
    events: EventLog
    on_failure: str
    command_for: Callable[[str], list[str]]
    sim_time: Callable[[], float | None]
    backoff: Backoff = field(default_factory=Backoff)
    #: Another back-off for a process of that name (the discovery server).
    backoff_for: dict[str, Backoff] = field(default_factory=dict)
    clock: Callable[[], float] = time.monotonic
    #: Processes given up on (the run goes on without them).
    given_up: list[str] = field(default_factory=list)
    #: Wall seconds from each death to the restarted process's ready signal.
    recovery_times: dict[str, list[float]] = field(default_factory=dict)
    _handled: set[int] = field(default_factory=set)
    _due: dict[str, tuple[float, float]] = field(default_factory=dict)
    _recovering: dict[str, _Recovering] = field(default_factory=dict)
    _policies: dict[str, RestartPolicy] = field(default_factory=dict)
    _log_events: LogEvents = field(init=False)

    def __post_init__(self) -> None:
        self._log_events = LogEvents(self.events, self.sim_time)

    def check(self) -> None:
        """Take the events reported in the logs, handle new deaths, start the restarts
        that are due, notice recoveries.

        Raises RunCannotContinueError when the run cannot go on.
        """
        self._log_events.check(self.procs.children)
        now = self.clock()
        for child in list(self.procs.children):
            if child.proc.poll() is not None and id(child) not in self._handled:
                self._handled.add(id(child))
                self._died(child, now)
        for name, (due, died_at) in list(self._due.items()):
            if now >= due:
                del self._due[name]
                self._restart(name, died_at, now)
        for name, rec in list(self._recovering.items()):
            if rec.child.proc.poll() is not None:
                del self._recovering[name]  # died again: handled as a death
            elif ready_signal(name) in rec.child.output():
                del self._recovering[name]
                took = now - rec.died_at
                self.recovery_times.setdefault(name, []).append(took)
                self.events.record(
                    name,
                    "recovered",
                    action=f"{took:.1f} s after it died",
                    sim_time=self.sim_time(),
                )

    @property
    def pending(self) -> list[str]:
        """Processes waiting for their restart."""
        return list(self._due)

    def _died(self, child: Child, now: float) -> None:
        name = child.name
        self._recovering.pop(name, None)
        died = exit_text(child.proc.returncode)

        def note(event: str, action: str) -> None:
            self.events.record(name, event, exit=died, action=action, sim_time=self.sim_time())

        def give_up(event: str, why: str) -> None:
            if name == names.SIM_BRIDGE_NODE:  # the run needs it
                note(event, f"{why}: stopping the run")
                raise RunCannotContinueError(f"{name} {event} ({died}): {why}")
            note(event, f"{why}: continuing without it")
            self.given_up.append(name)

        if name == "recorder" and child.proc.returncode == names.RECORDER_CANNOT_WRITE:
            note("cannot write the bag", "recording stopped; the run goes on")
            self.given_up.append(name)
        elif self.on_failure == "stop":
            note("died", "stopping the run")
            raise RunCannotContinueError(f"{name} died ({died}); --on-failure stop")
        elif self.on_failure == "continue":
            give_up("died", "--on-failure continue")
        else:
            b = self.backoff_for.get(name, self.backoff)
            policy = self._policies.setdefault(name, RestartPolicy(b))
            delay = policy.delay(now)
            if delay is None:
                give_up("died", f"restarted {b.limit} times within {b.window:g} s")
            else:
                note("died", f"restart in {delay:g} s")
                self._due[name] = (now + delay, now)

    def _restart(self, name: str, died_at: float, now: float) -> None:
        child = self.procs.start(name, self.command_for(name))
        self._policies[name].restarted(now)
        self._recovering[name] = _Recovering(child, died_at)
        self.events.record(
            name, "restarted", action=f"pid {child.proc.pid}", sim_time=self.sim_time()
        )

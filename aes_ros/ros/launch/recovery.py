"""When and how to restart a process that died, and when to give up on it.

The rule of ``aes-swarm launch --on-failure respawn``, like ``ros2 launch``'s
``respawn`` with ``respawn_delay`` but with back-off and a limit: the first
restart waits :attr:`Backoff.first` seconds, each further one twice as long up to
:attr:`Backoff.longest`; a process that has been restarted :attr:`Backoff.limit`
times within :attr:`Backoff.window` seconds is given up on (the run goes on
without it, if it can). :class:`RestartCommands` says with which command line.
"""

from __future__ import annotations

import sys
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aes_ros.ros import interface as names
from aes_ros.ros.bag import bag_segments, next_segment
from aes_ros.ros.launch.commands import ProcessSpec, recorder_command
from aes_ros.ros.launch.param_files import ros_value
from aes_ros.world_state import WorldState


@dataclass(frozen=True)
class Backoff:
    """Restart delays [s] and the restart limit per process."""

    first: float = 0.5
    factor: float = 2.0
    longest: float = 8.0
    limit: int = 5
    window: float = 60.0


class RestartPolicy:
    """Restart times of one process (wall clock [s], monotonic)."""

    def __init__(self, backoff: Backoff = Backoff()) -> None:
        self.backoff = backoff
        self._restarts: deque[float] = deque()
        self._consecutive = 0

    def delay(self, now: float) -> float | None:
        """Seconds to wait before restarting a process that died at ``now``, or None
        when it was restarted ``limit`` times within the last ``window`` seconds."""
        b = self.backoff
        while self._restarts and now - self._restarts[0] > b.window:
            self._restarts.popleft()
        if len(self._restarts) >= b.limit:
            return None
        if not self._restarts:
            self._consecutive = 0  # a quiet minute: start the back-off over
        wait = min(b.first * b.factor**self._consecutive, b.longest)
        self._consecutive += 1
        return wait

    def restarted(self, now: float) -> None:
        """The process was started again at ``now``."""
        self._restarts.append(now)

    @property
    def restarts(self) -> int:
        """Restarts within the current window."""
        return len(self._restarts)


@dataclass
class RestartCommands:
    """The command line that restarts a launch's process ``name`` (call the object).

    - the bridge: from the last world state the monitor sampled (``resume_from``,
      written to ``state_file``), so the swarm carries on where it was, and waiting
      at the run's end as the first did (``pause_at``);
    - the recorder: as it was first started (its ``--split``, ``--keep`` and
      ``--images`` too) into the next bag segment: one past the highest on disk,
      which a splitting recorder may have numbered (``run_1.mcap``, …), counting
      what was lost since the earlier ones;
    - the supervisor: with the last swarm command it published (a runtime
      ``/swarm/cmd`` or enable survives its restart);
    - any other process: as it was started.

    specs : each process's first command line. monitor : the launcher's
    :class:`~aes_ros.ros.launch.monitor.Monitor` (its samples, the latched command).
    record, images_rate : the recording and its camera frames a second, for a recorder
    not in ``specs``. segments : the number of the last segment a restart started.
    """

    specs: dict[str, ProcessSpec]
    monitor: Any
    state_file: Path
    record: Path | None
    num_robots: int
    segments: int = 0
    images_rate: float = 0.0
    #: The bridge's ``pause_at`` [s of sim time] once the launcher has set it (0: none).
    pause_at: float = 0.0

    def __call__(self, name: str) -> list[str]:
        if name == "recorder":
            record = Path(self.record).resolve()
            earlier = bag_segments(record)
            self.segments = max(self.segments + 1, next_segment(record))
            first = self.specs.get("recorder") or recorder_command(
                record, self.num_robots, sys.executable, images_rate=self.images_rate
            )
            # the first command line has neither --segment nor --after
            after = ["--after", *map(str, earlier)] if earlier else []
            return [*first.argv, "--segment", str(self.segments), *after]
        argv = list(self.specs[name].argv)
        mon = self.monitor
        if name == names.SIM_BRIDGE_NODE and mon.times:
            state = WorldState(mon.times[-1], mon.positions[-1], mon.headings[-1])
            argv += ["-p", f"resume_from:={state.save(self.state_file)}"]
        if name == names.SIM_BRIDGE_NODE and self.pause_at > 0.0:
            argv += ["-p", f"pause_at:={ros_value(self.pause_at)}"]
        if name == names.SUPERVISOR_NODE and mon.desired is not None:
            twist = mon.desired.twist
            argv += [
                "-p", f"desired_direction:={ros_value([twist.linear.x, twist.linear.y])}",
                "-p", f"rotation_rate:={ros_value(twist.angular.z)}",
            ]  # fmt: skip
        if name == names.SUPERVISOR_NODE and mon.enabled is not None:
            argv += ["-p", f"enabled:={ros_value(mon.enabled)}"]
        return argv

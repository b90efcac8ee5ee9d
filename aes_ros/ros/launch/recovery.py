"""When to restart a process that died, and when to give up on it (pure).

The rule of ``aes-swarm launch --on-failure respawn``, like ``ros2 launch``'s
``respawn`` with ``respawn_delay`` but with back-off and a limit: the first
restart waits :attr:`Backoff.first` seconds, each further one twice as long up to
:attr:`Backoff.longest`; a process that has been restarted :attr:`Backoff.limit`
times within :attr:`Backoff.window` seconds is given up on (the run goes on
without it, if it can).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass


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

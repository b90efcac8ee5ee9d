"""The lockstep barrier: a control step waits for a new command of every robot (pure)."""

from __future__ import annotations

import numpy as np


class LockstepBarrier:
    """Which robots have answered the state published last.

    >>> barrier = LockstepBarrier(3)
    >>> barrier.arrived(0); barrier.arrived(2)
    >>> barrier.complete, barrier.missing().tolist()
    (False, [1])
    """

    def __init__(self, n: int) -> None:
        self._fresh = np.zeros(n, dtype=bool)

    def arrived(self, robot_id: int) -> None:
        """A new command of ``robot_id`` since the last step."""
        self._fresh[robot_id] = True

    @property
    def complete(self) -> bool:
        """Every robot has answered: the world may step."""
        return bool(self._fresh.all())

    def missing(self) -> np.ndarray:
        """Ids of the robots not yet heard from in this step."""
        return np.flatnonzero(~self._fresh)

    def next_step(self) -> None:
        """The world stepped (or was reset): wait for every robot again."""
        self._fresh[:] = False

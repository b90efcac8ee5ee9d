"""The lockstep barrier: a control step waits for every member to answer (pure).

Members are the robots (their ``cmd_vel``) and, when a recording must be
lossless, the recorder (its progress). A member silent for longer than
``timeout`` wall seconds while the barrier waits for it leaves the barrier, so
that one dead robot does not stall the swarm; it is back in as soon as it answers
again. Silent means: no answer since the later of its last answer and the moment
the state of the step awaited was out (a member that answered at once, then waited with
everyone for a dead one, has had no time to answer the step after it; nor has one
whose answer waits in the bridge's queue while the bridge steps and publishes). A member never heard
from is waited for without a timeout (it may still be starting). With no fault
every step waits for everyone: a run stays deterministic.
"""

from __future__ import annotations

import math

import numpy as np

#: Wall seconds a member may be silent before it leaves the barrier.
DEFAULT_TIMEOUT = 2.0


class LockstepBarrier:
    """Which members have answered the state published last.

    >>> barrier = LockstepBarrier(3, timeout=2.0)
    >>> barrier.arrived(0, now=0.0); barrier.arrived(2, now=0.0)
    False
    False
    >>> barrier.complete, barrier.missing().tolist()
    (False, [1])
    """

    def __init__(self, n: int, timeout: float = DEFAULT_TIMEOUT) -> None:
        self.timeout = timeout
        self._fresh = np.zeros(n, dtype=bool)
        self._member = np.ones(n, dtype=bool)
        self._heard = np.full(n, -math.inf)  # wall time [s] of each member's last answer
        self._step_since = -math.inf  # wall time [s] the step awaited began

    def arrived(self, member: int, now: float) -> bool:
        """``member`` answered at wall time ``now``; True if it was out and is back in."""
        self._fresh[member] = True
        self._heard[member] = now
        if self._member[member]:
            return False
        self._member[member] = True
        return True

    @property
    def complete(self) -> bool:
        """Every member has answered: the world may step."""
        return bool(np.all(self._fresh | ~self._member))

    def missing(self) -> np.ndarray:
        """Members not yet heard from in this step."""
        return np.flatnonzero(~self._fresh & self._member)

    def drop_silent(self, now: float) -> np.ndarray:
        """Remove the members awaited but silent for longer than the timeout; their ids."""
        quiet_since = np.maximum(self._heard, self._step_since)
        silent = ~self._fresh & self._member & (now - quiet_since > self.timeout)
        silent &= np.isfinite(self._heard)  # never heard from: still starting
        self._member[silent] = False
        return np.flatnonzero(silent)

    def silent(self, now: float, after: float) -> np.ndarray:
        """Members not heard from for ``after`` wall seconds or more (never heard from
        included), member of the barrier or not."""
        return np.flatnonzero(now - self._heard >= after)

    def is_member(self, member: int) -> bool:
        return bool(self._member[member])

    def next_step(self, now: float) -> None:
        """The world stepped (or was reset) and its state is out at wall time ``now``: wait
        for every member again."""
        self._fresh[:] = False
        self._step_since = now

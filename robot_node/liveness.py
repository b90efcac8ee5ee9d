"""Which neighbours of a robot are alive, judged by the stamps of what they send (pure).

A neighbour counts as heard from at the stamp of its latest message (its
``aes_force``, or its odometry in the ``odom`` source). One whose latest stamp is
more than ``timeout_ns`` behind the robot's own pose is left out of the spring
sum; one never heard from counts as alive (it may still be starting), and one
that speaks again is taken back at once. With a camera in the loop, the tracker's
*lost* robots (not seen for its ``lost_after``: their poses are old) are left out
the same way, whichever process runs them (:attr:`NeighborLiveness.lost`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class LivenessChange(NamedTuple):
    """A neighbour went silent (``silent`` True, after ``seconds``; NaN: the tracker
    lost it) or was heard again."""

    neighbor: int
    silent: bool
    seconds: float


class NeighborLiveness:
    """Stamps [ns] of each neighbour's latest message, and the neighbours left out.

    >>> live = NeighborLiveness(timeout_ns=1_000_000_000)
    >>> live.heard(4, 0)
    >>> mask, changes = live.alive(np.array([4, 5]), 2_000_000_000)
    >>> mask.tolist(), changes[0].neighbor
    ([False, True], 4)
    """

    def __init__(self, timeout_ns: int) -> None:
        self.timeout_ns = int(timeout_ns)
        self._heard: dict[int, int] = {}
        self._silent: set[int] = set()
        #: Robots the tracker has lost (``/diagnostics``): silent whatever they send.
        self.lost: frozenset[int] = frozenset()

    def __bool__(self) -> bool:
        """True once any neighbour has been heard from or lost (before that all are
        alive)."""
        return bool(self._heard or self.lost or self._silent)

    def heard(self, neighbor: int, stamp_ns: int) -> None:
        """``neighbor`` spoke with a message stamped ``stamp_ns``."""
        self._heard[neighbor] = stamp_ns

    def forget(self, neighbor: int) -> None:
        """No longer listened to (e.g. it now runs in this process): alive again."""
        self._heard.pop(neighbor, None)
        self._silent.discard(neighbor)

    def clear(self) -> None:
        """Forget every stamp (the clock went back: they belong to the old time line)."""
        self._heard.clear()

    def alive(self, ids: np.ndarray, stamp_ns: int) -> tuple[np.ndarray, list[LivenessChange]]:
        """Mask ``(len(ids),)`` of the neighbours ``ids`` heard from within the
        timeout of ``stamp_ns``, and the neighbours whose state changed with this call."""
        keep = np.ones(len(ids), dtype=bool)
        changes: list[LivenessChange] = []
        if not self:
            return keep, changes
        for slot, j in enumerate(ids.tolist()):
            heard = self._heard.get(j)
            lost = j in self.lost
            silent = lost or (heard is not None and stamp_ns - heard > self.timeout_ns)
            keep[slot] = not silent
            if silent and j not in self._silent:
                self._silent.add(j)
                seconds = float("nan") if lost else (stamp_ns - heard) * 1e-9
                changes.append(LivenessChange(j, True, seconds))
            elif not silent and j in self._silent:
                self._silent.discard(j)
                changes.append(LivenessChange(j, False, 0.0))
        return keep, changes

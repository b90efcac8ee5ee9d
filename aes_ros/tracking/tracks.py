"""What the tracker knows of each robot between frames (pure: numpy, no ROS).

A frame's detections update the robots they saw; a robot not seen keeps its last
pose and its age grows; a robot unseen for longer than ``lost_after`` is *lost*
(reported, its last pose still published: nothing is invented, and the robots'
own neighbour liveness decides who counts). Ids that are neither a robot of the
swarm nor a reference marker are *unknown* and ignored; the detector already
drops an id seen twice in one frame (:mod:`aes_ros.tracking.detection`).

The tracker publishes ``/swarm/poses`` only once every robot has been seen at
least once (:attr:`Tracks.complete`): before that, a robot has no pose at all.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class FrameReport:
    """What one frame said: ids of the robots it saw, the unknown ids it ignored."""

    seen: np.ndarray
    unknown: tuple[int, ...]


@dataclass
class Tracks:
    """The last pose of each of ``n`` robots and when it was seen.

    Attributes
    ----------
    positions : (n, 2) [m; arena frame] (NaN until first seen)
    headings : (n,) [rad] (NaN until first seen)
    seen_ns : (n,) stamp [ns] of the frame each robot was last seen in (-1: never)
    """

    n: int
    references: frozenset[int] = frozenset()
    positions: np.ndarray = field(init=False)
    headings: np.ndarray = field(init=False)
    seen_ns: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.positions = np.full((self.n, 2), np.nan)
        self.headings = np.full(self.n, np.nan)
        self.seen_ns = np.full(self.n, -1, dtype=np.int64)

    def update(
        self, stamp_ns: int, ids: np.ndarray, positions: np.ndarray, headings: np.ndarray
    ) -> FrameReport:
        """Take one frame's detections: ``ids (M,)``, ``positions (M, 2)`` [m],
        ``headings (M,)`` [rad], of the frame exposed at ``stamp_ns``. A frame older
        than a robot's last sighting does not move that robot back in time."""
        ids = np.asarray(ids, dtype=np.int64)
        robot = (ids >= 0) & (ids < self.n)
        unknown = tuple(int(i) for i in ids[~robot] if int(i) not in self.references)
        newer = robot.copy()
        newer[robot] = self.seen_ns[ids[robot]] <= stamp_ns
        seen = ids[newer]
        self.positions[seen] = np.asarray(positions)[newer]
        self.headings[seen] = np.asarray(headings)[newer]
        self.seen_ns[seen] = stamp_ns
        return FrameReport(seen=seen, unknown=unknown)

    @property
    def complete(self) -> bool:
        """Every robot seen at least once: there is a pose to publish for each."""
        return bool(np.all(self.seen_ns >= 0))

    def missing(self) -> np.ndarray:
        """Ids of the robots never seen."""
        return np.flatnonzero(self.seen_ns < 0)

    def ages(self, stamp_ns: int) -> np.ndarray:
        """Seconds (n,) since each robot was last seen, at ``stamp_ns`` (inf: never)."""
        age = (stamp_ns - self.seen_ns) * 1e-9
        return np.where(self.seen_ns >= 0, age, np.inf)

    def lost(self, stamp_ns: int, lost_after: float) -> np.ndarray:
        """Ids of the robots not seen for longer than ``lost_after`` [s] (or never)."""
        return np.flatnonzero(self.ages(stamp_ns) > lost_after)

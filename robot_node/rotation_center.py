"""Which rotation centre x_c (E3) a robot uses (pure). One rule serves all robots of a
process (:class:`robot_node.swarm_inputs.SwarmInputs`), which hear the same messages.

The supervisor publishes ``/swarm/rotation_center``: a fixed point, or the live
centroid of ``/swarm/poses`` stamped with the poses' stamp. A robot that
recognises the live centroid (a published centre equal to the centroid of the
poses with the same stamp) uses the centroid of the very poses it acts on
instead of the published copy, which arrives one message late: so it has the
same x_c as the offline simulator.

The choice depends on the stamps of the messages heard, not on how the two
streams interleave (each arrives in its publisher's order): the centre in force is
the newest one that the poses heard so far reach. A centre ahead of them (the
supervisor heard its poses first, or no poses yet) is undecided, and the one before
it stays in force, point and all. Once poses reach it, it is the live centroid if
the poses of its stamp were heard and match it, else a fixed point (they passed its
stamp without it: a fixed centre, or the centroid of poses this process lost).
Taking a centre heard before any poses for a fixed point at once, as before, left a
robot on a stale centroid for a step when the supervisor's next centre came late
(the specification and that case: tests/unit/test_rotation_center.py).
"""

from __future__ import annotations

import numpy as np

from aes_ros.model import SwarmCommand

#: A published centre this close [m] to the centroid of the poses with the same
#: stamp means the supervisor follows the live centroid.
CENTROID_MATCH_TOL = 1e-9
#: How many recent poses messages' centroids, and undecided centres, are remembered.
CENTROID_MEMORY = 8


class RotationCenterRule:
    """The rotation centre of a robot, from the supervisor's messages and the poses.

    Parameters
    ----------
    center : (2,) [m] the scenario's fixed centre, or None for the live centroid
        (what the robot assumes until the supervisor speaks).
    """

    def __init__(self, center: np.ndarray | None) -> None:
        #: The newest centre heard (2,) [m] (x_c of robots that see no poses).
        self.point = None if center is None else np.asarray(center, dtype=float)
        #: The centre in force is the live centroid (else the fixed ``_fixed``).
        self.follows_centroid = center is None
        self._fixed = self.point
        self._centroids: dict[int, np.ndarray] = {}
        self._last_poses_stamp: int | None = None
        #: Centres ahead of the poses heard, (stamp, point) in arrival order.
        self._undecided: list[tuple[int, np.ndarray]] = []

    def on_poses(self, stamp_ns: int, centroid: np.ndarray) -> None:
        """The centroid (2,) of a poses message stamped ``stamp_ns``."""
        self._centroids[stamp_ns] = centroid
        if len(self._centroids) > CENTROID_MEMORY:
            del self._centroids[next(iter(self._centroids))]
        self._last_poses_stamp = stamp_ns
        undecided = self._undecided
        if undecided:  # the newest centre these poses reach is in force
            for k in range(len(undecided) - 1, -1, -1):
                stamp, point = undecided[k]
                if stamp <= stamp_ns:
                    self._take(point, stamp == stamp_ns and _same_point(centroid, point))
                    del undecided[: k + 1]  # the later ones stay ahead
                    break

    def on_center(self, stamp_ns: int, point: np.ndarray) -> None:
        """The supervisor's centre (2,) [m], stamped ``stamp_ns``."""
        self.point = point
        centroid = self._centroids.get(stamp_ns)
        if centroid is not None:
            self._take(point, _same_point(centroid, point))
        elif self._last_poses_stamp is not None and stamp_ns < self._last_poses_stamp:
            self._take(point, False)  # the poses passed it without its own
        else:  # ahead of the poses: decided when they reach it
            self._undecided.append((stamp_ns, point))
            if len(self._undecided) > CENTROID_MEMORY:
                del self._undecided[0]
            return
        self._undecided.clear()  # older than this one: superseded

    def _take(self, point: np.ndarray, follows: bool) -> None:
        self.follows_centroid = follows
        self._fixed = point

    def center(self, centroid: np.ndarray | None) -> np.ndarray | None:
        """x_c for a step whose poses have ``centroid`` (None: not known, e.g. the
        ``odom`` source: the newest centre heard); None when no centre is known at all."""
        if centroid is None:
            return self.point
        return centroid if self.follows_centroid else self._fixed


def _same_point(a: np.ndarray, b: np.ndarray | None) -> bool:
    # component by component: np.all on two 2-vectors was 4 % of a robot host's CPU
    return (
        b is not None
        and abs(a[0] - b[0]) <= CENTROID_MATCH_TOL
        and abs(a[1] - b[1]) <= CENTROID_MATCH_TOL
    )


def rotation_center_rule(command: SwarmCommand) -> RotationCenterRule:
    """The rule before anything is heard: the command's fixed centre, or the live
    centroid when it has none."""
    return RotationCenterRule(None if command.center is None else np.asarray(command.center))

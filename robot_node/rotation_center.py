"""Which rotation centre x_c (E3) a robot uses (pure). One rule serves all robots of a
process (:class:`robot_node.swarm_inputs.SwarmInputs`), which hear the same messages.

The supervisor publishes ``/swarm/rotation_center``: a fixed point, or the live
centroid of ``/swarm/poses`` stamped with the poses' stamp. A robot that
recognises the live centroid (a published centre equal to the centroid of the
poses with the same stamp) uses the centroid of the very poses it acts on
instead of the published copy, which arrives one message late: so it has the
same x_c as the offline simulator.
"""

from __future__ import annotations

import numpy as np

from aes_ros.model import SwarmCommand

#: A published centre this close [m] to the centroid of the poses with the same
#: stamp means the supervisor follows the live centroid.
CENTROID_MATCH_TOL = 1e-9
#: How many recent poses messages' centroids are remembered.
CENTROID_MEMORY = 8


class RotationCenterRule:
    """The rotation centre of a robot, from the supervisor's messages and the poses.

    Parameters
    ----------
    center : (2,) [m] the scenario's fixed centre, or None for the live centroid
        (what the robot assumes until the supervisor speaks).
    """

    def __init__(self, center: np.ndarray | None) -> None:
        self.point = None if center is None else np.asarray(center, dtype=float)
        self.follows_centroid = center is None
        self._point_stamp = -1
        self._pending = False
        self._centroids: dict[int, np.ndarray] = {}
        self._last_poses_stamp: int | None = None

    def on_poses(self, stamp_ns: int, centroid: np.ndarray) -> None:
        """The centroid (2,) of a poses message stamped ``stamp_ns``."""
        self._centroids[stamp_ns] = centroid
        if len(self._centroids) > CENTROID_MEMORY:
            del self._centroids[next(iter(self._centroids))]
        self._last_poses_stamp = stamp_ns
        if self._pending and stamp_ns >= self._point_stamp:
            same_stamp = stamp_ns == self._point_stamp
            self.follows_centroid = same_stamp and _same_point(centroid, self.point)
            self._pending = False

    def on_center(self, stamp_ns: int, point: np.ndarray) -> None:
        """The supervisor's centre (2,) [m], stamped ``stamp_ns``."""
        self.point = point
        self._point_stamp = stamp_ns
        centroid = self._centroids.get(stamp_ns)
        if centroid is not None:
            self.follows_centroid = _same_point(centroid, point)
            self._pending = False
        elif self._last_poses_stamp is not None and stamp_ns > self._last_poses_stamp:
            self._pending = True  # arrived before its poses: decide when they come
        else:
            self.follows_centroid = False
            self._pending = False

    def center(self, centroid: np.ndarray | None) -> np.ndarray | None:
        """x_c for a step whose poses have ``centroid`` (None: not known, e.g. the
        ``odom`` source); None when no centre is known at all."""
        if self.follows_centroid and centroid is not None:
            return centroid
        return self.point


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

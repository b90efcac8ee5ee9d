"""The latest IR ranges of one robot, for the avoidance term (pure: no rclpy).

:class:`IrReadings` keeps the newest valid reading of each of the Mona's five IR sensors
(``/mona_<i>/ir_<k>``, sensor_msgs/Range) with its stamp. A reading older than
:data:`MAX_AGE` at the robot's own pose stamp counts as nothing seen, so a sensor (or a
driver) that falls silent stops pushing the robot. docs/model.md, "Obstacle avoidance".
"""

from __future__ import annotations

import math

import numpy as np

from aes_ros.avoidance import N_IR

#: A reading older than this [s] (by stamp, against the own pose's) counts as nothing seen.
MAX_AGE = 0.5
#: Largest range [m] a reading may have: no IR proximity sensor sees farther, so a larger
#: value is a wrong unit or a broken driver, not a distance.
MAX_RANGE = 1.0


class IrReadings:
    """The newest valid range of each sensor and its stamp."""

    def __init__(self, max_age: float = MAX_AGE) -> None:
        self.max_age_ns = int(max_age * 1e9)
        self._ranges = np.full(N_IR, np.nan)
        self._stamps = np.zeros(N_IR, dtype=np.int64)

    def heard(self, sensor: int, stamp_ns: int, distance: float) -> str | None:
        """Keep sensor ``sensor``'s reading ``distance`` [m] stamped ``stamp_ns``; or, for a
        reading that is not a distance (NaN, ±inf, negative, above :data:`MAX_RANGE`),
        keep nothing and return why (the caller warns)."""
        if not (math.isfinite(distance) and 0.0 <= distance <= MAX_RANGE):
            return (
                f"dropped ir_{sensor}: range {distance!r} is not a distance in [0, {MAX_RANGE:g}] m"
            )
        self._ranges[sensor] = distance
        self._stamps[sensor] = stamp_ns
        return None

    def ranges(self, stamp_ns: int) -> np.ndarray | None:
        """The five ranges [m] at the own pose stamp ``stamp_ns``, NaN where a sensor's
        newest reading is older than the maximum age or never came; None if none is fresh."""
        fresh = (stamp_ns - self._stamps <= self.max_age_ns) & ~np.isnan(self._ranges)
        if not fresh.any():
            return None
        return np.where(fresh, self._ranges, np.nan)

    def clear(self) -> None:
        """Forget every reading (the clock went back, or the sensors are no longer read)."""
        self._ranges[:] = np.nan

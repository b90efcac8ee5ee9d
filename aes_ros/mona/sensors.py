"""A Mona's TELEMETRY in SI units: IR ranges, battery voltage, wheel odometry.

The IR model is an assumption, not a calibration (docs/mona_protocol.md, "IR
readings"): MonaRobot publishes no response curve of the Mona's IR proximity sensors,
so a raw ADC reading is turned into a signal that grows with reflected light
(``signal = 1023 − raw`` on the original Mona, whose reading falls as an obstacle
comes closer, docs/firmware.md; ``signal = raw`` with ``falling=False``) and mapped
by the inverse law ``range = gain / (signal − offset)``, clipped to
``[min_range, max_range]``, with constants a lab replaces by its own (the driver's
``ir_*`` parameters).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Full field of view of one IR sensor [rad] (an assumption, docs/mona_protocol.md).
IR_FIELD_OF_VIEW = 0.35


@dataclass(frozen=True)
class IrModel:
    """Raw IR ADC reading → range [m]: ``gain / (signal − offset)``, clipped.

    ``signal`` is ``FULL_SCALE − raw`` when ``falling`` (the original Mona: 1023 is
    nothing seen), else ``raw``. A signal at or below ``offset`` (ambient light only,
    nothing seen) is ``max_range``. The defaults put a signal of 1023 at 1 cm and one of
    150 at about 10 cm.
    """

    gain: float = 10.0  #: [m · ADC counts]
    offset: float = 50.0  #: ambient reading [ADC counts]
    min_range: float = 0.01  #: [m]
    max_range: float = 0.10  #: [m]
    falling: bool = True  #: the reading falls as an obstacle comes closer

    FULL_SCALE = 1023  #: a 10-bit ADC's largest reading

    def range(self, raw: np.ndarray | int) -> np.ndarray:
        """Range [m] of raw readings (any shape); always finite."""
        raw = np.asarray(raw, dtype=float)
        signal = self.FULL_SCALE - raw if self.falling else raw
        excess = signal - self.offset
        with np.errstate(divide="ignore"):
            r = np.where(excess > 0.0, self.gain / np.maximum(excess, 1e-12), self.max_range)
        return np.clip(r, self.min_range, self.max_range)

    def check(self) -> str | None:
        """Why these constants cannot work (None if they can)."""
        values = (self.gain, self.offset, self.min_range, self.max_range)
        if not all(math.isfinite(v) for v in values):
            return "IR model: every constant must be finite"
        if self.gain <= 0.0 or not 0.0 < self.min_range < self.max_range:
            return "IR model: gain > 0 and 0 < min_range < max_range"
        return None


def battery_volts(millivolts: int) -> float:
    """TELEMETRY's battery [mV] in volts."""
    return 1e-3 * float(millivolts)


def integrate_pose(
    x: float, y: float, theta: float, v: float, omega: float, dt: float
) -> tuple[float, float, float]:
    """Pose (x, y [m], θ [rad]) after moving at (v [m/s], ω [rad/s]) for ``dt`` s.

    Exact for a constant twist: an arc of radius v/ω (a straight line when ω ≈ 0);
    θ is wrapped to (−π, π].
    """
    dtheta = omega * dt
    if abs(dtheta) < 1e-9:
        dx, dy = v * dt * math.cos(theta), v * dt * math.sin(theta)
    else:
        radius = v / omega
        dx = radius * (math.sin(theta + dtheta) - math.sin(theta))
        dy = -radius * (math.cos(theta + dtheta) - math.cos(theta))
    heading = math.atan2(math.sin(theta + dtheta), math.cos(theta + dtheta))
    return x + dx, y + dy, heading

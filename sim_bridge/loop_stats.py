"""Figures of the bridge's control loop and bodies, for ``/sim/stats`` and the benchmark (pure).

The latencies go into a histogram of fixed size (log-spaced bins, 1 % wide) rather
than a list: a bridge nobody asks for its figures runs for hours at 5000 commands/s,
and a list of them grew by ~10 MB a minute. Percentiles are read from the bins
(within 1 %); the maximum is kept exactly.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Latency histogram: bins from LATENCY_MIN to LATENCY_MAX [s], BINS_PER_DECADE per decade
#: (edges 1.2 % apart); latencies outside go to the first or last bin.
LATENCY_MIN, LATENCY_MAX, BINS_PER_DECADE = 1e-6, 1e3, 200
_DECADES = round(np.log10(LATENCY_MAX / LATENCY_MIN))
_EDGES = LATENCY_MIN * 10.0 ** (np.arange(_DECADES * BINS_PER_DECADE + 1) / BINS_PER_DECADE)
#: A bin's value: the geometric middle of its edges.
_MIDDLES = np.sqrt(_EDGES[:-1] * _EDGES[1:])


class ControlLoopStats:
    """Commands per robot, their latencies and the bodies' contacts since the last
    :meth:`snapshot`.

    Parameters
    ----------
    n : robots. now : wall time [s, monotonic] of the start. step : the world's
    step count at the start. dt : control period [s] of sim time.
    """

    def __init__(self, n: int, now: float, step: int, dt: float) -> None:
        self.n, self.dt = n, dt
        self._reset(now, step)

    def _reset(self, now: float, step: int) -> None:
        self._since = (now, step)
        self._counts = np.zeros(self.n, dtype=np.int64)
        self._histogram = np.zeros(len(_MIDDLES), dtype=np.int64)
        self._latency_max: float | None = None
        self._contacts = 0
        self._closest = math.inf

    def bodies(self, contacts: int, closest: float) -> None:
        """A world step had ``contacts`` contacts and ``closest`` [m] as its smallest
        robot-robot centre distance (:attr:`sim_bridge.world.World.last_contacts`)."""
        self._contacts += contacts
        self._closest = min(self._closest, closest)

    def command(self, robot_id: int, latency: float) -> None:
        """A cmd_vel of ``robot_id`` arrived ``latency`` wall seconds after the newest
        state was published."""
        self._counts[robot_id] += 1
        self._histogram[latency_bin(latency)] += 1
        if self._latency_max is None or latency > self._latency_max:
            self._latency_max = latency

    def snapshot(self, now: float, step: int) -> dict[str, Any]:
        """The figures since the last snapshot, then start counting again.

        ``wall_s`` and ``sim_s`` elapsed (their ratio is ``real_time_factor``),
        per-robot ``cmd_vel`` rates [Hz of wall time] (min, median), and the
        latencies [ms] (p50, p99, max; None without commands); ``contacts_per_s``
        (contacts counted over the steps, per second of sim time) and
        ``min_centre_distance_m`` (the smallest robot-robot centre distance after any of
        those steps; None without a step or with one robot).
        """
        wall0, step0 = self._since
        wall = now - wall0
        rates = self._counts / wall if wall > 0 else np.zeros(self.n)
        seen = int(self._histogram.sum())
        stats: dict[str, Any] = {
            "robots": self.n,
            "wall_s": wall,
            "sim_s": (step - step0) * self.dt,
            "rate_min_hz": float(rates.min()) if self.n else 0.0,
            "rate_median_hz": float(np.median(rates)) if self.n else 0.0,
            "commands": int(self._counts.sum()),
            "latency_p50_ms": _percentile(self._histogram, 50) * 1e3 if seen else None,
            "latency_p99_ms": _percentile(self._histogram, 99) * 1e3 if seen else None,
            "latency_max_ms": self._latency_max * 1e3 if self._latency_max is not None else None,
            "contacts": self._contacts,
        }
        stats["contacts_per_s"] = self._contacts / stats["sim_s"] if stats["sim_s"] > 0 else 0.0
        stats["min_centre_distance_m"] = self._closest if math.isfinite(self._closest) else None
        stats["real_time_factor"] = stats["sim_s"] / wall if wall > 0 else 0.0
        self._reset(now, step)
        return stats


def latency_bin(latency: float) -> int:
    """The histogram bin of ``latency`` [s] (clipped to the first and last bins)."""
    if not latency > LATENCY_MIN:  # also NaN
        return 0
    k = int(np.log10(latency / LATENCY_MIN) * BINS_PER_DECADE)
    return min(k, len(_MIDDLES) - 1)


def _percentile(histogram: np.ndarray, q: float) -> float:
    """The ``q``-th percentile [s] of the latencies counted in ``histogram`` (the
    middle of the bin holding it: within 1 % of the exact value)."""
    cumulative = np.cumsum(histogram)
    k = int(np.searchsorted(cumulative, q / 100.0 * cumulative[-1]))
    return float(_MIDDLES[min(k, len(_MIDDLES) - 1)])

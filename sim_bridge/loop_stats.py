"""Figures of the bridge's control loop, for ``/sim/stats`` and the benchmark (pure)."""

from __future__ import annotations

from typing import Any

import numpy as np

#: At most this many cmd_vel latencies are kept between two snapshots.
MAX_LATENCY_SAMPLES = 2_000_000


class ControlLoopStats:
    """Commands per robot and their latencies since the last :meth:`snapshot`.

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
        self._latencies: list[float] = []

    def command(self, robot_id: int, latency: float) -> None:
        """A cmd_vel of ``robot_id`` arrived ``latency`` wall seconds after the newest
        state was published."""
        self._counts[robot_id] += 1
        if len(self._latencies) < MAX_LATENCY_SAMPLES:
            self._latencies.append(latency)

    def snapshot(self, now: float, step: int) -> dict[str, Any]:
        """The figures since the last snapshot, then start counting again.

        ``wall_s`` and ``sim_s`` elapsed (their ratio is ``real_time_factor``),
        per-robot ``cmd_vel`` rates [Hz of wall time] (min, median), and the
        latencies [ms] (p50, p99, max; None without commands).
        """
        wall0, step0 = self._since
        wall = now - wall0
        rates = self._counts / wall if wall > 0 else np.zeros(self.n)
        lat = np.asarray(self._latencies) * 1e3
        stats: dict[str, Any] = {
            "robots": self.n,
            "wall_s": wall,
            "sim_s": (step - step0) * self.dt,
            "rate_min_hz": float(rates.min()) if self.n else 0.0,
            "rate_median_hz": float(np.median(rates)) if self.n else 0.0,
            "commands": int(self._counts.sum()),
            "latency_p50_ms": float(np.percentile(lat, 50)) if lat.size else None,
            "latency_p99_ms": float(np.percentile(lat, 99)) if lat.size else None,
            "latency_max_ms": float(lat.max()) if lat.size else None,
        }
        stats["real_time_factor"] = stats["sim_s"] / wall if wall > 0 else 0.0
        self._reset(now, step)
        return stats

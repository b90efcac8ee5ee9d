"""The lines a run prints: its one-line summary at the end, a progress line as it goes."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from aes_ros import metrics
from aes_ros.metrics_csv import CSV_COLUMNS


def summary(table: dict[str, np.ndarray], label: str, n_robots: int, runs: int = 1) -> str:
    """One line: displacement, speed and direction of the centroid, final order, rotation."""
    tail = slice(len(table["t"]) // 2, None)  # second half: after the transient
    return summary_line(
        {c: table[c][0] for c in CSV_COLUMNS},
        {c: table[c][-1] for c in CSV_COLUMNS},
        float(np.mean(table["angular_velocity"][tail])),
        label, n_robots, runs,
    )  # fmt: skip


def summary_line(
    first: Mapping[str, float],
    last: Mapping[str, float],
    omega_tail: float,
    label: str,
    n_robots: int,
    runs: int = 1,
) -> str:
    """:func:`summary` from the first and the last row of the metrics and the mean
    angular velocity [rad/s] over their second half (what :class:`MetricsDigest` has)."""
    dx = last["centroid_x"] - first["centroid_x"]
    dy = last["centroid_y"] - first["centroid_y"]
    duration = last["t"] - first["t"]
    speed = math.hypot(dx, dy) / duration if duration > 0 else 0.0
    heading = math.degrees(math.atan2(dy, dx))
    return (
        f"{label}: N={n_robots} runs={runs} t={duration:.1f}s  centroid moved "
        f"{math.hypot(dx, dy):.2f} m at {speed:.3f} m/s toward {heading:.0f} deg  "
        f"psi={last['alignment']:.3f} psi_heading={last['heading_order']:.3f} "
        f"F={last['total_force']:.2f}  "
        f"omega={omega_tail:+.3f} rad/s"
    )


def progress(t: float, positions: np.ndarray, headings: np.ndarray) -> str:
    """One line on a run as it goes: sim time ``t`` [s], the centroid [m] and the
    heading order of one sample (positions (N, 2) [m], headings (N,) [rad])."""
    c = positions.mean(axis=0)
    order = float(metrics.heading_order(headings))
    return f"t = {t:6.1f} s  centroid ({c[0]:+.2f}, {c[1]:+.2f}) m  heading order {order:.3f}"

"""Run outputs shared by ``aes-swarm simulate`` and ``aes-swarm launch``.

From a trajectory this writes ``trajectory.npz``, ``metrics.csv``,
``snapshots.png`` and ``metrics.png`` and returns a one-line summary, so the
offline simulator and the ROS system report the same things the same way.

``trajectory.npz`` has one layout whichever command wrote it:

- ``times`` : (T,) [s] (sim time for ``launch``);
- ``positions`` : (B, T, N, 2) [m; odom];
- ``headings`` : (B, T, N) [rad];

with B the number of runs (``simulate --runs B``; 1 for ``launch``). Read it with
:func:`load_trajectory`.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aes_ros import metrics, plots
from aes_ros.model import total_forces
from aes_ros.scenario import Scenario

CSV_COLUMNS = (
    "t", "alignment", "heading_order", "total_force", "centroid_x", "centroid_y",
    "angular_velocity",
)  # fmt: skip


@dataclass(frozen=True)
class Trajectory:
    """A run's samples: times (T,) [s], positions (B, T, N, 2) [m], headings (B, T, N) [rad]."""

    times: np.ndarray
    positions: np.ndarray
    headings: np.ndarray


def load_trajectory(path: Path) -> Trajectory:
    """Read a ``trajectory.npz`` written by ``simulate`` or ``launch``."""
    with np.load(path) as data:
        return Trajectory(data["times"], data["positions"], data["headings"])


def metrics_table(
    times: np.ndarray, positions: np.ndarray, headings: np.ndarray, scenario: Scenario
) -> dict[str, np.ndarray]:
    """Metrics of a trajectory, one row per sample.

    times : (T,) [s]; positions : (..., T, N, 2) [m]; headings : (..., T, N) [rad].
    Leading run axes are averaged. ψ, ψ_heading and F use the noise-free force
    (E4) with the scenario's gains and command. ``angular_velocity`` [rad/s] at
    sample k is the rigid rotation from k-1 to k (at k = 0: from 0 to 1).

    Returns a dict of (T,) arrays keyed by :data:`CSV_COLUMNS`.
    """
    _, neighbors, rest = scenario.sheet()
    forces = total_forces(positions, neighbors, rest, scenario.gains, scenario.command)
    omega = metrics.angular_velocity(positions, np.diff(times))
    omega = np.concatenate([omega[..., :1], omega], axis=-1)
    centroid = positions.mean(axis=-2)
    runs = tuple(range(positions.ndim - 3))
    table = {
        "t": times,
        "alignment": metrics.alignment_order(forces, headings),
        "heading_order": metrics.heading_order(headings),
        "total_force": metrics.total_force(forces),
        "centroid_x": centroid[..., 0],
        "centroid_y": centroid[..., 1],
        "angular_velocity": omega,
    }
    return {k: (v if k == "t" else v.mean(axis=runs)) for k, v in table.items()}


def write_metrics_csv(path: Path, table: dict[str, np.ndarray]) -> None:
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(CSV_COLUMNS)
        for row in zip(*(table[c] for c in CSV_COLUMNS), strict=True):
            writer.writerow([f"{v:.6g}" for v in row])


def summary(table: dict[str, np.ndarray], label: str, n_robots: int, runs: int = 1) -> str:
    """One line: displacement, speed and direction of the centroid, final order, rotation."""
    t = table["t"]
    dx = table["centroid_x"][-1] - table["centroid_x"][0]
    dy = table["centroid_y"][-1] - table["centroid_y"][0]
    duration = t[-1] - t[0]
    speed = math.hypot(dx, dy) / duration if duration > 0 else 0.0
    heading = math.degrees(math.atan2(dy, dx))
    tail = slice(len(t) // 2, None)  # second half: after the transient
    return (
        f"{label}: N={n_robots} runs={runs} t={duration:.1f}s  centroid moved "
        f"{math.hypot(dx, dy):.2f} m at {speed:.3f} m/s toward {heading:.0f} deg  "
        f"psi={table['alignment'][-1]:.3f} psi_heading={table['heading_order'][-1]:.3f} "
        f"F={table['total_force'][-1]:.2f}  "
        f"omega={np.mean(table['angular_velocity'][tail]):+.3f} rad/s"
    )


def write_run_outputs(
    out_dir: Path,
    times: np.ndarray,
    positions: np.ndarray,
    headings: np.ndarray,
    scenario: Scenario,
    label: str = "run",
) -> str:
    """Write trajectory.npz, metrics.csv, snapshots.png and metrics.png; return the summary.

    times : (T,) [s]; positions : (B, T, N, 2) [m]; headings : (B, T, N) [rad]
    (the layout of ``trajectory.npz``). With B > 1 runs, metrics.csv holds the
    mean over runs and the snapshots show run 0.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    positions = np.asarray(positions, dtype=float)
    headings = np.asarray(headings, dtype=float)
    if positions.ndim != 4 or headings.ndim != 3:
        raise ValueError(
            f"positions {positions.shape}, headings {headings.shape}: need (B, T, N, 2), (B, T, N)"
        )
    np.savez_compressed(out_dir / "trajectory.npz", times=times, positions=positions,
                        headings=headings)  # fmt: skip
    table = metrics_table(times, positions, headings, scenario)
    write_metrics_csv(out_dir / "metrics.csv", table)
    _, neighbors, _ = scenario.sheet()
    runs, n = positions.shape[0], positions.shape[2]
    title = f"{label}: N = {n}" + (f", run 0 of {runs}" if runs > 1 else "")
    plots.snapshots(out_dir / "snapshots.png", times, positions[0], headings[0], neighbors, title)
    plots.metrics_plot(
        out_dir / "metrics.png", times, table["alignment"], table["heading_order"],
        table["total_force"], title=label + (f", mean of {runs} runs" if runs > 1 else ""),
    )  # fmt: skip
    return summary(table, label, n, runs)

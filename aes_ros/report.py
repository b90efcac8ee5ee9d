"""Run outputs shared by ``aes-swarm simulate`` and ``aes-swarm launch``.

From a trajectory this writes ``trajectory.npz``, ``metrics.csv``,
``snapshots.png`` and ``metrics.png`` and returns a one-line summary, so the
offline simulator and the ROS system report the same things the same way.

``trajectory.npz`` has one layout whichever command wrote it:

- ``times`` : (T,) [s] (sim time for ``launch``);
- ``positions`` : (B, T, N, 2) [m; odom];
- ``headings`` : (B, T, N) [rad];

with B the number of runs (``simulate --runs B``; 1 for ``launch``). Read it with
:func:`load_trajectory`. While ``launch`` runs, the trajectory is in
``trajectory.parts/`` (:mod:`aes_ros.run_writer`); :func:`load_trajectory` reads
those too, and :func:`rebuild_run_outputs` (``aes-swarm report DIR``) writes every
output from them after a crash. The files are written under a temporary name and
renamed, so each is either complete or absent.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from aes_ros import metrics
from aes_ros import scenario as scenario_mod
from aes_ros.model import total_forces
from aes_ros.scenario import Scenario

CSV_COLUMNS = (
    "t", "alignment", "heading_order", "total_force", "centroid_x", "centroid_y",
    "angular_velocity",
)  # fmt: skip
#: Where a running launch keeps its trajectory, one ``part-NNNNNN.npz`` per flush.
PARTS_DIR = "trajectory.parts"


@dataclass(frozen=True)
class Trajectory:
    """A run's samples: times (T,) [s], positions (B, T, N, 2) [m], headings (B, T, N) [rad]."""

    times: np.ndarray
    positions: np.ndarray
    headings: np.ndarray


def load_trajectory(path: Path) -> Trajectory:
    """Read a ``trajectory.npz`` written by ``simulate`` or ``launch``, or a run
    directory: its ``trajectory.npz``, else the parts of a run still going or cut
    short (concatenated in order)."""
    path = Path(path)
    run_dir = path if path.is_dir() else path.parent
    npz = path if not path.is_dir() else path / "trajectory.npz"
    if npz.exists():
        with np.load(npz) as data:
            return Trajectory(data["times"], data["positions"], data["headings"])
    parts = sorted((run_dir / PARTS_DIR).glob("part-*.npz"))
    if not parts:
        raise FileNotFoundError(f"{run_dir}: no trajectory.npz and no {PARTS_DIR}/")
    loaded = []
    for part in parts:
        with np.load(part) as data:
            loaded.append((data["times"], data["positions"], data["headings"]))
    return Trajectory(
        np.concatenate([t for t, _, _ in loaded]),
        np.concatenate([p for _, p, _ in loaded], axis=1),
        np.concatenate([h for _, _, h in loaded], axis=1),
    )


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
    """``metrics.csv``: a header of :data:`CSV_COLUMNS`, one row per sample (6 digits)."""
    with _replacing(path, "w", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(CSV_COLUMNS)
        for row in zip(*(table[c] for c in CSV_COLUMNS), strict=True):
            writer.writerow([f"{v:.6g}" for v in row])


@contextlib.contextmanager
def _replacing(path: Path, mode: str, **kwargs: Any) -> Iterator[IO]:
    """A file opened under a temporary name next to ``path``, renamed to ``path`` when
    the block ends without error: readers see the old file or the new one, never half."""
    path = Path(path)
    temporary = path.with_name("." + path.name + ".tmp")
    try:
        with open(temporary, mode, **kwargs) as fh:
            yield fh
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


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


def progress(t: float, positions: np.ndarray, headings: np.ndarray) -> str:
    """One line on a run as it goes: sim time ``t`` [s], the centroid [m] and the
    heading order of one sample (positions (N, 2) [m], headings (N,) [rad])."""
    c = positions.mean(axis=0)
    order = float(metrics.heading_order(headings))
    return f"t = {t:6.1f} s  centroid ({c[0]:+.2f}, {c[1]:+.2f}) m  heading order {order:.3f}"


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
    with _replacing(out_dir / "trajectory.npz", "wb") as fh:
        np.savez_compressed(fh, times=times, positions=positions, headings=headings)
    table = metrics_table(times, positions, headings, scenario)
    write_metrics_csv(out_dir / "metrics.csv", table)
    # matplotlib only here: importing it costs a launcher 25 MB and half a second at start.
    from aes_ros import plots

    _, neighbors, _ = scenario.sheet()
    runs, n = positions.shape[0], positions.shape[2]
    title = f"{label}: N = {n}" + (f", run 0 of {runs}" if runs > 1 else "")
    plots.snapshots(out_dir / "snapshots.png", times, positions[0], headings[0], neighbors, title)
    plots.metrics_plot(
        out_dir / "metrics.png", times, table["alignment"], table["heading_order"],
        table["total_force"], title=label + (f", mean of {runs} runs" if runs > 1 else ""),
    )  # fmt: skip
    return summary(table, label, n, runs)


def rebuild_run_outputs(out_dir: Path) -> str:
    """Every output of a run directory from what is on disk (``aes-swarm report DIR``).

    For a launch cut short (the launcher killed, the machine down): the trajectory
    from ``trajectory.parts/`` (or ``trajectory.npz``), the scenario from
    ``scenario.yaml``, the label from ``run.json``. Writes ``trajectory.npz``,
    ``metrics.csv`` and the plots, removes the parts, returns the summary line.
    """
    out_dir = Path(out_dir)
    scenario_file = out_dir / "scenario.yaml"
    if not scenario_file.exists():
        raise FileNotFoundError(f"{out_dir}: no scenario.yaml (not the output of a launch?)")
    scenario = scenario_mod.load(scenario_file)
    trajectory = load_trajectory(out_dir)
    if len(trajectory.times) < 2:
        raise ValueError(f"{out_dir}: {len(trajectory.times)} samples; need at least two")
    label = "run"
    run_file = out_dir / "run.json"
    if run_file.exists():
        label = json.loads(run_file.read_text()).get("label", label)
    summary = write_run_outputs(
        out_dir, trajectory.times, trajectory.positions, trajectory.headings, scenario, label
    )
    shutil.rmtree(out_dir / PARTS_DIR, ignore_errors=True)
    return summary

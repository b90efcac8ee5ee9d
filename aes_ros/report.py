"""Run outputs shared by ``aes-swarm simulate`` and ``aes-swarm launch``.

A run directory holds ``trajectory.h5`` (every sample; the layout in
:mod:`aes_ros.trajectory_file`), ``metrics.csv`` (one row per sample,
:mod:`aes_ros.metrics_csv`), ``snapshots.png`` and ``metrics.png``, and the run ends with a
one-line summary, so the offline simulator and the ROS system report the same
things the same way.

``simulate`` has its trajectory in memory and writes everything at the end
(:func:`write_run_outputs`). ``launch`` streams the samples to ``trajectory.h5`` and
the rows to ``metrics.csv`` while it runs (:mod:`aes_ros.run_writer`), and at the
end draws the plots and the summary from the disk (:func:`finish_run_outputs`) in
memory bounded independent of the run's length: the snapshots need a few samples
and one pass over run 0, ``metrics.png`` at most
:data:`~aes_ros.snapshot_view.MAX_PLOT_SAMPLES` rows of ``metrics.csv``, and the
summary of a long run comes from ``metrics.csv`` read a block at a time.
:func:`rebuild_run_outputs` (``aes-swarm report DIR``) writes every output of a launch
cut short.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from aes_ros import scenario as scenario_mod
from aes_ros.metrics_csv import (
    metrics_table,
    read_metrics_csv,
    write_metrics_csv,
    write_metrics_csv_from,
)
from aes_ros.run_summary import summary, summary_line
from aes_ros.scenario import Scenario
from aes_ros.snapshot_view import snapshot_view
from aes_ros.trajectory import TRAJECTORY_FILE
from aes_ros.trajectory_file import open_trajectory, seal, write_trajectory

#: A trajectory up to this many bytes is loaded whole for the summary (exact, as the
#: whole-run metrics give it); a larger one is summarised from ``metrics.csv``.
SUMMARY_LOAD_BYTES = 8 * 1024 * 1024


def write_run_outputs(
    out_dir: Path,
    times: np.ndarray,
    positions: np.ndarray,
    headings: np.ndarray,
    scenario: Scenario,
    label: str = "run",
) -> str:
    """Write trajectory.h5, metrics.csv, snapshots.png and metrics.png of a trajectory
    in memory (``aes-swarm simulate``); return the summary.

    times : (T,) [s]; positions : (B, T, N, 2) [m]; headings : (B, T, N) [rad]
    (the layout of ``trajectory.h5``). With B > 1 runs, metrics.csv holds the
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
    write_trajectory(out_dir / TRAJECTORY_FILE, times, positions, headings)
    table = metrics_table(times, positions, headings, scenario)
    write_metrics_csv(out_dir / "metrics.csv", table)
    return finish_run_outputs(out_dir, scenario, label, table=table)


def finish_run_outputs(
    out_dir: Path,
    scenario: Scenario,
    label: str = "run",
    table: dict[str, np.ndarray] | None = None,
) -> str:
    """snapshots.png, metrics.png and the summary of a run whose ``trajectory.h5`` and
    ``metrics.csv`` are on disk, in memory bounded independent of the run's length.

    The snapshots come from one pass over run 0 a block at a time; metrics.png from
    at most :data:`~aes_ros.snapshot_view.MAX_PLOT_SAMPLES` rows of metrics.csv. The
    summary is that of ``table`` (the run's :func:`~aes_ros.metrics_csv.metrics_table`)
    if given, else of the whole trajectory loaded if it holds at most
    :data:`SUMMARY_LOAD_BYTES`, else of metrics.csv (the same numbers to its 6 digits).
    """
    out_dir = Path(out_dir)
    with open_trajectory(out_dir) as traj:
        runs, n = traj.runs, traj.robots
        if traj.n_samples < 2:
            raise ValueError(f"{out_dir}: {traj.n_samples} samples; need at least two")
        view = snapshot_view(traj.blocks(run=0), traj.n_samples)
        if table is None and traj.nbytes <= SUMMARY_LOAD_BYTES:
            table = metrics_table(*traj.read(slice(None)), scenario)
    digest = read_metrics_csv(out_dir / "metrics.csv")
    # matplotlib only here: importing it costs a launcher 25 MB and half a second at start.
    from aes_ros import plots

    _, neighbors, _ = scenario.sheet()
    title = f"{label}: N = {n}" + (f", run 0 of {runs}" if runs > 1 else "")
    plots.snapshots(out_dir / "snapshots.png", view, neighbors, title)
    rows = digest.rows
    plots.metrics_plot(
        out_dir / "metrics.png", rows["t"], rows["alignment"], rows["heading_order"],
        rows["total_force"], title=label + (f", mean of {runs} runs" if runs > 1 else ""),
    )  # fmt: skip
    if table is not None:
        return summary(table, label, n, runs)
    return summary_line(digest.first, digest.last, digest.omega_tail, label, n, runs)


def rebuild_run_outputs(out_dir: Path) -> str:
    """Every output of a run directory from what is on disk (``aes-swarm report DIR``).

    For a launch cut short (the launcher killed, the machine down): the trajectory
    from ``trajectory.h5`` (its samples complete at the last flush), the scenario from
    ``scenario.yaml``, the label from ``run.json``. Rewrites ``trajectory.h5`` closed
    if its writer left it open (:func:`aes_ros.trajectory_file.seal`, so that every
    HDF5 reader opens it), ``metrics.csv`` from the trajectory (a block at a time),
    and the plots; returns the summary line.
    """
    out_dir = Path(out_dir)
    scenario_file = out_dir / "scenario.yaml"
    if not scenario_file.exists():
        raise FileNotFoundError(f"{out_dir}: no scenario.yaml (not the output of a launch?)")
    if not (out_dir / TRAJECTORY_FILE).exists():
        raise FileNotFoundError(f"{out_dir}: no {TRAJECTORY_FILE}")
    scenario = scenario_mod.load(scenario_file)
    with open_trajectory(out_dir) as traj:
        if traj.n_samples < 2:
            raise ValueError(f"{out_dir}: {traj.n_samples} samples; need at least two")
    seal(out_dir)
    with open_trajectory(out_dir) as traj:
        write_metrics_csv_from(out_dir / "metrics.csv", traj, scenario)
    label = "run"
    run_file = out_dir / "run.json"
    if run_file.exists():
        label = json.loads(run_file.read_text()).get("label", label)
    return finish_run_outputs(out_dir, scenario, label)


def main(argv: list[str] | None = None) -> int:
    """``python -m aes_ros.report OUT_DIR SCENARIO_FILE LABEL``: the plots and the
    summary of a run whose files are complete (:func:`finish_run_outputs`), in a
    process of their own (:meth:`aes_ros.run_writer.RunWriter.finish`); prints the
    summary line."""
    import sys

    out_dir, scenario_file, label = argv if argv is not None else sys.argv[1:]
    print(finish_run_outputs(Path(out_dir), scenario_mod.load(Path(scenario_file)), label))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Run outputs shared by ``aes-swarm simulate`` and ``aes-swarm launch``.

A run directory holds ``trajectory.h5`` (every sample; the layout in
:mod:`aes_ros.trajectory_file`), ``metrics.csv`` (one row per sample,
:data:`CSV_COLUMNS`), ``snapshots.png`` and ``metrics.png``, and the run ends with a
one-line summary, so the offline simulator and the ROS system report the same
things the same way.

``simulate`` has its trajectory in memory and writes everything at the end
(:func:`write_run_outputs`). ``launch`` streams the samples to ``trajectory.h5`` and
the rows to ``metrics.csv`` while it runs (:mod:`aes_ros.run_writer`), and at the
end draws the plots and the summary from the disk (:func:`finish_run_outputs`) in
memory bounded independent of the run's length: the snapshots need a few samples
and one pass over run 0, ``metrics.png`` at most :data:`MAX_PLOT_SAMPLES` rows of
``metrics.csv``, and the summary of a long run comes from ``metrics.csv`` read a
block at a time. :func:`load_trajectory` reads a trajectory whole, a slice or every
k-th sample, :func:`trajectory_samples` chosen samples; :func:`rebuild_run_outputs`
(``aes-swarm report DIR``) writes every output of a launch cut short.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from aes_ros import metrics
from aes_ros import scenario as scenario_mod
from aes_ros.model import total_forces
from aes_ros.scenario import Scenario
from aes_ros.trajectory_file import (
    FILE_NAME,
    TrajectoryFile,
    open_trajectory,
    seal,
    write_trajectory,
)

CSV_COLUMNS = (
    "t", "alignment", "heading_order", "total_force", "centroid_x", "centroid_y",
    "angular_velocity",
)  # fmt: skip
#: The trajectory's file name in a run directory.
TRAJECTORY_FILE = FILE_NAME
#: At most this many samples on a plot's time axis (every k-th sample, and the last).
MAX_PLOT_SAMPLES = 2000
#: A trajectory up to this many bytes is loaded whole for the summary (exact, as the
#: whole-run metrics give it); a larger one is summarised from ``metrics.csv``.
SUMMARY_LOAD_BYTES = 8 * 1024 * 1024
#: Bytes of metrics.csv parsed at once (some 10^4 rows).
CSV_BLOCK_BYTES = 1024 * 1024


@dataclass(frozen=True)
class Trajectory:
    """A run's samples: times (T,) [s], positions (B, T, N, 2) [m], headings (B, T, N) [rad]."""

    times: np.ndarray
    positions: np.ndarray
    headings: np.ndarray


def load_trajectory(
    path: Path, every: int = 1, *, start: int = 0, stop: int | None = None
) -> Trajectory:
    """Read ``trajectory.h5`` (the file, or a run directory holding it): samples
    ``start``, ``start + every``, … before ``stop`` (default: all of them).

    Reads what a run still going or cut short has on disk (its complete samples), and
    only the samples asked for: ``every=k`` of a long run costs 1/k of its memory.
    """
    if every < 1:
        raise ValueError(f"every={every}: need an integer >= 1")
    with open_trajectory(path) as traj:
        return Trajectory(*traj.read(slice(start, stop, every)))


def trajectory_samples(path: Path, indices: Iterable[int]) -> Trajectory:
    """The samples at ``indices`` (any order, repeats allowed; negative counts from
    the end) of ``trajectory.h5`` (the file or a run directory), in that order."""
    with open_trajectory(path) as traj:
        wanted = np.asarray(list(indices), dtype=np.int64)
        wanted = np.where(wanted < 0, wanted + traj.n_samples, wanted)
        if wanted.size and (wanted.min() < 0 or wanted.max() >= traj.n_samples):
            raise IndexError(f"sample indices out of [0, {traj.n_samples})")
        unique, order = np.unique(wanted, return_inverse=True)
        times, positions, headings = traj.read(unique)
    return Trajectory(times[order], positions[:, order], headings[:, order])


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


def metrics_rows(
    times: np.ndarray,
    positions: np.ndarray,
    headings: np.ndarray,
    scenario: Scenario,
    previous: Trajectory | None = None,
) -> dict[str, np.ndarray]:
    """:func:`metrics_table` of a block of samples that follows ``previous``.

    times : (T,) [s]; positions : (..., T, N, 2) [m]; headings : (..., T, N) [rad];
    previous : the sample just before them (times (1,), positions (..., 1, N, 2),
    headings (..., 1, N)), or None for the run's first block (then T >= 2).

    Returns the (T,) rows of the block, equal to those of the whole run's table
    (each row needs only its sample and the one before), so a run's metrics can be
    computed a block at a time.
    """
    if previous is not None:
        times = np.concatenate([previous.times, times])
        positions = np.concatenate([previous.positions, positions], axis=-3)
        headings = np.concatenate([previous.headings, headings], axis=-2)
    table = metrics_table(times, positions, headings, scenario)
    first = 0 if previous is None else 1
    return {k: v[first:] for k, v in table.items()}


def csv_rows(table: Mapping[str, np.ndarray]) -> bytes:
    """The ``metrics.csv`` lines of a table (:data:`CSV_COLUMNS` order, 6 digits)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    for row in zip(*(table[c] for c in CSV_COLUMNS), strict=True):
        writer.writerow([f"{v:.6g}" for v in row])
    return buffer.getvalue().encode()


def csv_header() -> bytes:
    """The first line of ``metrics.csv``."""
    return (",".join(CSV_COLUMNS) + "\n").encode()


def write_metrics_csv(path: Path, table: dict[str, np.ndarray]) -> None:
    """``metrics.csv``: a header of :data:`CSV_COLUMNS`, one row per sample (6 digits)."""
    with _replacing(path, "wb") as fh:
        fh.write(csv_header())
        fh.write(csv_rows(table))


def write_metrics_csv_from(path: Path, traj: TrajectoryFile, scenario: Scenario) -> None:
    """``metrics.csv`` of a trajectory on disk, computed a block at a time (the same
    rows as :func:`write_metrics_csv` of its whole table)."""
    previous = None
    with _replacing(path, "wb") as fh:
        fh.write(csv_header())
        for _, times, positions, headings in traj.blocks(max_bytes=1024 * 1024):
            fh.write(csv_rows(metrics_rows(times, positions, headings, scenario, previous)))
            previous = Trajectory(times[-1:], positions[:, -1:], headings[:, -1:])


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


def plot_every(n_samples: int, limit: int = MAX_PLOT_SAMPLES) -> int:
    """The k of "every k-th sample" that keeps at most ``limit`` samples (plus the last)."""
    return max(1, math.ceil(n_samples / limit))


@dataclass(frozen=True)
class MetricsDigest:
    """What the plots and the summary need of a ``metrics.csv``, read a block at a time.

    rows : every :func:`plot_every`-th row and the last, keyed by :data:`CSV_COLUMNS`.
    n_rows : rows in the file; first, last : its first and last row.
    omega_tail : mean ``angular_velocity`` [rad/s] over rows ``n_rows // 2`` onwards.
    """

    rows: dict[str, np.ndarray]
    n_rows: int
    first: dict[str, float]
    last: dict[str, float]
    omega_tail: float


def read_metrics_csv(path: Path, max_rows: int = MAX_PLOT_SAMPLES) -> MetricsDigest:
    """Read ``metrics.csv`` :data:`CSV_BLOCK_BYTES` at a time (memory bounded whatever
    its length) into a :class:`MetricsDigest`; only complete lines count."""
    path = Path(path)
    with open(path, "rb") as fh:
        n_rows = sum(chunk.count(b"\n") for chunk in iter(lambda: fh.read(CSV_BLOCK_BYTES), b""))
    n_rows -= 1  # the header
    if n_rows < 1:
        raise ValueError(f"{path}: no rows")
    every = plot_every(n_rows, max_rows)
    tail = n_rows // 2
    kept: list[np.ndarray] = []
    omega_sum, first, last = 0.0, None, None
    with open(path, "rb") as fh:
        header = fh.readline().decode().strip().split(",")
        if tuple(header) != CSV_COLUMNS:
            raise ValueError(f"{path}: columns {header}, expected {list(CSV_COLUMNS)}")
        start, rest = 0, b""
        while start < n_rows and (data := fh.read(CSV_BLOCK_BYTES)):
            data = rest + data
            cut = data.rfind(b"\n") + 1  # whole lines now, the rest with the next read
            data, rest = data[:cut], data[cut:]
            if not data:
                continue
            block = _parse_rows(data, path)
            index = np.arange(start, start + len(block))
            first = block[0] if first is None else first
            last = block[-1]
            keep = (index % every == 0) | (index == n_rows - 1)
            kept.append(block[keep])
            omega_sum += float(block[index >= tail, CSV_COLUMNS.index("angular_velocity")].sum())
            start += len(block)
    rows = np.concatenate(kept)
    return MetricsDigest(
        rows={c: rows[:, i] for i, c in enumerate(CSV_COLUMNS)},
        n_rows=n_rows,
        first=dict(zip(CSV_COLUMNS, map(float, first), strict=True)),
        last=dict(zip(CSV_COLUMNS, map(float, last), strict=True)),
        omega_tail=omega_sum / (n_rows - tail),
    )


def _parse_rows(lines: bytes, path: Path) -> np.ndarray:
    """Whole ``metrics.csv`` lines as a (rows, 7) array (numpy's C parser: loadtxt
    is as fast, but four times slower under tracemalloc, which the tests use)."""
    n_lines = lines.count(b"\n")
    values = np.fromstring(lines[:-1].replace(b"\n", b",").decode(), sep=",")
    if values.size != n_lines * len(CSV_COLUMNS):
        raise ValueError(f"{path}: a row without {len(CSV_COLUMNS)} numbers")
    return values.reshape(n_lines, len(CSV_COLUMNS))


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


@dataclass(frozen=True)
class SnapshotView:
    """What ``snapshots.png`` draws of one run.

    times : (P,) [s], positions : (P, N, 2) [m], headings : (P, N) [rad] of the panels'
    samples (the first is the run's first sample); track_times : (M,) [s] and track :
    (M, 2) [m], the centroid at every k-th sample and at the panels' samples; lo, hi :
    (2,) [m], the corners of a box around every position of the run.
    """

    times: np.ndarray
    positions: np.ndarray
    headings: np.ndarray
    track_times: np.ndarray
    track: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def snapshot_view(
    blocks: Iterable[tuple[int, np.ndarray, np.ndarray, np.ndarray]],
    n_samples: int,
    panels: int = 4,
    max_track: int = MAX_PLOT_SAMPLES,
) -> SnapshotView:
    """The :class:`SnapshotView` of a run read once, in order, a block at a time.

    blocks : (index of the block's first sample, times (k,) [s], positions (k, N, 2)
    [m], headings (k, N) [rad]), covering samples 0 … ``n_samples`` - 1 in order
    (:meth:`~aes_ros.trajectory_file.TrajectoryFile.blocks` of one run). The panels
    are ``panels`` samples evenly spaced from the first to the last; the centroid
    track keeps at most about ``max_track`` samples.
    """
    chosen = np.linspace(0, n_samples - 1, panels).round().astype(int)
    track_index = np.union1d(np.arange(0, n_samples, plot_every(n_samples, max_track)), chosen)
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    panel: dict[int, tuple[float, np.ndarray, np.ndarray]] = {}
    track_times, track = [], []
    for start, times, positions, headings in blocks:
        lo = np.minimum(lo, positions.min(axis=(0, 1)))
        hi = np.maximum(hi, positions.max(axis=(0, 1)))
        inside = track_index[(track_index >= start) & (track_index < start + len(times))] - start
        track_times.append(times[inside])
        track.append(positions[inside].mean(axis=-2))
        for k in chosen[(chosen >= start) & (chosen < start + len(times))]:
            # copies: a view would keep its whole block in memory
            panel[int(k)] = (
                times[k - start],
                positions[k - start].copy(),
                headings[k - start].copy(),
            )
    return SnapshotView(
        times=np.array([panel[k][0] for k in chosen]),
        positions=np.stack([panel[k][1] for k in chosen]),
        headings=np.stack([panel[k][2] for k in chosen]),
        track_times=np.concatenate(track_times),
        track=np.concatenate(track),
        lo=lo,
        hi=hi,
    )


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
    at most :data:`MAX_PLOT_SAMPLES` rows of metrics.csv. The summary is that of
    ``table`` (the run's :func:`metrics_table`) if given, else of the whole trajectory
    loaded if it holds at most :data:`SUMMARY_LOAD_BYTES`, else of metrics.csv (the
    same numbers to its 6 digits).
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

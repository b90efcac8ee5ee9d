"""A run's metrics, one row per sample, and ``metrics.csv`` both ways: written whole or a
block at a time (:func:`metrics_rows` gives the same rows), read back a block at a time
in memory bounded whatever its length (:func:`read_metrics_csv`)."""

from __future__ import annotations

import contextlib
import csv
import io
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from aes_ros import metrics
from aes_ros.contact_measures import contacts_over_time
from aes_ros.model import total_forces
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.obstacles import contact_arrays
from aes_ros.scenario import Scenario
from aes_ros.snapshot_view import MAX_PLOT_SAMPLES, plot_every
from aes_ros.trajectory import Trajectory
from aes_ros.trajectory_file import TrajectoryFile

CSV_COLUMNS = (
    "t", "alignment", "heading_order", "total_force", "centroid_x", "centroid_y",
    "angular_velocity", "contacts_per_s", "min_centre_distance",
)  # fmt: skip
#: The columns of files written before the contact columns; still read (those as NaN).
OLD_COLUMNS = CSV_COLUMNS[:7]
#: Bytes of metrics.csv parsed at once (some 10^4 rows).
CSV_BLOCK_BYTES = 1024 * 1024
#: Bodies of the contact columns (:mod:`aes_ros.contacts`).
BODY = MonaGeometry()


def metrics_table(
    times: np.ndarray, positions: np.ndarray, headings: np.ndarray, scenario: Scenario
) -> dict[str, np.ndarray]:
    """Metrics of a trajectory, one row per sample.

    times : (T,) [s]; positions : (..., T, N, 2) [m]; headings : (..., T, N) [rad].
    Leading run axes are averaged. ψ, ψ_heading and F use the noise-free force
    (E4) with the scenario's gains and command. ``angular_velocity`` [rad/s] at
    sample k is the rigid rotation from k-1 to k (at k = 0: from 0 to 1).
    ``contacts_per_s`` [1/s] is the number of bodies in contact at sample k (robot
    pairs, robots at a wall or an obstacle, overlapping or touching:
    :func:`aes_ros.contact_measures.measure_contacts`) over the interval that led to it, so its
    mean over a run is the run's contacts per second; ``min_centre_distance`` [m] is the
    smallest distance between two body centres (inf when none are within 3 body radii),
    the least over the runs.

    Returns a dict of (T,) arrays keyed by :data:`CSV_COLUMNS`.
    """
    _, neighbors, rest = scenario.sheet()
    forces = total_forces(positions, neighbors, rest, scenario.gains, scenario.command)
    omega = metrics.angular_velocity(positions, np.diff(times))
    omega = np.concatenate([omega[..., :1], omega], axis=-1)
    centroid = positions.mean(axis=-2)
    runs = tuple(range(positions.ndim - 3))
    contacts, closest = contacts_over_time(
        positions, headings, BODY.body_radius, BODY.axle_offset, *contact_arrays(scenario.values)
    )
    steps = np.diff(times)
    steps = np.concatenate([steps[:1], steps]) if len(steps) else np.ones(len(times))
    table = {
        "t": times,
        "alignment": metrics.alignment_order(forces, headings),
        "heading_order": metrics.heading_order(headings),
        "total_force": metrics.total_force(forces),
        "centroid_x": centroid[..., 0],
        "centroid_y": centroid[..., 1],
        "angular_velocity": omega,
        "contacts_per_s": contacts / steps,
    }
    table = {k: (v if k == "t" else v.mean(axis=runs)) for k, v in table.items()}
    return {**table, "min_centre_distance": closest.min(axis=runs)}


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
        if tuple(header) not in (CSV_COLUMNS, OLD_COLUMNS):
            raise ValueError(f"{path}: columns {header}, expected {list(CSV_COLUMNS)}")
        start, rest = 0, b""
        while start < n_rows and (data := fh.read(CSV_BLOCK_BYTES)):
            data = rest + data
            cut = data.rfind(b"\n") + 1  # whole lines now, the rest with the next read
            data, rest = data[:cut], data[cut:]
            if not data:
                continue
            block = _parse_rows(data, path, len(header))
            index = np.arange(start, start + len(block))
            first = block[0] if first is None else first
            last = block[-1]
            keep = (index % every == 0) | (index == n_rows - 1)
            kept.append(block[keep])
            omega_sum += float(block[index >= tail, CSV_COLUMNS.index("angular_velocity")].sum())
            start += len(block)
    rows = np.concatenate(kept)
    if len(header) < len(CSV_COLUMNS):  # a file from before the contact columns
        pad = np.full(len(CSV_COLUMNS) - len(header), np.nan)
        rows = np.hstack([rows, np.tile(pad, (len(rows), 1))])
        first, last = np.concatenate([first, pad]), np.concatenate([last, pad])
    return MetricsDigest(
        rows={c: rows[:, i] for i, c in enumerate(CSV_COLUMNS)},
        n_rows=n_rows,
        first=dict(zip(CSV_COLUMNS, map(float, first), strict=True)),
        last=dict(zip(CSV_COLUMNS, map(float, last), strict=True)),
        omega_tail=omega_sum / (n_rows - tail),
    )


def _parse_rows(lines: bytes, path: Path, columns: int) -> np.ndarray:
    """Whole ``metrics.csv`` lines as a (rows, columns) array (numpy's C parser: loadtxt
    is as fast, but four times slower under tracemalloc, which the tests use)."""
    n_lines = lines.count(b"\n")
    values = np.fromstring(lines[:-1].replace(b"\n", b",").decode(), sep=",")
    if values.size != n_lines * columns:
        raise ValueError(f"{path}: a row without {columns} numbers")
    return values.reshape(n_lines, columns)

"""What the studies share: sweeps of given points, the gain sets of the tuning study."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aes_ros.scenario import Scenario
from aes_ros.sweep.cluster import Scheduler
from aes_ros.sweep.engine import Sweep, execute
from aes_ros.sweep.spec import Axis

#: The tuning study's table (``aes-swarm study --out docs/study``): its gain sets.
STUDY_TABLE = Path(__file__).resolve().parents[2] / "docs" / "study" / "table.csv"


@dataclass(frozen=True)
class Where:
    """Where a study's sweeps run and keep their tables (resumable)."""

    work: Path
    scheduler: str | Scheduler | None = None
    workers: int | None = None
    progress: bool = True


def sweep_points(
    name: str,
    base: Scenario,
    names: list[str],
    points: np.ndarray,
    where: Where,
    *,
    mc: int,
    seed: int = 0,
    transient: float = 0.0,
    fail: tuple[float, float] | None = None,
    lhs: int | None = None,
) -> list[dict[str, Any]]:
    """Run a sweep of ``points`` (P, len(names)) into ``where.work / name``; its
    per-point summary rows (:func:`aes_ros.sweep.engine.summarize`)."""
    points = np.asarray(points, dtype=float)
    axes = [
        Axis(n, float(points[:, j].min()), float(points[:, j].max())) for j, n in enumerate(names)
    ]
    sweep = Sweep(base, axes, points, mc=mc, seed=seed, transient=transient, fail=fail, lhs=lhs)
    summary = execute(
        sweep,
        where.work / name,
        scheduler=where.scheduler,
        workers=where.workers,
        progress=where.progress,
        say=lambda line: print(f"{name}: {line}", flush=True),
    )
    with summary.open(newline="") as fh:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(fh)]


@dataclass(frozen=True)
class GainSet:
    label: str
    alpha: float
    beta: float
    k: float


def study_gain_sets(table: Path = STUDY_TABLE) -> list[GainSet]:
    """The untuned, the paper's and the TCACS gains of the tuning study's table."""
    with table.open(newline="") as fh:
        return [
            GainSet(row["gains"], float(row["alpha"]), float(row["beta"]), float(row["k"]))
            for row in csv.DictReader(fh)
        ]


def write_csv(path: Path, rows: list[dict[str, Any]]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path

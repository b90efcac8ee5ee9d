"""Running a sweep: here, on local Dask workers or on a Dask cluster; resumable; written as it goes.

``DIR/sweep.json`` says what the sweep is (scenario, axes, points, seeds); a run of
``aes-swarm sweep`` into a directory that holds another sweep is refused.
``DIR/runs.csv`` (one row per point and Monte-Carlo run, :mod:`aes_ros.sweep.runs`)
grows as tasks finish, flushed each time, so an interrupted sweep keeps every
finished point and a re-run skips them. At the end ``runs.csv`` is sorted by point
and run, ``points.csv`` has one row per point (mean and standard deviation of each
metric over its runs) and the figures are drawn (:mod:`aes_ros.sweep.figures`).

Where the tasks run:

- default: in this process, one after the other; the numba kernel spreads each
  task's runs over the local cores;
- ``workers=K``: a local Dask cluster of K worker processes (one thread each, the
  cores shared out among them);
- ``scheduler="tcp://HOST:8786"`` or a :class:`~aes_ros.sweep.cluster.Scheduler`
  (``tls://`` with certificates): an existing Dask cluster (``dask scheduler``,
  ``dask worker``); its workers need this package installed. A worker lost mid-sweep
  costs only its tasks, which Dask runs again elsewhere.

Every point's numbers depend only on its parameters and the seeds, so the three
give identical tables.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from aes_ros.scenario import Scenario
from aes_ros.scenario import defaults as scenario_defaults
from aes_ros.sweep.cluster import Scheduler
from aes_ros.sweep.runs import RUN_COLUMNS, Task, make_tasks, run_task
from aes_ros.sweep.spec import Axis, SweepSpecError

SPEC_FILE, RUNS_FILE, POINTS_FILE = "sweep.json", "runs.csv", "points.csv"


@dataclass
class Sweep:
    """One sweep: the base scenario, its axes and points, the Monte-Carlo seeds.

    points : (P, len(axes)) swept values. seeds : seed, seed+1, …, seed+mc−1 for
    every point. transient : sim seconds left out of the time averages. fail :
    (fraction, time [s]) of robots that stop moving mid-run, or None.
    """

    base: Scenario
    axes: list[Axis]
    points: np.ndarray
    mc: int = 10
    seed: int = 0
    transient: float = 0.0
    lhs: int | None = None
    fail: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.mc < 1:
            raise SweepSpecError(f"--runs {self.mc}: need at least 1 run per point")
        if not 0.0 <= self.transient < self.base.duration:
            raise SweepSpecError(
                f"--transient {self.transient:g}: need 0 <= transient < duration "
                f"({self.base.duration:g} s)"
            )
        if self.fail is not None:
            fraction, at = self.fail
            if not (0.0 <= fraction <= 1.0 and 0.0 <= at <= self.base.duration):
                raise SweepSpecError(
                    f"--fail {fraction:g}@{at:g}: need a fraction in [0, 1] and a time in "
                    f"[0, {self.base.duration:g}] s"
                )

    @property
    def names(self) -> list[str]:
        return [a.name for a in self.axes]

    @property
    def seeds(self) -> list[int]:
        return list(range(self.seed, self.seed + self.mc))

    def description(self) -> dict[str, Any]:
        """What sweep.json holds (plain JSON values)."""
        return json.loads(
            json.dumps(
                {
                    "scenario": self.base.values,
                    "axes": [a.__dict__ for a in self.axes],
                    "points": self.points.tolist(),
                    "mc": self.mc,
                    "seed": self.seed,
                    "transient": self.transient,
                    "lhs": self.lhs,
                    "fail": self.fail,
                },
                default=list,
            )
        )


def _columns(sweep: Sweep) -> list[str]:
    return ["point", "run", "seed", *sweep.names, *RUN_COLUMNS]


def prepare(sweep: Sweep, out: Path) -> set[int]:
    """Create or check ``out``; the points already finished there (all their runs)."""
    out.mkdir(parents=True, exist_ok=True)
    spec = out / SPEC_FILE
    mine = sweep.description()
    if spec.exists():
        theirs = json.loads(spec.read_text())
        # parameters added since that sweep was written ran at their defaults then
        defaults = json.loads(json.dumps(scenario_defaults(), default=list))
        theirs["scenario"] = {**defaults, **theirs.get("scenario", {})}
        if theirs != mine:
            differ = sorted(k for k in mine if theirs.get(k) != mine[k])
            raise SweepSpecError(
                f"--out {out}: holds another sweep (its {SPEC_FILE} differs in "
                f"{', '.join(differ)}); give another --out or remove it"
            )
    else:
        spec.write_text(json.dumps(mine, indent=1))
    runs = out / RUNS_FILE
    if not runs.exists():
        return set()
    with runs.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    counts: dict[int, int] = {}
    for row in rows:
        counts[int(row["point"])] = counts.get(int(row["point"]), 0) + 1
    done = {p for p, c in counts.items() if c == sweep.mc}
    if len(done) != len(counts):  # a point cut short while written: run it again
        _write_rows(runs, _columns(sweep), [r for r in rows if int(r["point"]) in done])
    return done


def _write_rows(path: Path, columns: list[str], rows: list[dict[str, Any]]) -> None:
    tmp = path.with_suffix(".tmp")
    with tmp.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, columns)
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(path)


def results(
    sweep: Sweep,
    tasks: list[Task],
    *,
    scheduler: str | Scheduler | None = None,
    workers: int | None = None,
) -> Iterator[list[dict[str, Any]]]:
    """The rows of each task as it finishes: here (default), on ``workers`` local
    Dask workers, or on the Dask cluster at ``scheduler``."""
    if scheduler is None and not workers:
        for task in tasks:
            yield _run(sweep, task)
    else:
        yield from _dask(sweep, tasks, scheduler, workers)


def _run(sweep: Sweep, task: Task) -> list[dict[str, Any]]:
    values = sweep.points[list(task.indices)]
    return run_task(
        sweep.base, sweep.names, task.indices, values, sweep.seeds, sweep.transient, sweep.fail
    )


def local_cluster(workers: int, numba_threads: int | None = None) -> Any:
    """A local Dask cluster of ``workers`` single-threaded worker processes, the cores
    shared out among their numba kernels (``numba_threads`` each; default: an even share)."""
    from dask.distributed import LocalCluster

    threads = numba_threads or max(1, (os.cpu_count() or 1) // workers)
    return LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        env={"NUMBA_NUM_THREADS": str(threads)},
    )


def _dask(
    sweep: Sweep, tasks: list[Task], scheduler: str | Scheduler | None, workers: int | None
) -> Iterator[list[dict[str, Any]]]:
    from dask.distributed import Client, as_completed

    if scheduler is not None:
        target = scheduler if isinstance(scheduler, Scheduler) else Scheduler(scheduler)
        client = target.client()
        cluster = None
    else:
        cluster = local_cluster(int(workers or 1))
        client = Client(cluster)
    try:
        futures = [
            client.submit(
                run_task,
                sweep.base,
                sweep.names,
                t.indices,
                sweep.points[list(t.indices)],
                sweep.seeds,
                sweep.transient,
                sweep.fail,
                key=f"aes-sweep-{t.indices[0]}-{len(t.indices)}",
                pure=False,
            )
            for t in tasks
        ]
        for future in as_completed(futures):
            yield future.result()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def execute(
    sweep: Sweep,
    out: Path,
    *,
    scheduler: str | Scheduler | None = None,
    workers: int | None = None,
    points_per_task: int = 4,
    progress: bool = True,
    say: Callable[[str], None] = print,
) -> Path:
    """Run every point of ``sweep`` not yet in ``out``; write the outputs; returns
    the path of ``points.csv``."""
    done = prepare(sweep, out)
    tasks = make_tasks(sweep.names, sweep.points, done, points_per_task)
    where = (
        f"on {scheduler}"
        if scheduler
        else f"on {workers} local Dask workers"
        if workers
        else "here"
    )
    say(
        f"sweep: {len(sweep.points)} points x {sweep.mc} runs, {len(done)} done before, "
        f"{len(tasks)} tasks {where}; outputs in {out}"
    )
    runs = out / RUNS_FILE
    fresh = not runs.exists()
    source = results(sweep, tasks, scheduler=scheduler, workers=workers)
    bar = tqdm(
        total=len(sweep.points), initial=len(done), unit="point", disable=not progress,
        desc="sweep",
    )  # fmt: skip
    with runs.open("a", newline="") as fh:
        writer = csv.DictWriter(fh, _columns(sweep))
        if fresh:
            writer.writeheader()
        for rows in source:
            writer.writerows(rows)
            fh.flush()
            os.fsync(fh.fileno())
            bar.update(len(rows) // sweep.mc)
    bar.close()
    return finish(sweep, out)


def finish(sweep: Sweep, out: Path) -> Path:
    """Sort ``runs.csv``, write ``points.csv`` and the figures."""
    from aes_ros.sweep.figures import plot_sweep

    with (out / RUNS_FILE).open(newline="") as fh:
        rows = sorted(csv.DictReader(fh), key=lambda r: (int(r["point"]), int(r["run"])))
    _write_rows(out / RUNS_FILE, _columns(sweep), rows)
    summary = summarize(sweep, rows)
    columns = ["point", *sweep.names, "runs"]
    columns += [f"{c}_{stat}" for c in RUN_COLUMNS for stat in ("mean", "std")]
    _write_rows(out / POINTS_FILE, columns, summary)
    plot_sweep(sweep, summary, out)
    return out / POINTS_FILE


def summarize(sweep: Sweep, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per point: its swept values, its number of runs, and the mean and
    standard deviation over its runs of every metric."""
    by_point: dict[int, list[dict[str, Any]]] = {}
    for row in rows:
        by_point.setdefault(int(row["point"]), []).append(row)
    out = []
    for point, runs in sorted(by_point.items()):
        summary: dict[str, Any] = {"point": point, "runs": len(runs)}
        summary.update({n: float(runs[0][n]) for n in sweep.names})
        for c in RUN_COLUMNS:
            values = np.array([float(r[c]) for r in runs])
            with np.errstate(invalid="ignore"):
                summary[f"{c}_mean"] = float(values.mean())
                summary[f"{c}_std"] = float(values.std())
        out.append(summary)
    return out

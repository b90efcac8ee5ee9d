"""Sweep throughput here and on local Dask workers, and Dask's overhead, side by side.

One sweep (combined setup, 100 robots, 30 s, ``--runs 10``, 12 points a task: a task
is about 1 s of one core) is run four ways in this process, each after a warm-up,
alternating, ``--trials`` times (best kept):

- ``local_1``: the tasks one after the other in a process of their own started with
  ``NUMBA_NUM_THREADS=1`` and the environment Dask gives its workers (one BLAS and
  OpenMP thread, malloc trimming; without it the local process is ~10 % slower);
- ``dask_1``: the same tasks on a local Dask cluster of 1 single-threaded worker;
- ``local_2``: the same, the kernel on 2 threads (``aes-swarm sweep`` on this machine);
- ``dask_2``: on 2 single-threaded Dask workers.

Only the task phase is timed (the cluster is started before, the figures are not
drawn). Throughput is agent-steps per second (robots × steps × runs / wall time);
Dask's overhead is its wall time against local execution on the same number of
cores (target: within 15 %). Every variant's table must equal the others'.

Usage::

    python bench/bench_sweep.py                 # ~2 min
    python bench/bench_sweep.py --points 48 --trials 1

Last line: ``RESULT local_1=… dask_1=… local_2=… dask_2=… overhead_1_pct=…
overhead_2_pct=… identical=yes targets_met=yes|no`` (throughputs in agent-steps/s).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from aes_ros import scenario
from aes_ros.cli.deprecated import add_deprecated
from aes_ros.cli.options import MAX_RUNS, number_type
from aes_ros.sweep.engine import Sweep, local_cluster, results
from aes_ros.sweep.runs import make_tasks
from aes_ros.sweep.spec import parse_axis, points

TARGET_OVERHEAD_PCT = 15.0


def make_sweep(n_points: int, mc: int) -> Sweep:
    base = scenario.load("combined").with_robots(100)
    axes = [parse_axis(f"alpha=0.02:0.3:{n_points // 4}"), parse_axis("k=0.5,1,1.5,2")]
    return Sweep(base, axes, points(axes), mc=mc)


def timed(sweep: Sweep, tasks, **where) -> tuple[float, list]:
    start = time.perf_counter()
    rows = [row for chunk in results(sweep, tasks, **where) for row in chunk]
    return time.perf_counter() - start, sorted(rows, key=lambda r: (r["point"], r["run"]))


def timed_local(threads: int, args: argparse.Namespace, work: Path) -> tuple[float, list]:
    """The tasks in a fresh process with ``NUMBA_NUM_THREADS=threads`` (warmed up first)."""
    out = work / f"local_{threads}.json"
    cmd = [sys.executable, __file__, "--child", str(out), "--points", str(args.points),
           "--runs", str(args.runs), "--points-per-task", str(args.points_per_task)]  # fmt: skip
    import dask

    # the environment Dask's nanny gives its workers (one BLAS/OpenMP thread, malloc
    # trimming): alone it makes a process about 10 % faster here, so the local runs get it too
    spawn = {k: str(v) for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()}
    env = {**os.environ, **spawn, "NUMBA_NUM_THREADS": str(threads)}
    subprocess.run(cmd, env=env, check=True)
    saved = json.loads(out.read_text())
    return saved["wall"], saved["rows"]


def child(args: argparse.Namespace) -> int:
    """``--child FILE``: warm up, time the tasks here, write the wall time and rows."""
    sweep = make_sweep(args.points, args.runs)
    warm = make_sweep(4, 1)
    timed(warm, make_tasks(warm.names, warm.points, set(), 4))
    wall, rows = timed(sweep, make_tasks(sweep.names, sweep.points, set(), args.points_per_task))
    Path(args.child).write_text(json.dumps({"wall": wall, "rows": rows}))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, default=96, help="points of the sweep")
    parser.add_argument(
        "--runs", type=number_type(int, 1, MAX_RUNS), default=10, metavar="N",
        help="Monte-Carlo runs per point (default 10)",
    )  # fmt: skip
    add_deprecated(parser, "--mc", "--runs")
    parser.add_argument("--points-per-task", type=int, default=12)
    parser.add_argument(
        "--trials", type=number_type(int, 1), default=2, metavar="N",
        help="timings of each configuration, the best kept (default 2)",
    )  # fmt: skip
    add_deprecated(parser, "--repeats", "--trials")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        return child(args)
    logging.getLogger("distributed").setLevel(logging.WARNING)
    work = Path(tempfile.mkdtemp(prefix="aes-bench-sweep-"))

    sweep = make_sweep(args.points, args.runs)
    tasks = make_tasks(sweep.names, sweep.points, set(), args.points_per_task)
    warm = make_sweep(4, 1)
    warm_tasks = make_tasks(warm.names, warm.points, set(), 4)
    n = len(sweep.base.nominal_positions())
    agent_steps = n * sweep.base.n_steps * sweep.mc * len(sweep.points)
    print(
        f"sweep: {len(sweep.points)} points x {sweep.mc} runs of {n} robots x "
        f"{sweep.base.n_steps} steps = {agent_steps:.3g} agent-steps in {len(tasks)} tasks",
        flush=True,
    )

    clusters = {}
    for k in (1, 2):
        clusters[k] = local_cluster(k, numba_threads=1)
        timed(warm, warm_tasks, scheduler=clusters[k].scheduler_address)  # JIT loaded
    best: dict[str, float] = {}
    tables: dict[str, list] = {}
    try:
        for r in range(args.trials):
            for name, k in (("local_1", 1), ("dask_1", 1), ("local_2", 2), ("dask_2", 2)):
                if name.startswith("local"):
                    wall, rows = timed_local(k, args, work)
                else:
                    wall, rows = timed(sweep, tasks, scheduler=clusters[k].scheduler_address)
                best[name] = min(best.get(name, np.inf), wall)
                tables[name] = rows
                print(f"  repeat {r}: {name:<8} {wall:6.2f} s", flush=True)
    finally:
        for cluster in clusters.values():
            cluster.close()
        shutil.rmtree(work, ignore_errors=True)
    same = json.loads(json.dumps(tables["dask_1"]))  # as the children saved theirs
    identical = all(json.loads(json.dumps(rows)) == same for rows in tables.values())
    rate = {name: agent_steps / wall for name, wall in best.items()}
    overhead = {k: 100 * (best[f"dask_{k}"] / best[f"local_{k}"] - 1) for k in (1, 2)}
    print(f"\n{'variant':<10}{'wall [s]':>10}{'agent-steps/s':>16}{'vs local':>10}")
    for name, wall in best.items():
        k = name[-1]
        ratio = wall / best[f"local_{k}"]
        print(f"{name:<10}{wall:>10.2f}{rate[name]:>16.3g}{ratio:>10.3f}")
    print(
        f"2 cores / 1 core, local: {best['local_1'] / best['local_2']:.2f}x; "
        f"Dask: {best['dask_1'] / best['dask_2']:.2f}x; tables identical: {identical}"
    )
    met = identical and max(overhead.values()) <= TARGET_OVERHEAD_PCT
    print(
        f"RESULT local_1={rate['local_1']:.3g} dask_1={rate['dask_1']:.3g} "
        f"local_2={rate['local_2']:.3g} dask_2={rate['dask_2']:.3g} "
        f"overhead_1_pct={overhead[1]:.1f} overhead_2_pct={overhead[2]:.1f} "
        f"identical={'yes' if identical else 'no'} targets_met={'yes' if met else 'no'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

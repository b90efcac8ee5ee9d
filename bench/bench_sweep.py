"""Sweep throughput here and on local Dask workers, and Dask's overhead, side by side.

One sweep (combined setup, 100 robots, 30 s, ``--mc 10``, 12 points a task: a task
is about 1 s of one core) is run four ways in this process, each after a warm-up,
alternating, ``--repeats`` times (best kept):

- ``local_1``: the tasks one after the other here, the numba kernel on 1 thread;
- ``dask_1``: the same tasks on a local Dask cluster of 1 single-threaded worker;
- ``local_2``: here, the kernel on 2 threads;
- ``dask_2``: on 2 single-threaded Dask workers.

Only the task phase is timed (the cluster is started before, the figures are not
drawn). Throughput is agent-steps per second (robots × steps × runs / wall time);
Dask's overhead is its wall time against local execution on the same number of
cores (target: within 15 %). Every variant's table must equal the others'.

Usage::

    python bench/bench_sweep.py                 # ~2 min
    python bench/bench_sweep.py --points 48 --repeats 1

Last line: ``RESULT local_1=… dask_1=… local_2=… dask_2=… overhead_1_pct=…
overhead_2_pct=… identical=yes targets_met=yes|no`` (throughputs in agent-steps/s).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "2")

import numba  # noqa: E402
import numpy as np  # noqa: E402

from aes_ros import scenario  # noqa: E402
from aes_ros.sweep.engine import Sweep, results  # noqa: E402
from aes_ros.sweep.runs import make_tasks  # noqa: E402
from aes_ros.sweep.spec import parse_axis, points  # noqa: E402

TARGET_OVERHEAD_PCT = 15.0


def make_sweep(n_points: int, mc: int) -> Sweep:
    base = scenario.load("combined").with_robots(100)
    axes = [parse_axis(f"alpha=0.02:0.3:{n_points // 4}"), parse_axis("k=0.5,1,1.5,2")]
    return Sweep(base, axes, points(axes), mc=mc)


def timed(sweep: Sweep, tasks, **where) -> tuple[float, list]:
    start = time.perf_counter()
    rows = [row for chunk in results(sweep, tasks, **where) for row in chunk]
    return time.perf_counter() - start, sorted(rows, key=lambda r: (r["point"], r["run"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, default=96, help="points of the sweep")
    parser.add_argument("--mc", type=int, default=10)
    parser.add_argument("--points-per-task", type=int, default=12)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args(argv)
    from dask.distributed import LocalCluster

    sweep = make_sweep(args.points, args.mc)
    tasks = make_tasks(sweep.names, sweep.points, set(), args.points_per_task)
    warm = make_sweep(4, 1)
    warm_tasks = make_tasks(warm.names, warm.points, set(), 4)
    n = len(sweep.base.nominal_positions())
    agent_steps = n * sweep.base.n_steps * sweep.mc * len(sweep.points)
    print(f"sweep: {len(sweep.points)} points x {sweep.mc} runs of {n} robots x "
          f"{sweep.base.n_steps} steps = {agent_steps:.3g} agent-steps in {len(tasks)} tasks",
          flush=True)  # fmt: skip

    clusters = {}
    for k in (1, 2):
        clusters[k] = LocalCluster(
            n_workers=k, threads_per_worker=1, processes=True, dashboard_address=None,
            env={"NUMBA_NUM_THREADS": "1"},
        )  # fmt: skip
        timed(warm, warm_tasks, scheduler=clusters[k].scheduler_address)  # JIT loaded
    timed(warm, warm_tasks)
    best: dict[str, float] = {}
    tables: dict[str, list] = {}
    try:
        for r in range(args.repeats):
            for name, threads, where in (
                ("local_1", 1, {}),
                ("dask_1", 1, {"scheduler": clusters[1].scheduler_address}),
                ("local_2", 2, {}),
                ("dask_2", 2, {"scheduler": clusters[2].scheduler_address}),
            ):
                numba.set_num_threads(threads)
                wall, rows = timed(sweep, tasks, **where)
                best[name] = min(best.get(name, np.inf), wall)
                tables[name] = rows
                print(f"  repeat {r}: {name:<8} {wall:6.2f} s", flush=True)
    finally:
        for cluster in clusters.values():
            cluster.close()
    identical = all(rows == tables["local_1"] for rows in tables.values())
    rate = {name: agent_steps / wall for name, wall in best.items()}
    overhead = {k: 100 * (best[f"dask_{k}"] / best[f"local_{k}"] - 1) for k in (1, 2)}
    print(f"\n{'variant':<10}{'wall [s]':>10}{'agent-steps/s':>16}{'vs local':>10}")
    for name, wall in best.items():
        k = name[-1]
        ratio = wall / best[f"local_{k}"]
        print(f"{name:<10}{wall:>10.2f}{rate[name]:>16.3g}{ratio:>10.3f}")
    print(f"2 cores / 1 core, local: {best['local_1'] / best['local_2']:.2f}x; "
          f"Dask: {best['dask_1'] / best['dask_2']:.2f}x; tables identical: {identical}")  # fmt: skip
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

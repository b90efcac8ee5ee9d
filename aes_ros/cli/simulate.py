"""``aes-swarm simulate``: one of the paper's setups in the offline simulator.

Example::

    aes-swarm simulate --setup combined --out out/combined
    aes-swarm simulate --scenario my.yaml --set alpha=0.1 --set direction=0,1 --runs 10 --out out/x
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from aes_ros import report, simulator
from aes_ros.cli.options import (
    MAX_RUNS,
    add_scenario_options,
    add_seed_option,
    duration_type,
    load_scenario,
    number_type,
    scenario_label,
)
from aes_ros.params import PARAMS
from aes_ros.previous_run import SIMULATE_OUTPUTS, add_overwrite_option, check_out_dir, remove

#: Agent-steps above which a progress bar is shown (about a second of work).
PROGRESS_ABOVE = 2e7


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_options(p)
    add_seed_option(p)
    p.add_argument(
        "--runs",
        type=number_type(int, 1, MAX_RUNS),
        default=1,
        metavar="N",
        help="independent Monte-Carlo runs (metrics.csv holds their mean; default 1)",
    )
    p.add_argument(
        "--dt", type=float, default=None, help=f"time step [s] ({PARAMS['dt'].allowed()})"
    )
    p.add_argument(
        "--duration",
        type=duration_type(open_ended=False),
        default=None,
        metavar="S",
        help=f"run length [s] ({PARAMS['duration'].allowed()})",
    )
    p.add_argument("--no-noise", action="store_true", help="switch both noise terms off")
    p.add_argument(
        "--out", type=Path, required=True, metavar="DIR",
        help="the directory this command writes; one that holds an earlier run's outputs is "
        "refused unless --overwrite",
    )  # fmt: skip
    add_overwrite_option(p, "outputs in --out")


def run(args: argparse.Namespace) -> int:
    sc = load_scenario(args)
    earlier = check_out_dir(args.out, SIMULATE_OUTPUTS, overwrite=args.overwrite)
    seeds = [args.seed + b for b in range(args.runs)]
    n_robots = len(sc.nominal_positions())
    start = time.perf_counter()
    long_run = args.runs * n_robots * sc.n_steps > PROGRESS_ABOVE
    result = simulator.simulate(sc, seeds, noise=not args.no_noise, progress=long_run)
    elapsed = time.perf_counter() - start
    remove(earlier)  # with --overwrite: the earlier run's files, now that this one is done
    line = report.write_run_outputs(
        args.out, result.times, result.positions, result.headings, sc, label=scenario_label(args)
    )
    print(f"{line}  [{elapsed:.2f} s, outputs in {args.out}]")
    return 0

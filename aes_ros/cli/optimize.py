"""``aes-swarm optimize``: tune α, β, k with TCACS on the Monte-Carlo cost J (E10).

Examples::

    aes-swarm optimize --out out/tune                      # the paper's run: 300 evals x 10 runs
    aes-swarm optimize --w1 0.1 --w2 -1 --bounds k=1:3 --seed 2 --out out/tune-force

Default search box: alpha=0.001:0.5, beta=0.01:5, k=0.5:5 (see aes_ros.optim.tuning
for why k stops at 0.5: J rewards a weak sheet, and k -> 0 tears it).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from aes_ros.cli.options import (
    MAX_EVALS,
    add_runs_option,
    add_scenario_options,
    add_seed_option,
    check_tcacs_options,
    load_scenario,
    number_type,
    scenario_label,
)
from aes_ros.optim import tcacs, tuning
from aes_ros.params import ParameterError
from aes_ros.previous_run import OPTIMIZE_OUTPUTS, add_overwrite_option, check_out_dir, remove

#: TCACS's options as ``aes-swarm optimize`` spells them (for error messages).
FLAGS = {
    "n_ants": "--ants",
    "max_evals": "--evals",
    "weighting": "--weighting",
    "gamma": "--gamma",
    "m": "--m",
}


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_options(p)
    evals, paper = tcacs.DEFAULT_MAX_EVALS, tcacs.PAPER_OPTIONS
    p.add_argument(
        "--evals",
        type=number_type(int, 1, MAX_EVALS),
        default=evals,
        help=f"evaluation budget (default {evals})",
    )
    add_runs_option(p)
    p.add_argument("--w1", type=float, default=None, help="weight of F (default 1/N)")
    p.add_argument("--w2", type=float, default=-1.0, help="weight of psi (default -1)")
    default_box = ",".join(f"{n}={lo:g}:{hi:g}" for n, (lo, hi) in tuning.DEFAULT_BOUNDS.items())
    p.add_argument(
        "--bounds",
        default="",
        metavar="alpha=LO:HI,beta=LO:HI,k=LO:HI",
        help=f"search box; names left out keep the default ({default_box})",
    )
    add_seed_option(p, "TCACS's own draws use S too")
    ants, weighting = paper["n_ants"], paper["weighting"]
    p.add_argument("--ants", type=int, default=ants, help=f"ants per iteration ({ants})")
    p.add_argument(
        "--weighting",
        default=weighting,
        help=f"roulette (the paper's) or rank (default {weighting})",
    )
    # Floats, like values typed on the command line (result.json records them).
    gamma, m = float(paper["gamma"]), float(paper["m"])
    p.add_argument(
        "--gamma", type=float, default=gamma, help=f"cost share of the weights ({gamma:g})"
    )
    p.add_argument("--m", type=float, default=m, help=f"PCA factor m ({m:g})")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--out", type=Path, required=True, metavar="DIR",
        help="the directory this command writes; one that holds an earlier tuning's outputs is "
        "refused unless --overwrite",
    )  # fmt: skip
    add_overwrite_option(p, "outputs in --out")


def run(args: argparse.Namespace) -> int:
    check_tcacs_options(
        FLAGS,
        n_ants=args.ants,
        weighting=args.weighting,
        gamma=args.gamma,
        m=args.m,
        max_evals=args.evals,
    )
    bounds = tuning.parse_bounds(args.bounds)
    sc = load_scenario(args)
    earlier = check_out_dir(args.out, OPTIMIZE_OUTPUTS, overwrite=args.overwrite)
    start = time.perf_counter()
    try:
        outcome = tuning.tune(
            sc,
            bounds=bounds,
            evals=args.evals,
            mc=args.runs,
            w1=args.w1,
            w2=args.w2,
            seed=args.seed,
            n_ants=args.ants,
            weighting=args.weighting,
            gamma=args.gamma,
            m=args.m,
            progress=not args.no_progress,
        )
    except ValueError as exc:  # e.g. a non-finite weight
        raise ParameterError(str(exc)) from None
    outcome.extra["total_time_s"] = round(time.perf_counter() - start, 3)
    remove(earlier)  # with --overwrite: the earlier tuning's files, now that this one is done
    tuning.write_tune_outputs(args.out, outcome, sc, scenario_label(args))
    print(tuning.summary_line(outcome, args.out))
    return 0

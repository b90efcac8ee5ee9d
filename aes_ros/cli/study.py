"""``aes-swarm study``: the paper's tuning study (untuned vs paper vs TCACS gains).

Example::

    aes-swarm study --out docs/study                       # default vs tuned, weight variants

Unlike ``launch``, ``simulate`` and ``optimize`` it replaces what an earlier study left
in ``--out`` without ``--overwrite``: its outputs are the figures and tables of
docs/tuning.md, regenerated whole by this command (and kept in git).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from aes_ros.cli.deprecated import add_deprecated
from aes_ros.cli.options import (
    MAX_EVALS,
    MAX_RUNS,
    add_runs_option,
    add_scenario_options,
    check_tcacs_options,
    load_scenario,
    number_type,
)
from aes_ros.optim import study, tcacs
from aes_ros.optim.tuning import PAPER_GAINS


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_options(p)
    evals = tcacs.DEFAULT_MAX_EVALS
    p.add_argument(
        "--evals",
        type=number_type(int, 1, MAX_EVALS),
        default=evals,
        help=f"evaluations per TCACS run ({evals})",
    )
    add_runs_option(p)
    p.add_argument(
        "--restarts",
        type=number_type(int, 1, MAX_RUNS),
        default=3,
        help="TCACS runs per setting (3)",
    )
    p.add_argument(
        "--held-out",
        type=number_type(int, 1, MAX_RUNS),
        default=50,
        metavar="N",
        help="held-out Monte-Carlo runs per gain set, seeds disjoint from tuning (default 50)",
    )
    add_deprecated(p, "--eval-runs", "--held-out")
    p.add_argument("--no-progress", action="store_true", help="no progress output")
    p.add_argument(
        "--out", type=Path, required=True, metavar="DIR",
        help="the directory this command writes (docs/study holds the published one)",
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    # The study runs TCACS with the paper's options, so only the budget is the user's.
    check_tcacs_options(
        {"max_evals": "--evals", "n_ants": "TCACS's ants per iteration"}, max_evals=args.evals
    )
    sc = load_scenario(args)
    result = study.run_study(
        args.out,
        sc,
        evals=args.evals,
        mc=args.runs,
        restarts=args.restarts,
        eval_runs=args.held_out,
        progress=not args.no_progress,
    )
    best = result["table"][2]
    paper = ", ".join(f"{v:g}" for v in PAPER_GAINS.values())
    print(
        f"study done in {result['total_time_s']:.0f} s: TCACS (1/N, -1) gives "
        f"alpha={best['alpha']:.3g}, beta={best['beta']:.3g}, k={best['k']:.3g} "
        f"(paper: {paper}); outputs in {args.out}"
    )
    return 0

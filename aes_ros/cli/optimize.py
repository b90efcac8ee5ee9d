"""``aes-swarm optimize`` (TCACS tuning of α, β, k) and ``aes-swarm study`` (the paper's study).

Examples::

    aes-swarm optimize --out out/tune                      # the paper's run: 300 evals x 10 MC
    aes-swarm optimize --w1 0.1 --w2 -1 --bounds k=1:3 --seed 2 --out out/tune-force
    aes-swarm study --out docs/study                       # default vs tuned, weight variants

Default search box: alpha=0.001:0.5, beta=0.01:5, k=0.5:5 (see aes_ros.optim.tuning
for why k stops at 0.5: J rewards a weak sheet, and k -> 0 tears it).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from aes_ros.cli.simulate import add_scenario_options, load_scenario
from aes_ros.optim import study, tcacs, tuning
from aes_ros.params import ParameterError

#: TCACS's options as ``aes-swarm optimize`` spells them (for error messages).
OPTIMIZE_FLAGS = {
    "n_ants": "--ants",
    "max_evals": "--evals",
    "weighting": "--weighting",
    "gamma": "--gamma",
    "m": "--m",
}


def register(sub: argparse._SubParsersAction) -> None:
    _register_optimize(sub)
    _register_study(sub)


def _default_bounds_text() -> str:
    return ",".join(f"{n}={lo:g}:{hi:g}" for n, (lo, hi) in tuning.DEFAULT_BOUNDS.items())


def _register_optimize(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "optimize",
        help="tune alpha, beta, k with TCACS on the Monte-Carlo cost J (E10)",
        description="Tune the gains with TCACS (SPEC §6) on J (E10): every candidate is "
        "simulated with the same --mc seeds (common random numbers), all ants x all runs "
        "of an iteration in one batch. Writes result.json, history.csv and convergence.png "
        "to --out.",
    )
    add_scenario_options(p)
    evals, paper = tcacs.DEFAULT_MAX_EVALS, tcacs.PAPER_OPTIONS
    p.add_argument("--evals", type=int, default=evals, help=f"evaluation budget (default {evals})")
    p.add_argument("--mc", type=int, default=10, help="Monte-Carlo runs per candidate (10)")
    p.add_argument("--w1", type=float, default=None, help="weight of F (default 1/N)")
    p.add_argument("--w2", type=float, default=-1.0, help="weight of psi (default -1)")
    p.add_argument(
        "--bounds",
        default="",
        metavar="alpha=LO:HI,beta=LO:HI,k=LO:HI",
        help=f"search box; names left out keep the default ({_default_bounds_text()})",
    )
    p.add_argument("--seed", type=int, default=0, help="seeds TCACS and picks the MC seeds")
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
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.set_defaults(func=run_optimize)


def _register_study(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "study",
        help="the paper's tuning study: untuned vs paper vs TCACS gains, weight variants",
        description="Reproduce the paper's study: TCACS with the weights (1/N,-1), (10/N,-1), "
        "(1/N,-10) (and k free down to 0), restarted with independent seeds, then every gain "
        "set re-simulated on held-out seeds. Writes effect_of_optimisation.png, "
        "convergence.png, j_slices.png, table.csv, runs.csv, study.json and study.md.",
    )
    add_scenario_options(p)
    evals = tcacs.DEFAULT_MAX_EVALS
    p.add_argument("--evals", type=int, default=evals, help=f"evaluations per TCACS run ({evals})")
    p.add_argument("--mc", type=int, default=10, help="Monte-Carlo runs per candidate (10)")
    p.add_argument("--restarts", type=int, default=3, help="TCACS runs per setting (3)")
    p.add_argument("--eval-runs", type=int, default=50, help="held-out runs per gain set (50)")
    p.add_argument("--no-progress", action="store_true", help="no progress output")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.set_defaults(func=run_study)


def _check_counts(args: argparse.Namespace, names: tuple[str, ...]) -> None:
    for name in names:
        value = getattr(args, name.replace("-", "_"))
        if value < 1:
            raise ParameterError(f"--{name}: {value} is not allowed; need an integer >= 1")


def _check_tcacs(labels: dict[str, str], **options: Any) -> None:
    """TCACS's own option check, its message naming the option as this command spells it."""
    try:
        tcacs.check_options(**options, labels=labels)
    except ValueError as exc:
        raise ParameterError(str(exc)) from None


def run_optimize(args: argparse.Namespace) -> int:
    _check_counts(args, ("mc",))
    _check_tcacs(
        OPTIMIZE_FLAGS,
        n_ants=args.ants,
        weighting=args.weighting,
        gamma=args.gamma,
        m=args.m,
        max_evals=args.evals,
    )
    bounds = tuning.parse_bounds(args.bounds)
    sc = load_scenario(args)
    label = args.scenario.stem if args.scenario is not None else args.setup
    start = time.perf_counter()
    try:
        outcome = tuning.tune(
            sc,
            bounds=bounds,
            evals=args.evals,
            mc=args.mc,
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
    tuning.write_tune_outputs(args.out, outcome, sc, label)
    print(tuning.summary_line(outcome, args.out))
    return 0


def run_study(args: argparse.Namespace) -> int:
    _check_counts(args, ("mc", "restarts", "eval-runs"))
    # The study runs TCACS with the paper's options, so only the budget is the user's.
    _check_tcacs(
        {"max_evals": "--evals", "n_ants": "TCACS's ants per iteration"}, max_evals=args.evals
    )
    sc = load_scenario(args)
    result = study.run_study(
        args.out,
        sc,
        evals=args.evals,
        mc=args.mc,
        restarts=args.restarts,
        eval_runs=args.eval_runs,
        progress=not args.no_progress,
    )
    best = result["table"][2]
    print(
        f"study done in {result['total_time_s']:.0f} s: TCACS (1/N, -1) gives "
        f"alpha={best['alpha']:.3g}, beta={best['beta']:.3g}, k={best['k']:.3g} "
        f"(paper: 0.066, 0.97, 1.28); outputs in {args.out}"
    )
    return 0

"""``aes-swarm simulate``: one of the paper's setups in the offline simulator.

Example::

    aes-swarm simulate --setup combined --out out/combined
    aes-swarm simulate --scenario my.yaml --set alpha=0.1 --set direction=0,1 --runs 10 --out out/x
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from aes_ros import report, scenario, simulator
from aes_ros.params import PARAMS, ParameterError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="run a scenario in the fast offline simulator and write plots and metrics",
        description="Run a scenario offline (batched numpy/numba simulator, SPEC §1.4) and "
        "write trajectory.npz, metrics.csv, snapshots.png and metrics.png to --out.",
    )
    add_scenario_options(p)
    p.add_argument("--seed", type=int, default=0, help="seed of run 0; run b uses seed + b")
    p.add_argument(
        "--runs",
        type=number_type("--runs", int, 1),
        default=1,
        help="independent Monte-Carlo runs B (metrics.csv holds their mean)",
    )
    p.add_argument(
        "--dt", type=float, default=None, help=f"time step [s] ({PARAMS['dt'].allowed()})"
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        help=f"run length [s] ({PARAMS['duration'].allowed()})",
    )
    p.add_argument("--no-noise", action="store_true", help="switch both noise terms off")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.set_defaults(func=run)


def add_scenario_options(p: argparse.ArgumentParser) -> None:
    """--setup / --scenario / --set, shared with the other subcommands."""
    p.add_argument(
        "--setup",
        default="combined",
        metavar="{" + ",".join(scenario.SETUPS) + "}",
        help="one of the paper's setups (default: combined)",
    )
    p.add_argument(
        "--scenario",
        type=Path,
        default=None,
        help="a scenario YAML file (copy one from aes_ros/scenarios/); overrides --setup",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a parameter (repeatable); see `aes-swarm params`",
    )


def load_scenario(args: argparse.Namespace) -> scenario.Scenario:
    """The scenario named by --setup/--scenario with --set (and --dt/--duration) applied."""
    source = args.scenario if args.scenario is not None else args.setup
    if args.scenario is None and args.setup not in scenario.SETUPS:
        raise ParameterError(
            f"--setup: unknown setup {args.setup!r}; allowed: {', '.join(scenario.SETUPS)}"
        )
    sc = scenario.load(source, scenario.parse_assignments(args.set))
    options = {n: v for n in ("dt", "duration") if (v := getattr(args, n, None)) is not None}
    return sc.with_overrides(options, "--" + "/--".join(options)) if options else sc


def number_type(name: str, kind: type = float, minimum: float | None = None):
    """An argparse ``type``: a finite number of ``kind`` (int or float), at least
    ``minimum`` if given; the error names the option ``name`` and what is allowed."""
    noun = "an integer" if kind is int else "a number"

    def parse(text: str) -> int | float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}: {text!r} is not {noun}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{name}: {text!r} is not finite")
        if minimum is not None and value < minimum:
            raise argparse.ArgumentTypeError(f"{name}: need {noun} >= {minimum:g}, got {text}")
        return value

    return parse


def run(args: argparse.Namespace) -> int:
    sc = load_scenario(args)
    seeds = [args.seed + b for b in range(args.runs)]
    n_robots = len(sc.nominal_positions())
    start = time.perf_counter()
    # A progress bar for runs longer than about a second (~2e7 agent-steps/s).
    long_run = args.runs * n_robots * sc.n_steps > 2e7
    result = simulator.simulate(sc, seeds, noise=not args.no_noise, progress=long_run)
    elapsed = time.perf_counter() - start
    label = args.scenario.stem if args.scenario is not None else args.setup
    line = report.write_run_outputs(
        args.out, result.times, result.positions, result.headings, sc, label=label
    )
    print(f"{line}  [{elapsed:.2f} s, outputs in {args.out}]")
    return 0

"""Options and checks shared by the ``aes-swarm`` subcommands.

Every value from the command line is checked here or by the function it is
passed to; a bad one raises ``argparse.ArgumentTypeError`` or
:class:`aes_ros.params.ParameterError`, which ``aes-swarm`` turns into exit code 2
and a one-line message naming the option.

One vocabulary across the commands: ``--runs N`` repeated Monte-Carlo runs of one
configuration, ``--seed S`` with one rule (Monte-Carlo run r, 0-based, uses seed S + r;
:data:`SEED_RULE`), ``--duration S`` in seconds (0 = until Ctrl-C only where a run can be
open-ended), ``--out DIR`` the directory the command writes. Old spellings still parse,
with a warning (:mod:`aes_ros.cli.deprecated`).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from aes_ros import scenario
from aes_ros.cli.deprecated import add_deprecated
from aes_ros.params import ParameterError


def add_scenario_options(p: argparse.ArgumentParser) -> None:
    """``--setup`` / ``--scenario`` / ``--set`` / ``--robots``: which scenario, with which
    overrides."""
    p.add_argument(
        "--setup",
        default="combined",
        metavar="{" + ",".join(scenario.PACKAGED) + "}",
        help="one of the paper's setups or cluttered (default: combined)",
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
    p.add_argument(
        "--robots", type=number_type(int, 1, MAX_ROBOTS), default=None,
        help="number of robots N: a near-square grid (default: the scenario's formation)",
    )  # fmt: skip


def load_scenario(args: argparse.Namespace) -> scenario.Scenario:
    """The scenario named by --setup/--scenario with --set, --robots (and --dt/--duration)
    applied."""
    source = args.scenario if args.scenario is not None else args.setup
    if args.scenario is None and args.setup not in scenario.PACKAGED:
        raise ParameterError(
            f"--setup: unknown setup {args.setup!r}; allowed: {', '.join(scenario.PACKAGED)}"
        )
    sc = scenario.load(source, scenario.parse_assignments(args.set))
    if args.robots is not None:
        sc = sc.with_robots(args.robots)
    options = {n: v for n in ("dt", "duration") if (v := getattr(args, n, None)) is not None}
    return sc.with_overrides(options, "--" + "/--".join(options)) if options else sc


#: Monte-Carlo runs per candidate (the paper's N_MC, docs/design.md#cost).
DEFAULT_MC = 10

#: The one seed rule of every command with ``--seed`` and ``--runs``.
SEED_RULE = "Monte-Carlo run r (0-based) of a configuration uses seed S + r"


def add_runs_option(
    p: argparse.ArgumentParser, default: int = DEFAULT_MC, what: str = "per candidate"
) -> None:
    """``--runs``: Monte-Carlo runs of one configuration, with common random numbers (the
    old spelling ``--mc`` still parses, with a warning)."""
    p.add_argument(
        "--runs",
        type=number_type(int, 1, MAX_RUNS),
        default=default,
        metavar="N",
        help=f"Monte-Carlo runs {what}, with common random numbers (default {default})",
    )
    add_deprecated(p, "--mc", "--runs")


def add_seed_option(p: argparse.ArgumentParser, what: str = "") -> None:
    """``--seed S``, its help stating :data:`SEED_RULE`."""
    extra = f"; {what}" if what else ""
    p.add_argument(
        "--seed", type=seed_type, default=0, metavar="S",
        help=f"{SEED_RULE} (default 0){extra}",
    )  # fmt: skip


#: Commands where ``--duration 0`` means "until Ctrl-C".
OPEN_ENDED = "launch"


def duration_type(open_ended: bool) -> Callable[[str], float]:
    """``--duration S`` in seconds: > 0, or also 0 (= until Ctrl-C) if ``open_ended``."""
    parse = number_type(float, 0)

    def check(text: str) -> float:
        value = float(parse(text))
        if value == 0 and not open_ended:
            raise argparse.ArgumentTypeError(f"need > 0 (0 = until Ctrl-C only for {OPEN_ENDED})")
        return value

    return check


def scenario_label(args: argparse.Namespace) -> str:
    """The run's name in summaries and titles: the setup, or the scenario file's stem."""
    return args.scenario.stem if args.scenario is not None else args.setup


def number_type(
    kind: type = float, minimum: float | None = None, maximum: float | None = None
) -> Callable[[str], int | float]:
    """An argparse ``type``: a finite number of ``kind`` (int or float), at least
    ``minimum`` and at most ``maximum`` if given; argparse's error names the option, this
    says what is allowed."""
    noun = "an integer" if kind is int else "a number"

    def parse(text: str) -> int | float:
        shown = text if len(text) <= 40 else text[:39] + "…"
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{shown!r} is not {noun}") from None
        # an int is always finite (and math.isfinite overflows on 400 digits)
        if isinstance(value, float) and not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{shown!r} is not finite")
        if minimum is not None and value < minimum:
            raise argparse.ArgumentTypeError(f"need {noun} >= {_bound(minimum)}, got {shown}")
        if maximum is not None and value > maximum:
            raise argparse.ArgumentTypeError(f"need {noun} <= {_bound(maximum)}, got {shown}")
        return value

    return parse


def _bound(value: float) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


#: Limits of counts and seeds given on the command line: beyond them a value is a
#: typo, and would overflow a float, an int64 ROS parameter or the memory later.
MAX_ROBOTS = 1_000_000  # the largest grid, 1000 x 1000
MAX_RUNS = 100_000
MAX_EVALS = 1_000_000_000
MAX_SEED = 2**63 - 1
#: ``--seed``: an integer in [0, MAX_SEED].
seed_type = number_type(int, 0, MAX_SEED)


def check_tcacs_options(labels: Mapping[str, str], **options: Any) -> None:
    """TCACS's own option check (:func:`aes_ros.optim.tcacs.check_options`), its
    message naming the option as the command spells it (``labels``)."""
    from aes_ros.optim import tcacs  # here: it loads scipy.optimize, 0.5 s of every command

    try:
        tcacs.check_options(**options, labels=dict(labels))
    except ValueError as exc:
        raise ParameterError(str(exc)) from None

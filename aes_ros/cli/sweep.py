"""``aes-swarm sweep``: the offline simulator over a grid or a Latin hypercube of parameters.

Examples::

    aes-swarm sweep --param alpha=0.01:0.2:20 --param k=log:0.05:5:20 --runs 10 --out out/ak
    aes-swarm sweep --param d_r=0:2:9 --param robots=25,100,400 --duration 60 --transient 20 \\
        --out out/noise
    aes-swarm sweep --lhs 200 --param alpha=0.01:0.5 --param beta=0.1:5 --param k=log:0.05:5 \\
        --out out/lhs --scheduler tls://10.0.0.5:8786 \\
        --tls-ca ca.pem --tls-cert client.pem --tls-key client-key.pem

Writes ``runs.csv`` (one row per point and run), ``points.csv`` (per point),
``sweep_metrics.png`` and ``sweep.json`` to ``--out``; re-running the same command
after an interruption skips the points already done (:mod:`aes_ros.sweep.engine`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from aes_ros.cli.options import (
    add_runs_option,
    add_scenario_options,
    add_seed_option,
    duration_type,
    load_scenario,
    number_type,
)
from aes_ros.params import PARAMS
from aes_ros.sweep.cluster import TLS_OPTIONS, Scheduler, scheduler
from aes_ros.sweep.spec import MAX_POINTS, SweepSpecError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--param", action="append", default=[], metavar="NAME=SPEC", required=True,
        help="a swept parameter (repeatable): NAME=low:high:n, NAME=log:low:high:n, "
        "NAME=v1,v2,… or, with --lhs, NAME=low:high; NAME is a scenario parameter "
        "(`aes-swarm params`) or robots",
    )  # fmt: skip
    p.add_argument(
        "--lhs", type=number_type(int, 1, MAX_POINTS), default=None, metavar="N",
        help="N Latin-hypercube samples of the --param ranges instead of the grid",
    )  # fmt: skip
    add_scenario_options(p)
    add_runs_option(p, what="per point")
    p.add_argument(
        "--duration", type=duration_type(open_ended=False), default=None, metavar="S",
        help=f"run length [s] ({PARAMS['duration'].allowed()})",
    )  # fmt: skip
    p.add_argument(
        "--transient", type=number_type(float, 0), default=0.0,
        help="sim seconds left out of the time averages ψ̄, ψ̄_heading, F̄/N (default 0)",
    )  # fmt: skip
    p.add_argument(
        "--fail", default=None, metavar="FRACTION@TIME",
        help="robots failing mid-run: e.g. 0.1@15 stops 10 %% of them (the same ones in "
        "every run) at t = 15 s",
    )  # fmt: skip
    add_seed_option(p, "the Latin hypercube's draws use S too")
    p.add_argument(
        "--out", type=Path, required=True, metavar="DIR",
        help="the directory this command writes (resumable)",
    )  # fmt: skip
    add_scheduler_options(p)
    p.add_argument(
        "--workers", type=number_type(int, 1), default=None, metavar="K",
        help="run on a local Dask cluster of K worker processes",
    )  # fmt: skip
    p.add_argument(
        "--points-per-task", type=number_type(int, 1), default=4, metavar="P",
        help="points simulated in one batch (one task; default 4)",
    )  # fmt: skip
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def add_scheduler_options(p: argparse.ArgumentParser) -> None:
    """``--scheduler`` and its ``--tls-*`` files (:mod:`aes_ros.sweep.cluster`)."""
    p.add_argument(
        "--scheduler", default=None, metavar="ADDRESS",
        help="run on this Dask cluster (tls://HOST:8786 with the --tls-* files, or "
        "tcp://HOST:8786) instead of the local cores; whoever reaches a scheduler runs code",
    )  # fmt: skip
    helps = ("the cluster's CA certificate", "this client's certificate", "its private key")
    for option, text in zip(TLS_OPTIONS, helps, strict=True):
        p.add_argument(option, type=Path, default=None, metavar="PEM", help=f"{text} (PEM)")


def scheduler_from_args(args: argparse.Namespace) -> Scheduler | None:
    """The checked :class:`Scheduler` of ``--scheduler`` and ``--tls-*``, or None."""
    tls = (args.tls_ca, args.tls_cert, args.tls_key)
    if args.scheduler is None:
        if any(path is not None for path in tls):
            raise SweepSpecError("--tls-ca/--tls-cert/--tls-key need --scheduler tls://HOST:PORT")
        return None
    return scheduler(args.scheduler, *tls, warn=lambda text: print(text, file=sys.stderr))


def run(args: argparse.Namespace) -> int:
    from aes_ros.sweep.engine import Sweep, execute
    from aes_ros.sweep.spec import parse_axis, points

    if args.scheduler is not None and args.workers is not None:
        raise SweepSpecError("--scheduler and --workers: give one of them")
    cluster = scheduler_from_args(args)
    base = load_scenario(args)
    axes = [parse_axis(text) for text in args.param]
    fail = None
    if args.fail is not None:
        fraction, sep, at = args.fail.partition("@")
        try:
            fail = (float(fraction), float(at))
        except ValueError:
            sep = ""
        if not sep:
            raise SweepSpecError(f"--fail {args.fail!r}: need FRACTION@TIME, e.g. 0.1@15")
    sweep = Sweep(
        base,
        axes,
        points(axes, args.lhs, args.seed),
        mc=args.runs,
        seed=args.seed,
        transient=args.transient,
        lhs=args.lhs,
        fail=fail,
    )
    summary = execute(
        sweep,
        args.out,
        scheduler=cluster,
        workers=args.workers,
        points_per_task=args.points_per_task,
        progress=not args.no_progress,
    )
    print(f"sweep done: {len(sweep.points)} points; {summary} and {args.out / 'runs.csv'}")
    return 0

"""``aes-swarm``: the user's front door (docs/design.md#starting).

Every subcommand is registered in :data:`COMMANDS` below; its module of this
package has ``add_arguments(parser)`` and ``run(args) -> int``, and the first
paragraph of the module docstring is the command's ``--help`` description. Bad
input (a ParameterError or ValueError from validation) exits with code 2 and a
one-line message naming the field; no traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Collection

from aes_ros.params import ParameterError

#: Every subcommand, in the order ``--help`` lists them: name -> one-line help.
#: The module ``aes_ros.cli.<name>`` implements it.
COMMANDS: dict[str, str] = {
    "simulate": "run a scenario in the fast offline simulator and write plots and metrics",
    "params": "list the scenario parameters (name, default, range)",
    "optimize": "tune alpha, beta, k with TCACS on the Monte-Carlo cost J (E10)",
    "study": "the paper's tuning study: untuned vs paper vs TCACS gains, weight variants",
    "sweep": "the offline simulator over a grid or Latin hypercube of parameters (local or Dask)",
    "explore": "studies on sweeps: pareto, noise, robustness, perception, ladder, clutter",
    "launch": "run the ROS 2 system (pybullet bridge, supervisor, robot nodes) and write outputs",
    "steer": "steer the running swarm: publish one /swarm/cmd",
    "dashboard": "watch and steer the running swarm in the browser",
    "calibrate": "the overhead camera's pose from one frame of reference markers",
    "report": "rebuild a launch's trajectory, metrics, plots and summary from what is on disk",
}

#: Longer descriptions shown by ``aes-swarm <command> --help``.
DESCRIPTIONS: dict[str, str] = {
    "simulate": "Run a scenario offline (batched numpy/numba simulator, docs/design.md#motion) and "
    "write trajectory.h5, metrics.csv, snapshots.png and metrics.png to --out.",
    "optimize": "Tune the gains with TCACS (docs/design.md#tcacs) on J (E10): every candidate is "
    "simulated with the same --runs seeds (common random numbers), all ants x all runs "
    "of an iteration in one batch. Writes result.json, history.csv and convergence.png "
    "to --out.",
    "study": "Reproduce the paper's study: TCACS with the weights (1/N,-1), (10/N,-1), "
    "(1/N,-10) (and k free down to 0), restarted with independent seeds, then every gain "
    "set re-simulated on held-out seeds. Writes effect_of_optimisation.png, "
    "convergence.png, j_slices.png, table.csv, runs.csv, study.json and study.md.",
    "sweep": "Simulate every point of a parameter grid (or of a Latin hypercube) with --runs "
    "Monte-Carlo runs each, with common random numbers, batched into the numba simulator; "
    "on the local cores, local Dask workers or a Dask cluster. Writes runs.csv (one row per "
    "point and run), points.csv, sweep_metrics.png and sweep.json; resumable.",
    "launch": "Start aes-sim-bridge, aes-supervisor and the robot nodes as separate "
    "processes, wait until every robot moves, run for --duration seconds of sim time "
    "(or until Ctrl-C), stop everything cleanly and write trajectory.h5, metrics.csv, "
    "snapshots.png and metrics.png to --out (the trajectory and the metrics streamed to "
    "disk as it runs).",
    "dashboard": "A ROS node with a web server: the swarm drawn live (robots coloured by "
    "their force alignment, springs by strain, the centroid's trail), strip charts of the "
    "order and the force, and controls that act through the swarm's public ROS interface.",
    "report": "Write metrics.csv, snapshots.png and metrics.png of a run directory from "
    "the trajectory.h5 that aes-swarm launch streams while it runs, e.g. after the launcher "
    "was killed (trajectory.h5 is then rewritten closed, for readers other than h5py with "
    "swmr=True).",
    "steer": "Publish one geometry_msgs/Twist on /swarm/cmd (linear.x/y = desired "
    "direction, angular.z = rotation rate ω, counter-clockwise positive) and wait until "
    "the supervisor echoes it on /swarm/desired_velocity. A value not given keeps the "
    "supervisor's current one.",
}


def build_parser(commands: Collection[str] = tuple(COMMANDS)) -> argparse.ArgumentParser:
    """The parser of every subcommand; the options of those in ``commands`` only (the
    others are listed, their modules not imported)."""
    parser = argparse.ArgumentParser(
        prog="aes-swarm",
        description="Active Elastic Sheet swarms: offline simulation, tuning and the ROS 2 system.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, help_text in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=DESCRIPTIONS.get(name, help_text))
        if name in commands:
            module = importlib.import_module(f"aes_ros.cli.{name}")
            module.add_arguments(p)
            p.set_defaults(func=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``aes-swarm`` with ``argv``; returns the exit code (2: bad input)."""
    argv = sys.argv[1:] if argv is None else argv
    # Only the command given is imported: all of them (the simulator, the optimiser,
    # matplotlib) took 1.5 s before any command ran; `launch --help` 1.6 s, now 0.6 s.
    parser = build_parser(argv[:1])
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, or argparse's own message naming the option
        return int(exc.code or 0)
    try:
        return int(args.func(args) or 0)
    except ParameterError as exc:
        print(f"aes-swarm {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())

"""``aes-swarm``: the user's front door (SPEC §7 "Starting it").

Each subcommand lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a
function ``(args) -> int``. Bad input (a ParameterError or ValueError from
validation) exits with code 2 and a one-line message naming the field; no
traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from aes_ros.params import ParameterError

#: Subcommand modules, in the order ``--help`` lists them.
SUBCOMMANDS = ("simulate", "params", "optimize", "launch")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="aes-swarm",
        description="Active Elastic Sheet swarms: offline simulation, tuning and the ROS 2 system.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"aes_ros.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"aes_ros.cli.{name}":
                raise
            continue
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ParameterError as exc:
        print(f"aes-swarm {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())

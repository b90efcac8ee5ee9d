"""``aes-swarm params``: every scenario parameter with its default, unit and allowed range."""

from __future__ import annotations

import argparse

from aes_ros.params import markdown_table


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("params", help="list the scenario parameters (name, default, range)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    print(markdown_table())
    return 0

"""``aes-swarm params``: every scenario parameter with its default, unit and allowed range."""

from __future__ import annotations

import argparse

from aes_ros.params import markdown_table


def add_arguments(p: argparse.ArgumentParser) -> None:
    """No options."""


def run(args: argparse.Namespace) -> int:
    print(markdown_table())
    return 0

"""``aes-swarm params``: every scenario parameter with its default, unit and allowed range.

With ``--ros``: the nodes' ROS parameters and the ``params`` / ``--set`` name each one
stands for (``/supervisor desired_direction`` is ``direction``), or that it has none.
"""

from __future__ import annotations

import argparse

from aes_ros.params import markdown_table


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--ros", action="store_true",
        help="the table of the nodes' ROS parameters and their params / --set names",
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    if args.ros:
        from aes_ros.ros.parameter_table import markdown_table as ros_table

        print(ros_table())
    else:
        print(markdown_table())
    return 0

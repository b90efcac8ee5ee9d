"""``aes-swarm steer``: one ``/swarm/cmd`` to the running swarm, confirmed by the supervisor.

Examples::

    aes-swarm steer --direction 0 1            # drive north, keep the rotation rate
    aes-swarm steer --omega 0.5                # turn counter-clockwise, keep the direction
    aes-swarm steer --disable                  # /swarm/enable false: every robot stops
    aes-swarm steer --enable
"""

from __future__ import annotations

import argparse
import sys

from aes_ros.cli.options import number_type
from aes_ros.params import ParameterError


def add_arguments(p: argparse.ArgumentParser) -> None:
    switch = p.add_mutually_exclusive_group()
    switch.add_argument(
        "--enable", dest="enable", action="store_const", const=True, default=None,
        help="call /swarm/enable true: the robots drive again",
    )  # fmt: skip
    switch.add_argument(
        "--disable", dest="enable", action="store_const", const=False,
        help="call /swarm/enable false: every robot publishes zero cmd_vel",
    )  # fmt: skip
    p.add_argument(
        "--direction", nargs=2, type=number_type(), metavar=("X", "Y"),
        default=None, help="desired direction v_d in the world frame (0 0 switches the drive off)",
    )  # fmt: skip
    p.add_argument(
        "--omega", type=number_type(), default=None, metavar="W",
        help="rotation rate ω [rad/s], counter-clockwise positive",
    )  # fmt: skip
    p.add_argument(
        "--timeout", type=number_type(float, 0), default=15.0,
        help="give up after this many seconds [s] (default 15)",
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    if args.direction is None and args.omega is None and args.enable is None:
        raise ParameterError("steer: give --direction X Y, --omega W, --enable or --disable")
    from aes_ros.ros.steering import set_enabled, steer

    if args.enable is not None:
        ok, message = set_enabled(args.enable, timeout=args.timeout)
        print(message, file=sys.stdout if ok else sys.stderr)
        if not ok or (args.direction is None and args.omega is None):
            return 0 if ok else 1
    ok, message = steer(args.direction, args.omega, timeout=args.timeout)
    print(message, file=sys.stdout if ok else sys.stderr)
    return 0 if ok else 1

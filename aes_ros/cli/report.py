"""``aes-swarm report``: a run's outputs rebuilt from what is on disk.

Example::

    aes-swarm report --out out/demo    # after a launch that was cut short (kill -9, power loss)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from aes_ros.params import ParameterError
from aes_ros.report import rebuild_run_outputs


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--out", type=Path, default=None, metavar="DIR",
        help="the directory this command writes: a launch's --out, rebuilt in place (required)",
    )  # fmt: skip
    p.add_argument("run_dir", type=Path, nargs="?", default=None, help=argparse.SUPPRESS)


def run(args: argparse.Namespace) -> int:
    if args.run_dir is not None:  # the old positional spelling, one more release
        print("aes-swarm report: DIR is deprecated; use --out DIR", file=sys.stderr)
        if args.out is not None and args.out != args.run_dir:
            raise ParameterError(f"--out {args.out} and DIR {args.run_dir}: give one")
        args.out = args.run_dir
    if args.out is None:
        raise ParameterError("--out DIR is required: the output directory of aes-swarm launch")
    try:
        summary = rebuild_run_outputs(args.out)
    except (FileNotFoundError, ValueError) as exc:
        raise ParameterError(f"--out: {exc}") from None
    print(f"{summary}  [outputs rebuilt in {args.out}]")
    return 0

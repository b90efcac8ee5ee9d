"""``aes-swarm report``: a run's outputs rebuilt from what is on disk.

Example::

    aes-swarm report out/demo      # after a launch that was cut short (kill -9, power loss)
"""

from __future__ import annotations

import argparse
from pathlib import Path

from aes_ros.params import ParameterError
from aes_ros.report import rebuild_run_outputs


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("run_dir", type=Path, help="the output directory of aes-swarm launch")


def run(args: argparse.Namespace) -> int:
    try:
        summary = rebuild_run_outputs(args.run_dir)
    except (FileNotFoundError, ValueError) as exc:
        raise ParameterError(f"run_dir: {exc}") from None
    print(f"{summary}  [outputs rebuilt in {args.run_dir}]")
    return 0

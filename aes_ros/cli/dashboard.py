"""``aes-swarm dashboard``: watch and steer a running swarm in the browser.

Examples::

    aes-swarm dashboard                              # http://127.0.0.1:8080/, this machine only
    aes-swarm dashboard --setup linear --robots 16 --port 8090
    aes-swarm dashboard --host 0.0.0.0               # other machines: prints a URL with a token

It is a ROS node (``/dashboard``) in this ROS domain: it drives a swarm started by
``aes-swarm launch``, ``scripts/start_swarm.sh`` or on other hosts, through the same
topics, services and parameters as the CLI.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from aes_ros.cli.options import add_scenario_options, load_scenario, number_type


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_options(p)
    p.add_argument(
        "--port", type=number_type(int, 0, 65535), default=8080,
        help="web server port (default 8080; 0: any free one)",
    )  # fmt: skip
    p.add_argument(
        "--host", default="127.0.0.1",
        help="address to listen on (default 127.0.0.1; any other needs the token)",
    )  # fmt: skip
    p.add_argument("--token", default="", help="access token (default: made up when needed)")


def run(args: argparse.Namespace) -> int:
    from aes_ros.ros.launch.plan import ros_args, write_scenario
    from dashboard_node.node import main

    sc = load_scenario(args)
    with tempfile.TemporaryDirectory(prefix="aes-dashboard-") as tmp:
        name = args.scenario.stem if args.scenario is not None else args.setup
        scenario_file = write_scenario(sc, Path(tmp) / f"{name}.yaml")
        params = {
            "scenario": str(scenario_file),
            "host": args.host,
            "port": int(args.port),
            "token": args.token,
            "use_sim_time": True,
        }
        return main(["aes-dashboard", *ros_args(params)])

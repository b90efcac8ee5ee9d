"""``aes-swarm dashboard``: watch and steer a running swarm in the browser.

Examples::

    aes-swarm dashboard                              # prints http://127.0.0.1:8080/?token=…
    aes-swarm dashboard --setup linear --robots 16 --port 8090
    aes-swarm dashboard --host 0.0.0.0               # other machines too (all need the token)
    AES_DASHBOARD_TOKEN_FILE=~/.dashboard-token aes-swarm dashboard   # a token of your own

It runs the dashboard's ROS node (``/dashboard``, ``python -m dashboard_node``) in this
ROS domain, in a child process that Ctrl-C stops with it: it drives a swarm started by
``aes-swarm launch``, ``scripts/start_swarm.sh`` or on other hosts, through the same
topics, services and parameters as the CLI. Its token is made up, or taken from
``AES_DASHBOARD_TOKEN`` or a file of mode 0600 (``--token-file``), never from the
command line (the child gets it by environment); the URL with it is printed here only.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

from aes_ros.cli.options import add_scenario_options, load_scenario, number_type

#: The dashboard node's program that prints its URL with the token (dashboard_node/__main__.py).
DASHBOARD_PROGRAM = ("-m", "dashboard_node")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_options(p)
    p.add_argument(
        "--port", type=number_type(int, 0, 65535), default=8080,
        help="web server port (default 8080; 0: any free one)",
    )  # fmt: skip
    p.add_argument(
        "--host", default="127.0.0.1",
        help="address to listen on (default 127.0.0.1; any other: viewing needs the token too)",
    )  # fmt: skip
    p.add_argument(
        "--token-file", type=Path, default=None, metavar="FILE",
        help="read the access token from FILE (mode 0600, at least 16 characters); "
        "default: $AES_DASHBOARD_TOKEN, else one is made up",
    )  # fmt: skip
    p.add_argument("--token", default=None, help=argparse.SUPPRESS)  # refused: see run()


def run(args: argparse.Namespace) -> int:
    from aes_ros.ros.dashboard_token import (
        TOKEN_VARIABLE,
        TokenError,
        given_token,
        read_token_file,
    )
    from aes_ros.ros.launch.param_files import ros_args, write_scenario

    if args.token is not None:
        print(
            "aes-swarm dashboard: error: --token: a token on the command line is visible to "
            f"every user of this machine (ps); put it in ${TOKEN_VARIABLE} or in a file of "
            "mode 0600 given with --token-file",
            file=sys.stderr,
        )
        return 2
    try:
        if args.token_file is not None:
            token = read_token_file(args.token_file.expanduser())
        else:
            token = given_token(os.environ)
    except TokenError as exc:
        print(f"aes-swarm dashboard: error: {exc}", file=sys.stderr)
        return 2
    env = dict(os.environ)
    if token is not None:  # to the node by environment, never argv
        env[TOKEN_VARIABLE] = token
    sc = load_scenario(args)
    with tempfile.TemporaryDirectory(prefix="aes-dashboard-") as tmp:
        name = args.scenario.stem if args.scenario is not None else args.setup
        scenario_file = write_scenario(sc, Path(tmp) / f"{name}.yaml")
        params = {
            "scenario": str(scenario_file),
            "host": args.host,
            "port": int(args.port),
            "use_sim_time": True,
        }
        return serve([sys.executable, *DASHBOARD_PROGRAM, *ros_args(params)], env)


def serve(command: Sequence[str], env: Mapping[str, str]) -> int:
    """Run ``command`` in the foreground until it exits; a SIGINT or SIGTERM sent to this
    process goes on to it (Ctrl-C in a terminal reaches both). Its exit code (128 + the
    signal if one killed it)."""
    child: list[subprocess.Popen] = []
    early: list[int] = []

    def forward(sig: int, _frame: object) -> None:
        if child:
            child[0].send_signal(sig)
        else:
            early.append(sig)

    previous = {s: signal.signal(s, forward) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        child.append(subprocess.Popen(list(command), env=dict(env)))
        for sig in early:
            child[0].send_signal(sig)
        code = child[0].wait()
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
    return code if code >= 0 else 128 - code

"""What bounds the start of a large swarm: creating ROS 2 nodes and their parameter services.

Plain rclpy nodes, no aes-swarm code: ``/mona_<i>/aes_robot`` with a ``cmd_vel`` and an
``aes_force`` publisher, with or without the six parameter services that Jazzy's
``ros2 param set`` waits for. Three measurements: (1) N nodes in one process, with and
without services; (2) 1000 nodes in P processes discovering each other, through a
discovery server, and each in a domain of its own (the floor); (3) 1000 nodes in one
process in P participants beside a reader of their ``cmd_vel`` (the robot host and the
bridge), until every reader matched. Fast DDS runs with its defaults or, with
``--profile launch``, the profile every launched process gets. Figures and what they
mean: docs/performance.md#starting-1000-robots.

Usage::

    python bench/bench_startup.py                     # ~10 min
    python bench/bench_startup.py --profile launch    # ~5 min
    python bench/bench_startup.py --quick             # smaller counts (~1 min)

Prints tables and a last ``RESULT`` line with ``machine_ref_us``.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aes_ros.ros import discovery as dds
from aes_ros.ros.launch.processes import PROFILE_VARIABLES, fastdds_environment
from aes_ros.ros.launch.shared_memory import clean_shared_memory

sys.path.insert(0, str(Path(__file__).resolve().parent))
from process_stats import machine_reference_us  # a sibling script, not a package

#: Domain IDs of this benchmark (far from the tests' and the launcher's defaults).
FIRST_DOMAIN = 150


def child(first: int, count: int, services: bool, participants: int = 1) -> int:
    """Create ``count`` robot-like nodes (in ``participants`` rclpy contexts, consecutive
    blocks as the robot host makes them), print the seconds it took, wait to be killed."""
    import rclpy
    from geometry_msgs.msg import Twist, Vector3Stamped
    from rclpy.node import Node

    contexts = [rclpy.Context() for _ in range(participants)]
    for context in contexts:
        rclpy.init(context=context)
    start = time.perf_counter()
    nodes = []
    for k, i in enumerate(range(first, first + count)):
        node = Node(
            "aes_robot",
            namespace=f"mona_{i}",
            start_parameter_services=services,
            context=contexts[k * participants // count],
        )
        node.create_publisher(Twist, "cmd_vel", 1)
        node.create_publisher(Vector3Stamped, "aes_force", 1)
        nodes.append(node)
    print(f"created {time.perf_counter() - start:.3f}", flush=True)
    # Killed, with all the others at once, by the parent: tearing the nodes down one by
    # one is quadratic too, and a process that leaves while others still send to it can
    # leave a shared-memory port locked (Fast DDS then blocks its senders for good).
    sys.stdin.read()
    return 0


def reader(count: int) -> int:
    """Subscribe to the ``cmd_vel`` of robots 0 … count-1 (as the bridge does) and print
    ``matched`` once every subscription has matched a publisher; then wait to be killed."""
    import rclpy
    from geometry_msgs.msg import Twist
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.experimental import EventsExecutor

    rclpy.init()
    node = rclpy.create_node("reader")
    matched: set[int] = set()

    def on_matched(i: int) -> Callable[[Any], None]:
        return lambda info: matched.add(i) if info.current_count > 0 else None

    for i in range(count):
        node.create_subscription(
            Twist, f"/mona_{i}/cmd_vel", lambda _msg: None, 1,
            event_callbacks=SubscriptionEventCallbacks(matched=on_matched(i)),
        )  # fmt: skip
    print("ready", flush=True)
    executor = EventsExecutor()
    executor.add_node(node)
    while len(matched) < count:
        executor.spin_once(timeout_sec=0.1)
    print("matched", flush=True)
    sys.stdin.read()
    return 0


def child_environment(profile: str) -> dict[str, str]:
    """The children's environment: Fast DDS's defaults, or (``launch``) the launch's profile."""
    env = {k: v for k, v in os.environ.items() if k not in PROFILE_VARIABLES}
    return fastdds_environment(env) if profile == "launch" else env


def _start_server(env: dict[str, str], started: list[subprocess.Popen]) -> dict[str, str]:
    """Start a discovery server on a free port (appended to ``started``); ``env`` for its
    clients."""
    port = dds.free_udp_port()
    argv = dds.server_argv(port, "127.0.0.1")
    started.append(subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL))
    return dds.Discovery("server", f"127.0.0.1:{port}").client_environment(env)


def _kill_all(procs: list[subprocess.Popen], domains: set[int]) -> None:
    """Kill ``procs`` all at once, then remove what they left in the shared memory of
    ``domains``."""
    for proc in procs:
        proc.kill()
    for proc in procs:
        proc.wait()
    for domain in domains:
        clean_shared_memory(domain)


def _run_children(
    env: dict[str, str],
    domains: list[int],
    shares: list[tuple[int, int]],
    services: bool,
    server: bool = False,
) -> tuple[list[float], float]:
    """Start one child per share (``(first, count)``, in the ROS domain beside it; with
    ``server``, a discovery server first and the children its clients), and once all are
    done: each one's creation seconds and the wall seconds from starting them. Then kill
    them all together and remove what they left in shared memory."""
    cmd = [sys.executable, __file__, "--child"]
    start = time.perf_counter()
    started: list[subprocess.Popen] = []
    if server:
        env = _start_server(env, started)
    children = [
        subprocess.Popen(
            [*cmd, str(first), str(count), str(int(services))],
            env=dict(env, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                     ROS_DOMAIN_ID=str(domain)),
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
        )
        for domain, (first, count) in zip(domains, shares, strict=True)
    ]  # fmt: skip
    started += children
    try:
        lines = [proc.stdout.readline() for proc in children]
        wall = time.perf_counter() - start
    finally:
        _kill_all(started, set(domains))
    if not all(line.startswith("created") for line in lines):
        raise RuntimeError(f"a child failed: {lines!r}")
    return [float(line.split()[1]) for line in lines], wall


def start_processes(
    env: dict[str, str],
    robots: int,
    processes: int,
    services: bool,
    shared: bool,
    server: bool = False,
) -> float:
    """Wall seconds until every one of ``processes`` children created its robots (in one
    domain if ``shared``, through a discovery server if ``server``)."""
    share = robots // processes
    domains = [FIRST_DOMAIN if shared else FIRST_DOMAIN + 1 + p for p in range(processes)]
    shares = [(p * share, share) for p in range(processes)]
    _, wall = _run_children(env, domains, shares, services, server)
    return wall


def participants_beside_reader(
    env: dict[str, str], robots: int, participants: int, server: bool, limit: float
) -> float:
    """Wall seconds until a reader of every robot's ``cmd_vel``, started first, has matched
    the ``robots`` nodes (with their services) one process makes in ``participants``
    participants; ``inf`` after ``limit`` s."""
    procs: list[subprocess.Popen] = []
    if server:
        env = _start_server(env, procs)
    env = dict(env, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(FIRST_DOMAIN))
    pipes = {"stdin": subprocess.PIPE, "stdout": subprocess.PIPE, "text": True}
    maker = [sys.executable, __file__, "--child", "0", str(robots), "1", str(participants)]
    start = time.perf_counter()
    try:
        read = subprocess.Popen(
            [sys.executable, __file__, "--reader", str(robots)], env=env, **pipes
        )
        procs.append(read)
        if read.stdout.readline().strip() != "ready":
            raise RuntimeError("the reader failed to start")
        procs.append(subprocess.Popen(maker, env=env, **pipes))
        # past the limit the reader is killed, and its next line is ""
        timer = threading.Timer(max(0.0, start + limit - time.perf_counter()), read.kill)
        timer.start()
        matched = read.stdout.readline().strip() == "matched"
        timer.cancel()
        return time.perf_counter() - start if matched else math.inf
    finally:
        _kill_all(procs, {FIRST_DOMAIN})


def one_process(env: dict[str, str], robots: int, services: bool) -> float:
    """Seconds one process takes to create ``robots`` nodes (its own count, not the wall)."""
    (seconds,), _ = _run_children(env, [FIRST_DOMAIN], [(0, robots)], services)
    return seconds


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller counts (~1 min)")
    parser.add_argument(
        "--profile",
        choices=("default", "launch"),
        default="default",
        help="Fast DDS's defaults, or the profile of aes-swarm launch",
    )
    parser.add_argument("--child", nargs="+", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--reader", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        first, count, services, *participants = args.child
        return child(first, count, bool(services), *participants)
    if args.reader:
        return reader(args.reader)

    env = child_environment(args.profile)
    ref_before = machine_reference_us()
    single = (50, 100) if args.quick else (50, 100, 200, 300)
    robots, splits = (200, (2, 10)) if args.quick else (1000, (2, 10, 20))
    print(f"machine: {ref_before:.2f} µs per agent-step of bench_sim's per-agent loop")
    print(f"Fast DDS profile: {env.get(PROFILE_VARIABLES[0], 'none (defaults)')}")
    print("\none process: seconds to create N nodes")
    print(f"{'N':>6} {'no services':>12} {'6 services':>11} {'ratio':>6}")
    ratios = {}
    for n in single:
        bare, full = one_process(env, n, False), one_process(env, n, True)
        ratios[n] = full / bare
        print(f"{n:>6} {bare:>12.2f} {full:>11.2f} {ratios[n]:>6.1f}", flush=True)

    print(f"\n{robots} nodes with their 6 services in P processes: wall seconds until all exist")
    print(
        f"{'P':>4} {'discovering each other':>23} {'discovery server':>17} {'isolated (floor)':>17}"
    )
    walls = {}
    for p in splits:
        walls[p] = (
            start_processes(env, robots, p, True, True),
            start_processes(env, robots, p, True, True, server=True),
            start_processes(env, robots, p, True, False),
        )
        print(f"{p:>4} {walls[p][0]:>23.1f} {walls[p][1]:>17.1f} {walls[p][2]:>17.1f}", flush=True)
    print(
        f"\n{robots} nodes with their 6 services in one process, in P participants, beside a "
        "reader of their cmd_vel:\nwall seconds until it matched every one"
    )
    print(f"{'P':>4} {'simple discovery':>17} {'discovery server':>17}")
    matched = {}
    limit = 60.0 if args.quick else 120.0
    for p in (1, 4) if args.quick else (1, 4, 10):
        matched[p] = [
            participants_beside_reader(env, robots, p, server, limit) for server in (False, True)
        ]
        print(f"{p:>4} {matched[p][0]:>17.1f} {matched[p][1]:>17.1f}", flush=True)
    matched_text = " ".join(
        f"matched_s_{mode}_p{p}={m[k]:.1f}"
        for p, m in matched.items()
        for k, mode in enumerate(("simple", "server"))
    )
    ref = (ref_before + machine_reference_us()) / 2
    best_shared, best_server, best_isolated = (min(w[k] for w in walls.values()) for k in range(3))
    ratio_text = " ".join(f"services_ratio_{n}={r:.1f}" for n, r in ratios.items())
    print(
        f"RESULT profile={args.profile} robots={robots} start_s_shared={best_shared:.1f} "
        f"start_s_server={best_server:.1f} start_s_isolated={best_isolated:.1f} {ratio_text} "
        f"{matched_text} "
        f"machine_ref_us={ref:.2f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

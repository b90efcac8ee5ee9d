"""The bridge's kinematic step with contacts off and on, side by side, no ROS.

Steps two :class:`sim_bridge.world.World` of the combined scenario's swarm (one with
``contacts`` off, which still counts contacts with ``measure_contacts``, one with them on,
which resolves them with ``resolve_contacts``) in alternating blocks of ``--steps`` steps and
prints µs per robot-step of each block, then ``RESULT off_us=<median> on_us=<median>
ratio=<median of the blocks' on/off>``: the most contacts can add to ``bench_ros.py``'s CPU
per robot-step.

Usage: ``python bench/bench_contacts_step.py [--robots 100] [--rounds 7] [--steps 500]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from aes_ros import scenario
from sim_bridge.world import World


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=100, help="robots N (default 100)")
    parser.add_argument("--rounds", type=int, default=7, help="blocks per mode (default 7)")
    parser.add_argument("--steps", type=int, default=500, help="steps per block (default 500)")
    args = parser.parse_args()
    for name in ("robots", "rounds", "steps"):
        if getattr(args, name) < 1:
            parser.error(f"--{name}: need >= 1")
    sc = scenario.load("combined", {"contacts": False}).with_robots(args.robots)
    positions, headings = sc.initial_state(0)
    n = len(headings)
    worlds = {on: World(positions, headings, dt=0.02, contacts=on) for on in (False, True)}
    # Forward with random turns, so that bodies meet; both worlds get the same commands.
    rng = np.random.default_rng(0)
    u, turn = np.full(n, 0.05), rng.normal(0.0, 0.3, n)
    for world in worlds.values():
        for _ in range(50):  # load the kernels
            world.step((u, turn))
    us: dict[bool, list[float]] = {False: [], True: []}
    for _ in range(args.rounds):
        for on, world in worlds.items():
            start = time.perf_counter()
            for _ in range(args.steps):
                world.step((u, turn))
            us[on].append((time.perf_counter() - start) / (args.steps * n) * 1e6)
    for on in (False, True):
        blocks = " ".join(f"{v:.3f}" for v in us[on])
        print(f"contacts {'on ' if on else 'off'}: {blocks} µs/robot-step")
    ratios = [b / a for a, b in zip(us[False], us[True], strict=True)]
    print(
        f"RESULT off_us={np.median(us[False]):.3f} on_us={np.median(us[True]):.3f} "
        f"ratio={np.median(ratios):.2f} spread={min(ratios):.2f}-{max(ratios):.2f}"
    )


if __name__ == "__main__":
    main()

"""Cost of the simulated IR proximity sensors per robot-step, against the step itself.

Measured side by side in one run, for the 100-robot combined scenario at its initial
state (robots 0.2 m apart, so rays meet neighbours):

- ``kernel``: the numba rays (:func:`aes_ros.ir.ray_distances`, what the offline kernel
  calls) and :func:`aes_ros.ir_readings.ir_ranges` (numpy entry point: rays, noise and response
  curve) against one robot-step of the offline simulator (batch 1, the same scenario);
- ``pybullet``: :func:`sim_bridge.ir_sensors.cast_ir` (one ``rayTestBatch``) against one
  control step of :class:`sim_bridge.world.World`, kinematic and dynamic;
- ``publish``: the bridge's :class:`sim_bridge.ir_sensors.IrSensors` casting and
  publishing 5 N ``sensor_msgs/Range`` at every step to a subscriber on every topic,
  against the bridge's own step and ``publish_state`` (poses and clock; odometry to
  nobody) without IR; ROS in its own domain.

Prints a table [µs per robot] and, as its last line,
``RESULT kernel_ratio=<IR / sim step> pybullet_ratio=<IR / kinematic world step>
publish_ratio=<IR published / bridge step>``.

Usage: ``python bench/bench_ir.py [--robots 100] [--calls 200]``
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from aes_ros import scenario, simulator
from aes_ros.ir import IR_ANGLES, ray_distances
from aes_ros.ir_readings import IrResponse, ir_ranges
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.mona.sensors import IrModel
from sim_bridge.ir_sensors import cast_ir
from sim_bridge.world import World

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


def per_call(fn: Callable[[], object], repeat: int, rounds: int = 5) -> float:
    """Best of ``rounds`` timings of ``repeat`` calls [s per call] (the machine is shared)."""
    fn()  # compile, warm caches
    best = np.inf
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(repeat):
            fn()
        best = min(best, (time.perf_counter() - t0) / repeat)
    return best


def offline(n: int, repeat: int) -> tuple[float, float, float]:
    """(rays of the numba kernel, ir_ranges with noise and response, simulator step)
    [s per robot]."""
    sc = scenario.load("combined").with_robots(n)
    positions, headings = sc.initial_state(0)
    response = IrResponse(noise=0.002)
    rng = np.random.default_rng(0)
    out = np.empty((n, len(IR_ANGLES)))
    none, g = np.zeros(0), MonaGeometry()
    rays = per_call(
        lambda: ray_distances(
            positions,
            headings,
            g.body_radius,
            g.axle_offset,
            IR_ANGLES,
            response.model.max_range,
            none,
            none.reshape(0, 3),
            none.reshape(0, 4),
            out,
        ),
        repeat,
    )
    ir = per_call(lambda: ir_ranges(positions, headings, response=response, rng=rng), repeat)
    long = sc.with_overrides({"duration": 120.0})  # set-up costs spread over many steps
    step = per_call(lambda: simulator.simulate(long, [0], record=False), 1, 3) / long.n_steps
    return rays / n, ir / n, step / n


def in_pybullet(n: int, repeat: int, mode: str) -> tuple[float, float]:
    """(IR rays, world step) [s per robot] in a ``mode`` world."""
    sc = scenario.load("combined").with_robots(n)
    positions, headings = sc.initial_state(0)
    with World(positions, headings, mode=mode, dt=sc.dt) as world:
        commands = (np.full(n, 0.02), np.full(n, 0.1))
        max_range = IrModel().max_range

        def step_and_cast() -> None:
            world.step(commands)
            cast_ir(world, max_range)

        step = per_call(lambda: world.step(commands), repeat)
        if mode == "dynamic":  # bodies always in place: the rays alone
            return per_call(lambda: cast_ir(world, max_range), repeat) / n, step / n
        # kinematic: the rays first place the bodies the step moved
        both = per_call(step_and_cast, repeat)
    return (both - step) / n, step / n


def publishing(n: int, repeat: int) -> tuple[float, float]:
    """(IR cast and published to subscribers, the bridge's step and publish_state without
    IR) [s per robot], in a kinematic bridge."""
    from helpers.ros_env import reserved_domain_id, ros_variables

    with reserved_domain_id() as domain:
        os.environ.update(ros_variables(domain))
        import rclpy
        from rclpy.parameter import Parameter
        from sensor_msgs.msg import Range

        from aes_ros.ros import interface as names
        from aes_ros.ros.qos import SENSOR
        from sim_bridge.node import SimBridgeNode

        rclpy.init(args=["--ros-args", "--log-level", "warn"])
        bridge = SimBridgeNode(
            parameter_overrides=[Parameter("num_robots", value=n), Parameter("ir_rate", value=0.0)]
        )
        listener = rclpy.create_node("ir_listener")
        for i in range(n):
            for k in range(5):
                topic = names.robot_topic(i, f"{names.IR}_{k}")
                listener.create_subscription(Range, topic, lambda _m: None, SENSOR)

        def step() -> None:
            bridge.world.step()
            bridge.publish_state()

        try:
            off = per_call(step, repeat)
            bridge.ir.rate = bridge.rate  # a reading at every step
            bridge.ir._create_publishers()
            deadline = time.monotonic() + 20.0
            while len(bridge.ir.listened) < n and time.monotonic() < deadline:
                step()
                time.sleep(0.05)
            on = per_call(step, repeat)
            if len(bridge.ir.listened) < n:
                raise RuntimeError(f"only {len(bridge.ir.listened)} robots' IR topics matched")
        finally:
            listener.destroy_node()
            bridge.destroy_node()
            rclpy.try_shutdown()
    return (on - off) / n, off / n


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=100, help="N (default 100)")
    parser.add_argument("--calls", type=int, default=200, help="calls per timing")
    args = parser.parse_args()
    n, repeat = args.robots, args.calls
    rays, ir, step = offline(n, repeat)
    rows = [
        ("kernel rays (numba) vs offline sim step", rays, step),
        ("ir_ranges (+noise, response) vs sim step", ir, step),
    ]
    for mode in ("kinematic", "dynamic"):
        rows.append((f"pybullet rays vs {mode} world step", *in_pybullet(n, repeat, mode)))
    rows.append(("bridge: IR published vs bridge step", *publishing(n, max(20, repeat // 10))))
    print(f"{n} robots; µs per robot")
    print(f"| {'what':<40} | {'IR':>8} | {'step':>8} | {'IR / step':>9} |")
    print(f"|{'-' * 42}|{'-' * 10}|{'-' * 10}|{'-' * 11}|")
    for what, ir, step in rows:
        print(f"| {what:<40} | {ir * 1e6:8.3f} | {step * 1e6:8.3f} | {ir / step:9.2f} |")
    ratios = [ir / step for _, ir, step in rows]
    print(
        f"RESULT kernel_ratio={ratios[0]:.3g} pybullet_ratio={ratios[2]:.3g} "
        f"publish_ratio={ratios[4]:.3g}"
    )


if __name__ == "__main__":
    main()

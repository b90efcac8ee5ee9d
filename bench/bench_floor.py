"""The floor under the CPU per robot-step: what one ``cmd_vel`` topic per robot costs at the least.

Issue #13 asks 1000 robots at 20 Hz with ≥ 95 % of the steps answered. On two cores
that leaves at most ``2e6 / (0.95 · N · rate)`` µs of CPU per robot-step for the whole
system (105 µs at 1000 robots, 20 Hz). This script measures, each part alone and in
this run, the work no design with one ``cmd_vel`` topic per robot (docs/design.md#ros-interface) can
avoid, with nothing else of the system running:

1. ``control``: a robot host's work per step without ROS: decode one ``/swarm/poses``
   of N robots (:func:`aes_ros.ros.cdr.decode_pose_array`), each robot's
   :meth:`robot_node.controller.RobotController.poses_input`, one
   :func:`aes_ros.robot_batch.evaluate_robots` for all, one :func:`aes_ros.ros.cdr.encode_twist`
   each.
2. ``publish``: a process with N publishers ``/mona_<i>/cmd_vel`` (the robots' QoS)
   publishing one raw Twist per robot per step at ``rate`` Hz; its CPU per message,
   DDS threads included.
3. ``receive``: a second process with N raw subscriptions on an EventsExecutor with
   the bridge's QoS (best effort, depth 1), decoding each Twist; its CPU per message.

The sum is the floor; it leaves out the bridge's physics step, ``/swarm/poses``,
``/clock``, the supervisor and the executors' timers, which the real system also pays.

Usage::

    python bench/bench_floor.py                       # 1000 robots at 20 Hz (~2 min)
    python bench/bench_floor.py --robots 100 --rate 50

Last line: ``RESULT floor robots=… hz=… control_us=… publish_us=… receive_us=…
floor_us=… budget_us=… machine_ref_us=…`` (all µs of CPU per robot-step).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from aes_ros import scenario as scenario_mod
from aes_ros.cli.deprecated import add_deprecated
from aes_ros.ros.launch.shared_memory import clean_shared_memory

sys.path.insert(0, str(Path(__file__).resolve().parent))
from process_stats import machine_reference_us  # a sibling script, not a package

#: ROS domain of this benchmark (far from the tests' and the launcher's).
DOMAIN = 170
#: Share of the steps the issue asks to be answered, and the machine's cores.
ANSWERED = 0.95
CORES = 2


def control_us(robots: int, rate: float, steps: int) -> float:
    """µs of CPU per robot-step of the control law of ``robots`` robots, without ROS."""
    from aes_ros.robot_batch import evaluate_robots
    from aes_ros.ros.cdr import PoseArrayEncoder, decode_pose_array, encode_twist
    from robot_node.controller import RobotController, RobotSettings
    from robot_node.rotation_center import rotation_center_rule

    sc = scenario_mod.load("combined", {"dt": 1.0 / rate}).with_robots(robots)
    _, table, rest = sc.sheet()
    controllers = []
    center = rotation_center_rule(sc.command)  # one per process, as in SwarmInputs
    for i in range(robots):
        keep = table[i] >= 0
        settings = RobotSettings(
            robot_id=i,
            neighbors=tuple(table[i][keep].tolist()),
            rest_lengths=tuple(rest[i][keep].tolist()),
            gains=sc.gains,
            limits=(sc.max_linear_speed, sc.max_angular_speed),
            neighbor_timeout=1.0,
            seed=0,
            neighbor_source="poses",
        )
        controllers.append(RobotController(settings, sc.command, print, print, center=center))
    positions, headings = sc.initial_state(0)
    encoder = PoseArrayEncoder(robots)
    rng = np.random.default_rng(0)
    period_ns = round(1e9 / rate)

    def step(k: int) -> None:
        stamp_ns = k * period_ns
        data = encoder.encode(stamp_ns // 10**9, stamp_ns % 10**9, positions, headings)
        _, _, xy, yaw = decode_pose_array(data)
        centroid = xy.mean(axis=0)
        center.on_poses(stamp_ns, centroid)
        inputs = [c.poses_input(stamp_ns, xy, yaw, centroid) for c in controllers]
        for result in evaluate_robots(inputs):
            encode_twist(result.linear, result.angular)

    for k in range(3):  # rest lengths latched, caches warm
        step(k)
    start = time.process_time()
    for k in range(3, 3 + steps):
        positions += rng.normal(0.0, 1e-3, positions.shape)  # the swarm moves a little
        step(k)
    return (time.process_time() - start) / (steps * robots) * 1e6


def writer(robots: int, rate: float, seconds: float) -> dict[str, float]:
    """Child: publish one raw Twist per robot per step; CPU per message over ``seconds``."""
    import rclpy
    from geometry_msgs.msg import Twist
    from rclpy.node import Node

    from aes_ros.ros.cdr import encode_twist
    from aes_ros.ros.qos import COMMAND_KEPT

    rclpy.init()
    node = Node("floor_writer", start_parameter_services=False)
    pubs = [node.create_publisher(Twist, f"/mona_{i}/cmd_vel", COMMAND_KEPT) for i in range(robots)]
    deadline = time.monotonic() + 300.0
    while min(p.get_subscription_count() for p in pubs) < 1:  # the reader knows them all
        if time.monotonic() > deadline:
            raise RuntimeError("the reader did not match every cmd_vel within 300 s")
        time.sleep(0.1)
    data = encode_twist(0.05, 0.1)
    period = 1.0 / rate
    warmup = max(1, round(rate))  # a second
    count = warmup + round(seconds * rate)
    next_t = time.monotonic()
    cpu0 = 0.0
    for k in range(count):
        if k == warmup:
            cpu0 = time.process_time()
        for pub in pubs:
            pub.publish(data)
        next_t += period
        time.sleep(max(0.0, next_t - time.monotonic()))
    cpu = time.process_time() - cpu0
    return {"publish_us": cpu / ((count - warmup) * robots) * 1e6}


def reader(robots: int) -> dict[str, float]:
    """Child: N raw cmd_vel subscriptions on an EventsExecutor, each message decoded;
    CPU per message between 20 % and 90 % of the stream (ends 3 s after it stops)."""
    import rclpy
    from geometry_msgs.msg import Twist
    from rclpy.experimental import EventsExecutor
    from rclpy.node import Node
    from rclpy.task import Future

    from aes_ros.ros.cdr import decode_twist
    from aes_ros.ros.qos import LATEST_COMMAND

    rclpy.init()
    node = Node("floor_reader", start_parameter_services=False)
    received = [0]
    samples: list[tuple[int, float, float]] = []
    latest = np.zeros((robots, 2))

    def callback(i: int) -> Callable[[bytes], None]:
        def on_cmd_vel(data: bytes) -> None:
            latest[i] = decode_twist(data)
            received[0] += 1
            if received[0] % robots == 0:  # about once a step
                samples.append((received[0], time.process_time(), time.monotonic()))

        return on_cmd_vel

    for i in range(robots):
        node.create_subscription(
            Twist, f"/mona_{i}/cmd_vel", callback(i), LATEST_COMMAND, raw=True
        )  # the bridge's QoS: best effort, the newest command only
    print("ready", flush=True)
    executor = EventsExecutor()
    executor.add_node(node)
    while not samples or time.monotonic() - samples[-1][2] < 3.0:
        executor.spin_until_future_complete(Future(), timeout_sec=0.5)
    first, span = samples[0][2], samples[-1][2] - samples[0][2]
    window = [s for s in samples if first + 0.2 * span <= s[2] <= first + 0.9 * span]
    if len(window) < 2:
        raise RuntimeError(f"too few messages to measure ({received[0]}): publish for longer")
    (n0, c0, _), (n1, c1, _) = window[0], window[-1]
    return {"receive_us": (c1 - c0) / (n1 - n0) * 1e6, "received": received[0]}


def transport_us(robots: int, rate: float, seconds: float) -> dict[str, float]:
    """Run the reader and the writer children; their figures. Each child reports and
    leaves with ``os._exit`` (tearing 1000 endpoints down is slow, and a child stuck
    in it must not hold the benchmark): on any error both are killed."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(DOMAIN))
    cmd = [sys.executable, __file__, "--robots", str(robots), "--rate", str(rate)]
    timeout = 300.0 + 3 * seconds
    read = subprocess.Popen([*cmd, "--child", "reader"], env=env, stdout=subprocess.PIPE, text=True)
    write = None
    try:
        if read.stdout.readline().strip() != "ready":
            raise RuntimeError("the reader child did not start")
        write = subprocess.Popen(
            [*cmd, "--child", "writer", "--duration", str(seconds)],
            env=env, stdout=subprocess.PIPE, text=True,
        )  # fmt: skip
        out_w, _ = write.communicate(timeout=timeout)
        out_r, _ = read.communicate(timeout=timeout)
        return {**json.loads(out_w.splitlines()[-1]), **json.loads(out_r.splitlines()[-1])}
    finally:
        for proc in (read, write):
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.wait()
        clean_shared_memory(DOMAIN)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", type=int, default=1000)
    parser.add_argument("--rate", type=float, default=20.0, help="control rate [Hz]")
    parser.add_argument("--duration", type=float, default=20.0, help="measured publishing [s]")
    add_deprecated(parser, "--seconds", "--duration")
    parser.add_argument("--child", choices=("reader", "writer"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child == "reader":
        print(json.dumps(reader(args.robots)), flush=True)
        os._exit(0)
    if args.child == "writer":
        print(json.dumps(writer(args.robots, args.rate, args.duration)), flush=True)
        os._exit(0)

    n, rate = args.robots, args.rate
    ref_before = machine_reference_us()
    control = control_us(n, rate, steps=max(20, round(20_000 / n)))
    print(f"control law of {n} robots, no ROS: {control:.1f} µs per robot-step", flush=True)
    t = transport_us(n, rate, args.duration)
    print(
        f"cmd_vel, {n} topics at {rate:g} Hz: publish {t['publish_us']:.1f} µs, "
        f"receive {t['receive_us']:.1f} µs per message ({t['received']} received)",
        flush=True,
    )
    ref = 0.5 * (ref_before + machine_reference_us())
    floor = control + t["publish_us"] + t["receive_us"]
    budget = CORES * 1e6 / (ANSWERED * n * rate)
    print(
        f"floor {floor:.1f} µs per robot-step against a budget of {budget:.1f} µs "
        f"({ANSWERED:.0%} of {n} robots at {rate:g} Hz on {CORES} cores): "
        f"{floor / budget:.0%} of the budget before the bridge, the clock and the executors"
    )
    print(
        f"RESULT floor robots={n} hz={rate:g} control_us={control:.1f} "
        f"publish_us={t['publish_us']:.1f} receive_us={t['receive_us']:.1f} "
        f"floor_us={floor:.1f} budget_us={budget:.1f} machine_ref_us={ref:.2f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark of the real ROS 2 system: control rate, real-time factor, latency, CPU, memory.

For every configuration (robot count, control rate, neighbour source, layout, discovery)
it starts the system as ``aes-swarm launch`` does, waits until every robot moves and
measures a steady window: ``cmd_vel`` rate per robot at the bridge, RTF, latency from a
state to its ``cmd_vel``, CPU and memory of every process, and the CPU per robot-step
beside the straightforward design (``bench/naive_swarm.py``) and the machine's speed
(``machine_ref_us``). Its last line is ``RESULT …`` for 100 robots, 50 Hz, poses; before
it, the goals its rows can judge, each met or not with what bounds it. What each figure
means: docs/performance.md.

Usage::

    python bench/bench_ros.py                       # the standard grid (~15 min)
    python bench/bench_ros.py --robots 100 --rates 50 --sources poses --layouts auto,per-core
    python bench/bench_ros.py --quick               # smoke version for CI (~30 s)
    python bench/bench_ros.py --robots 1000 --rates 20 --discovery simple,server --runs 3 \
        --no-baseline                               # discovery modes side by side (~15 min)
    python bench/bench_ros.py --physics             # only the bridge physics line
    python bench/bench_ros.py --robots 100 --rates 50 --contacts off,on --runs 3 \
        --no-baseline                               # contacts' cost, off and on interleaved

Writes ``bench_ros.csv`` and ``bench_ros.png`` to ``--out`` (default ``out/bench_ros``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from aes_ros import scenario as scenario_mod
from aes_ros.cli.deprecated import add_deprecated
from aes_ros.cli.options import MAX_RUNS, number_type
from aes_ros.ros.discovery import SERVER_PROCESS

sys.path.insert(0, str(Path(__file__).resolve().parent))
from process_stats import cpu_seconds, machine_reference_us, pss_mb  # sibling scripts
from ros_contacts import contacts_lines, contacts_modes
from ros_naive import measure_naive
from ros_rows import (
    Row,
    discovery_lines,
    find_row,
    goal_lines,
    per_robot_step,
    plot,
    print_table,
    write_csv,
)

#: The standard grid: (robots, rate [Hz], source, layout).
STANDARD_GRID = [
    *[(n, r, "poses", "auto") for n in (16, 100, 400, 1000) for r in (10, 20, 50)],
    *[(n, r, "odom", "auto") for n in (16, 100) for r in (10, 20, 50)],
    (400, 10, "odom", "auto"),
    (100, 50, "poses", "per-core"),
    (100, 50, "odom", "per-core"),
    (16, 20, "poses", "single"),
    (100, 20, "poses", "single"),
    (16, 20, "poses", "per-robot"),
    (16, 20, "odom", "per-robot"),
]
QUICK_GRID = [(16, 20, "poses", "auto")]
#: The RESULT line's configuration when the grid has it: (robots, rate [Hz], source).
REFERENCE = (100, 50, "poses")
#: The most robots the straightforward design is measured at. It runs 10 robots per process:
#: at 1000 robots that is 100 rclpy processes, which take far longer to start than the
#: measurement itself, so a larger RESULT line gets its baseline at the reference size.
BASELINE_MAX_ROBOTS = 100


def measure(
    robots: int,
    rate: float,
    source: str,
    layout: str,
    warmup: float,
    window: float,
    discovery: str = "auto",
    run: int = 1,
    contacts: bool | None = None,
    bodies: dict | None = None,
) -> Row:
    from aes_ros.ros.launch import LaunchConfig, Launcher
    from aes_ros.ros.launch.config import resolved_discovery
    from aes_ros.ros.launch.layout import resolved_layout

    overrides = {"dt": 1.0 / rate} | ({} if contacts is None else {"contacts": contacts})
    sc = scenario_mod.load("combined", overrides).with_robots(robots)
    config = LaunchConfig(
        sc, label="bench", layout=layout, neighbor_source=source, mode="kinematic",
        duration=0.0, start_timeout=600.0, discovery=discovery,
    )  # fmt: skip
    layout = resolved_layout(config)  # the table shows what `auto` chose
    discovery = resolved_discovery(config)
    launcher = Launcher(config, say=lambda _text: None)
    t0 = time.monotonic()
    try:
        launcher.start()
        launcher.wait_until_moving()
        start_s = time.monotonic() - t0
        launcher.spin_for(warmup)
        launcher.monitor.bridge_stats()  # resets the bridge's counters
        pids = {c.name: c.proc.pid for c in launcher.procs.children}
        pids["launcher"] = os.getpid()
        cpu0 = {name: cpu_seconds(pid) for name, pid in pids.items()}
        w0 = time.monotonic()
        launcher.spin_for(window)
        stats = launcher.monitor.bridge_stats()
        wall = time.monotonic() - w0
        cpu = {name: 100.0 * (cpu_seconds(pid) - cpu0[name]) / wall for name, pid in pids.items()}
        memory = sum(pss_mb(pid) for name, pid in pids.items())
        if bodies is not None:  # what /sim/stats says of the bodies in the window
            bodies.update({k: stats.get(k) for k in ("contacts_per_s", "min_centre_distance_m")})
    finally:
        launcher.stop()
        launcher.cleanup(True)
    robot_cpu = sum(v for k, v in cpu.items() if k.startswith("robot"))
    server_cpu = cpu.get(SERVER_PROCESS, 0.0)  # part of the system's cost when there is one
    system_cpu = cpu["sim_bridge"] + cpu["supervisor"] + robot_cpu + server_cpu
    return Row(
        robots, rate, source, layout, start_s, stats["real_time_factor"],
        stats["rate_min_hz"], stats["rate_median_hz"],
        stats["latency_p50_ms"] or float("nan"), stats["latency_p99_ms"] or float("nan"),
        cpu["sim_bridge"], cpu["supervisor"], robot_cpu, cpu["launcher"], memory,
        len(pids) - 1, per_robot_step(system_cpu, stats, robots), "aes", discovery, run,
        server_cpu,
    )  # fmt: skip


def physics_rtf(robots: int = 100, physics_rate: float = 240.0, seconds: float = 10.0) -> float:
    """Real-time factor of the pybullet world alone: ``dynamic`` mode, no ROS."""
    from sim_bridge.world import World

    sc = scenario_mod.load("combined").with_robots(robots)
    positions, headings = sc.initial_state(0)
    dt = sc.dt
    with World(positions, headings, mode="dynamic", dt=dt, physics_rate=physics_rate) as world:
        rng = np.random.default_rng(0)
        steps = round(seconds / dt)
        t0 = time.perf_counter()
        for _ in range(steps):
            world.set_commands(rng.uniform(0, 0.1, robots), rng.uniform(-1, 1, robots))
            world.step()
            world.poses()
        wall = time.perf_counter() - t0
    return steps * dt / wall


def baseline_size(robots: int, rate: float) -> tuple[int, float]:
    """(robots, rate [Hz]) at which the straightforward design is measured for a RESULT line
    of ``robots`` at ``rate``: the same, or the reference size (``REFERENCE``) when that is
    more than ``BASELINE_MAX_ROBOTS``. Either way this design is compared at that size."""
    if robots <= BASELINE_MAX_ROBOTS:
        return robots, rate
    return REFERENCE[0], REFERENCE[1]


def _ints(text: str) -> list[int]:
    return [int(v) for v in text.split(",") if v]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=_ints, help="robot counts, e.g. 16,100")
    parser.add_argument("--rates", type=_ints, help="control rates [Hz], e.g. 10,20,50")
    parser.add_argument("--sources", default="poses", help="poses,odom")
    parser.add_argument(
        "--layouts", default="auto", help="auto,single,per-core,per-robot (auto: as launch)"
    )
    parser.add_argument("--quick", action="store_true", help="one small configuration (CI smoke)")
    parser.add_argument("--physics", action="store_true", help="only the bridge physics line")
    parser.add_argument(
        "--no-baseline", action="store_true",
        help="skip the straightforward design (bench/naive_swarm.py) of the reference line",
    )  # fmt: skip
    parser.add_argument(
        "--discovery", default="auto",
        help="simple,server,auto: measured side by side, one after the other (auto: as launch)",
    )  # fmt: skip
    parser.add_argument(
        "--runs", type=number_type(int, 1, MAX_RUNS), default=1, metavar="N",
        help="runs of the whole grid, the modes interleaved (default 1)",
    )  # fmt: skip
    add_deprecated(parser, "--repeat", "--runs")
    parser.add_argument(
        "--contacts", default="",
        help="off, on or off,on (measured side by side, interleaved); default: the scenario's",
    )  # fmt: skip
    parser.add_argument("--warmup", type=float, default=3.0, help="wall seconds before measuring")
    parser.add_argument("--window", type=float, default=10.0, help="wall seconds measured")
    parser.add_argument("--out", type=Path, default=Path("out/bench_ros"))
    args = parser.parse_args(argv)
    try:
        contacts = contacts_modes(args.contacts)
    except ValueError as exc:
        parser.error(str(exc))

    rtf = physics_rtf(seconds=2.0 if args.quick else 10.0)
    line = f"physics: 100 robots, dynamic mode, 240 Hz, no ROS: RTF {rtf:.2f}"
    print(line, flush=True)
    if args.physics:
        return 0
    if args.quick:
        grid, args.warmup, args.window = QUICK_GRID, 1.0, 3.0
    elif args.robots or args.rates:
        grid = [
            (n, r, s, lay)
            for n in (args.robots or [100])
            for r in (args.rates or [50])
            for s in args.sources.split(",")
            for lay in args.layouts.split(",")
        ]
    else:
        grid = STANDARD_GRID

    args.out.mkdir(parents=True, exist_ok=True)
    ref_before = machine_reference_us()
    rows: list[Row] = []
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        tqdm = None
    modes = args.discovery.split(",")
    runs = [
        (run, *config, mode, on)
        for run in range(1, args.runs + 1)
        for config in grid
        for mode in modes
        for on in contacts
    ]
    configs = tqdm(runs, desc="configurations", file=sys.stderr) if tqdm else runs
    measured = []  # (row, contacts, what /sim/stats said of the bodies)
    for run, n, rate, source, layout, mode, on in configs:
        bodies: dict = {}
        try:
            row = measure(n, rate, source, layout, args.warmup, args.window, mode, run, on, bodies)
        except Exception as exc:  # one failing configuration must not lose the others
            print(f"{n} robots {rate} Hz {source} {layout} {mode}: FAILED: {exc}", flush=True)
            continue
        rows.append(row)
        measured.append((row, on, bodies))
        said = "" if on is None else f"  contacts {'on' if on else 'off'}"
        print("  ".join(row.cells()) + said, flush=True)
    if not rows:
        print("RESULT failed: no configuration measured")
        return 1
    key = find_row(rows, *REFERENCE) or rows[0]
    naive = None
    ratios = ""
    if not args.no_baseline:
        # the naive design and this one (poses and odometry) at the same robots and rate
        base_n, base_rate = baseline_size(key.robots, key.rate)
        if (base_n, base_rate) != (key.robots, key.rate):
            print(
                f"baseline: not at {key.robots} robots ({-(-key.robots // 10)} processes of the "
                f"straightforward design start for longer than the measurement takes); at "
                f"{base_n} robots, {base_rate:g} Hz instead, against this design at that size",
                flush=True,
            )
        layout = key.layout if (base_n, base_rate) == (key.robots, key.rate) else "auto"
        ours: dict[str, Row] = {}
        try:
            for source in ("poses", "odom"):
                found = find_row(rows, base_n, base_rate, source)
                if found is None:
                    found = measure(base_n, base_rate, source, layout, args.warmup, args.window)
                    rows.append(found)
                    print("  ".join(found.cells()), flush=True)
                ours[source] = found
            naive = measure_naive(base_n, base_rate, args.warmup, args.window)
        except Exception as exc:  # the rows measured so far must not be lost
            print(f"baseline: FAILED, no efficiency ratio in this run: {exc}", flush=True)
    if naive is not None:
        rows.append(naive)
        print("  ".join(naive.cells()), flush=True)
        poses, odom = ours["poses"], ours["odom"]
        ratio = naive.cpu_us_per_robot_step / poses.cpu_us_per_robot_step
        ratio_odom = naive.cpu_us_per_robot_step / odom.cpu_us_per_robot_step
        ratios = (
            f" baseline_robots={base_n} baseline_hz={base_rate:g}"
            f" baseline_cpu_us_per_robot_step={naive.cpu_us_per_robot_step:.1f}"
            f" efficiency_ratio={ratio:.2f} efficiency_ratio_odom={ratio_odom:.2f}"
            f" baseline_rate_hz={naive.rate_median_hz:.2f}"
        )
    ref_after = machine_reference_us()
    ref = 0.5 * (ref_before + ref_after)
    machine = (
        f"machine: bench_sim per-agent loop {ref:.2f} µs per agent-step "
        f"(before the grid {ref_before:.2f}, after {ref_after:.2f})"
    )
    print()
    print_table(rows)
    print(line)
    print(machine)
    if ratios:
        print(
            f"CPU per robot-step, {base_n} robots at {base_rate:g} Hz: this design "
            f"{poses.cpu_us_per_robot_step:.0f} µs (poses), {odom.cpu_us_per_robot_step:.0f} µs "
            f"(odom); the straightforward design {naive.cpu_us_per_robot_step:.0f} µs "
            f"(answering {naive.rate_median_hz:.1f} of {base_rate:g} Hz): efficiency "
            f"{ratio:.2f}x (poses), {ratio_odom:.2f}x (odom)"
        )
    if goals := goal_lines(rows):
        print("\nissue #13's goals this run can judge:")
        print("\n".join(goals))
    if side_by_side := discovery_lines(rows):
        print("\ndiscovery modes side by side (issue #24):")
        print("\n".join(side_by_side))
    if with_and_without := contacts_lines(measured):
        print("\ncontacts off and on side by side (issue #34):")
        print("\n".join(with_and_without))
    write_csv(rows, args.out / "bench_ros.csv")
    plot(rows, args.out / "bench_ros.png")
    (args.out / "physics.txt").write_text(line + "\n" + machine + "\n")
    print(
        f"RESULT robots={key.robots} hz={key.rate:g} source={key.source} "
        f"discovery={key.discovery} "
        f"rate_hz={key.rate_median_hz:.2f} rate_min_hz={key.rate_min_hz:.2f} rtf={key.rtf:.3f} "
        f"p99_ms={key.p99_ms:.1f} start_s={key.start_s:.1f} "
        f"cpu_us_per_robot_step={key.cpu_us_per_robot_step:.1f}{ratios} "
        f"machine_ref_us={ref:.2f} cpu_per_ref={key.cpu_us_per_robot_step / ref:.1f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

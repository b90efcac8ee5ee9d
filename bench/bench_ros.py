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

Writes ``bench_ros.csv`` and ``bench_ros.png`` to ``--out`` (default ``out/bench_ros``).
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aes_ros import scenario as scenario_mod
from aes_ros.cli.deprecated import add_deprecated
from aes_ros.cli.options import MAX_RUNS, number_type
from aes_ros.ros.discovery import SERVER_PROCESS

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sim import direct_port  # a sibling script, not a package

CLK_TCK = os.sysconf("SC_CLK_TCK")
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
#: Wall seconds the straightforward design gets until every robot moves (~10 s at 100 robots).
NAIVE_START_TIMEOUT = 120.0

#: Where a goal's bound is measured when the run does not meet it.
FLOOR = "bench/bench_floor.py (the floor of one cmd_vel topic per robot)"
PROFILE = "docs/performance.md, 'Where the goals of issue #13 stand' (py-spy profile)"
DISCOVERY = "bench/bench_startup.py --profile launch (nodes with services, no robot code)"
HOST_CORE = "one robot host's Python on one core (CPU robots % above; docs/performance.md)"


@dataclass
class Row:
    robots: int
    rate: float
    source: str
    layout: str
    start_s: float
    rtf: float
    rate_min_hz: float
    rate_median_hz: float
    p50_ms: float
    p99_ms: float
    cpu_bridge: float
    cpu_supervisor: float
    cpu_robots: float
    cpu_launcher: float
    memory_mb: float
    processes: int
    cpu_us_per_robot_step: float = float("nan")
    design: str = "aes"
    discovery: str = "simple"
    run: int = 1
    cpu_discovery: float = 0.0

    def cells(self) -> list[str]:
        return [
            f"{self.robots}",
            f"{self.rate:g}",
            self.source,
            self.layout,
            f"{self.start_s:.1f}",
            f"{self.rtf:.3f}",
            f"{self.rate_min_hz:.1f}",
            f"{self.rate_median_hz:.1f}",
            f"{self.p50_ms:.1f}",
            f"{self.p99_ms:.1f}",
            f"{self.cpu_bridge:.0f}",
            f"{self.cpu_supervisor:.0f}",
            f"{self.cpu_robots:.0f}",
            f"{self.cpu_launcher:.0f}",
            f"{self.memory_mb:.0f}",
            f"{self.cpu_us_per_robot_step:.0f}",
            self.discovery,
            f"{self.cpu_discovery:.0f}",
        ]


HEADER = [
    "robots", "Hz", "source", "layout", "start [s]", "RTF", "rate min", "rate med",
    "p50 [ms]", "p99 [ms]", "CPU bridge %", "CPU sup %", "CPU robots %", "CPU launch %",
    "mem [MB]", "CPU µs/robot-step", "discovery",
    "CPU disc %",
]  # fmt: skip


def machine_reference_us(steps: int = 30) -> float:
    """µs of one agent-step of bench_sim's per-agent Python loop on this machine now
    (the best of three runs of ``steps`` steps of the 100-robot combined scenario)."""
    sc = scenario_mod.load("combined")
    n = len(sc.nominal_positions())
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        direct_port(sc, 0, steps)
        best = min(best, time.perf_counter() - start)
    return best / (n * steps) * 1e6


def cpu_seconds(pid: int) -> float:
    """User + system CPU time [s] of a process (0 if it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def pss_mb(pid: int) -> float:
    """Proportional set size [MB] of a process: shared pages split among their users."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def measure(
    robots: int,
    rate: float,
    source: str,
    layout: str,
    warmup: float,
    window: float,
    discovery: str = "auto",
    run: int = 1,
) -> Row:
    from aes_ros.ros.launch import LaunchConfig, Launcher
    from aes_ros.ros.launch.config import resolved_discovery
    from aes_ros.ros.launch.layout import resolved_layout

    sc = scenario_mod.load("combined", {"dt": 1.0 / rate}).with_robots(robots)
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


def per_robot_step(cpu_pct: float, stats: dict, robots: int) -> float:
    """µs of CPU (bridge + supervisor + robot processes) per robot per control step
    answered: CPU [% of a core] over the commands the bridge received per second."""
    commands_per_s = stats["rate_median_hz"] * robots
    return 1e6 * (cpu_pct / 100.0) / commands_per_s if commands_per_s > 0 else float("nan")


def measure_naive(robots: int, rate: float, warmup: float, window: float) -> Row:
    """The same bridge and supervisor with the straightforward design's robots
    (:mod:`naive_swarm`: a node per robot, Odometry objects, SingleThreadedExecutor,
    10 robots per process) instead of ``aes-robot-host``."""
    import tempfile

    from aes_ros.ros.launch.commands import bridge_command, supervisor_command
    from aes_ros.ros.launch.config import LaunchConfig
    from aes_ros.ros.launch.layout import split_robots
    from aes_ros.ros.launch.monitor import Monitor
    from aes_ros.ros.launch.param_files import write_scenario
    from aes_ros.ros.launch.preflight import refuse_other_swarm
    from aes_ros.ros.launch.processes import ProcessSet, fastdds_environment

    sc = scenario_mod.load("combined", {"dt": 1.0 / rate}).with_robots(robots)
    config = LaunchConfig(sc, neighbor_source="odom", mode="kinematic", duration=0.0)
    work = Path(tempfile.mkdtemp(prefix="aes-bench-naive-"))
    scenario_file = write_scenario(sc, work / "scenario.yaml")
    procs = ProcessSet(work / "logs", fastdds_environment(dict(os.environ)))
    monitor = Monitor(robots)
    naive = Path(__file__).with_name("naive_swarm.py")
    t0 = time.monotonic()
    try:
        refuse_other_swarm(monitor.other_swarm(1.0))  # as a launch does: it would take commands
        children = [procs.start(*bridge_command(config, scenario_file)),
                    procs.start(*supervisor_command(config, scenario_file))]  # fmt: skip
        for k, ids in enumerate(split_robots(robots, -(-robots // 10))):
            cmd = [sys.executable, str(naive), "--scenario", str(scenario_file),
                   "--ids", f"{ids[0]}:{ids[-1] + 1}"]  # fmt: skip
            children.append(procs.start(f"robot_naive_{k}", cmd))
        deadline = time.monotonic() + NAIVE_START_TIMEOUT
        moved = np.zeros(robots, dtype=bool)
        checked = 0.0
        while not moved.all():
            monitor.spin_once(0.05)
            if time.monotonic() - checked > 0.5:
                checked = time.monotonic()
                refuse_other_swarm(monitor.second_swarm())
            if len(monitor.times) > 1:
                moved |= (
                    np.linalg.norm(monitor.positions[-1] - monitor.positions[0], axis=-1) > 1e-4
                )
            if time.monotonic() > deadline or any(c.proc.poll() is not None for c in children):
                still = np.flatnonzero(~moved)
                raise RuntimeError(
                    f"the naive swarm did not start within {time.monotonic() - t0:.0f} s: "
                    f"{len(still)} of {robots} robots never moved (first: {still[:10].tolist()}), "
                    f"{len(monitor.times)} pose samples; logs in {work / 'logs'}"
                )
        start_s = time.monotonic() - t0
        monitor.spin_for(warmup)
        monitor.bridge_stats()
        pids = {c.name: c.proc.pid for c in children}
        cpu0 = {name: cpu_seconds(pid) for name, pid in pids.items()}
        w0 = time.monotonic()
        monitor.spin_for(window)
        stats = monitor.bridge_stats()
        wall = time.monotonic() - w0
        cpu = {name: 100.0 * (cpu_seconds(pid) - cpu0[name]) / wall for name, pid in pids.items()}
        memory = sum(pss_mb(pid) for pid in pids.values())
    finally:
        procs.stop_all(10.0)
        monitor.close()
    robot_cpu = sum(v for k, v in cpu.items() if k.startswith("robot"))
    return Row(
        robots, rate, "odom", "naive", start_s, stats["real_time_factor"],
        stats["rate_min_hz"], stats["rate_median_hz"],
        stats["latency_p50_ms"] or float("nan"), stats["latency_p99_ms"] or float("nan"),
        cpu["sim_bridge"], cpu["supervisor"], robot_cpu, 0.0, memory, len(pids),
        per_robot_step(cpu["sim_bridge"] + cpu["supervisor"] + robot_cpu, stats, robots),
        "naive",
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


def _row(rows: list[Row], robots: int, rate: float, source: str, design: str = "aes") -> Row | None:
    """The first row of ``design`` measured at ``robots``, ``rate`` [Hz] and ``source``."""
    return next(
        (r for r in rows
         if (r.robots, r.rate, r.source, r.design) == (robots, rate, source, design)),
        None,
    )  # fmt: skip


def baseline_size(robots: int, rate: float) -> tuple[int, float]:
    """(robots, rate [Hz]) at which the straightforward design is measured for a RESULT line
    of ``robots`` at ``rate``: the same, or the reference size (``REFERENCE``) when that is
    more than ``BASELINE_MAX_ROBOTS``. Either way this design is compared at that size."""
    if robots <= BASELINE_MAX_ROBOTS:
        return robots, rate
    return REFERENCE[0], REFERENCE[1]


def goal_lines(rows: list[Row]) -> list[str]:
    """Issue #13's goals that this run's rows can judge, one line each: the goal, the
    measured figure, ``met`` or ``NOT met`` and then where the bound is shown."""
    lines = []

    def judge(goal: str, figure: str, met: bool, bound: str) -> None:
        lines.append(f"{goal:<44} {figure:<30} {'met' if met else 'NOT met; bound: ' + bound}")

    naive = next((r for r in rows if r.design == "naive"), None)
    for source, least in (("poses", 5.0), ("odom", 3.0)):
        ours = naive and _row(rows, naive.robots, naive.rate, source)
        if naive and ours:
            ratio = naive.cpu_us_per_robot_step / ours.cpu_us_per_robot_step
            judge(f"efficiency_ratio ({source}) >= {least:g}", f"{ratio:.2f}", ratio >= least,
                  FLOOR)  # fmt: skip
    if odom := _row(rows, 100, 50, "odom"):
        judge("odom, 100 robots at 50 Hz: >= 49 Hz answered",
              f"{odom.rate_median_hz:.1f} Hz (min {odom.rate_min_hz:.1f})",
              odom.rate_median_hz >= 49.0, PROFILE)  # fmt: skip
    thousand = [r for r in rows if r.robots == 1000 and r.design == "aes"]
    if thousand:
        start = min(r.start_s for r in thousand)
        judge("1000 robots: every one moving <= 15 s", f"{start:.0f} s", start <= 15.0, DISCOVERY)
    if big := _row(rows, 1000, 20, "poses"):
        share = big.rate_median_hz / big.rate
        judge("1000 robots at 20 Hz: >= 95 % answered, RTF",
              f"{100 * share:.0f} % (RTF {big.rtf:.3f})",
              share >= 0.95 and big.rtf >= 0.95, HOST_CORE)  # fmt: skip
    return lines


def discovery_lines(rows: list[Row]) -> list[str]:
    """Each size measured with more than one discovery mode, the modes side by side (every
    run: seconds until every robot moved, Hz answered, CPU per robot-step), then issue
    #24's goals those rows can judge: through a server 1000 robots at 20 Hz move within
    15 s and answer >= 95 % in every run; 100 robots at 50 Hz no worse than simple
    discovery (median answered rate within 1 %, median CPU per robot-step within 10 %)."""
    groups: dict[tuple[int, float, str, str], dict[str, list[Row]]] = {}
    for r in rows:
        if r.design == "aes":
            key = (r.robots, r.rate, r.source, r.layout)
            groups.setdefault(key, {}).setdefault(r.discovery, []).append(r)
    lines = []
    for (robots, rate, source, layout), modes in groups.items():
        if len(modes) < 2:
            continue
        lines.append(f"{robots} robots at {rate:g} Hz ({source}, {layout}):")
        for mode, runs in modes.items():
            starts = "/".join(f"{r.start_s:.1f}" for r in runs)
            hz = "/".join(f"{r.rate_median_hz:.1f}" for r in runs)
            cpu = "/".join(f"{r.cpu_us_per_robot_step:.0f}" for r in runs)
            lines.append(
                f"  {mode:<7} moving after {starts} s; answered {hz} Hz; CPU {cpu} µs/robot-step"
            )
        server, simple = modes.get("server"), modes.get("simple")
        if server and (robots, rate) == (1000, 20):
            worst_start = max(r.start_s for r in server)
            worst_share = min(r.rate_median_hz for r in server) / rate
            met = worst_start <= 15.0 and worst_share >= 0.95
            lines.append(
                f"  goal (server, every run): moving <= 15 s, >= 95 % answered: worst "
                f"{worst_start:.1f} s, {100 * worst_share:.0f} %: {'met' if met else 'NOT met'}"
            )
        if server and simple and (robots, rate) == (100, 50):
            hz = [float(np.median([r.rate_median_hz for r in m])) for m in (server, simple)]
            cpu = [float(np.median([r.cpu_us_per_robot_step for r in m])) for m in (server, simple)]
            met = hz[0] >= 0.99 * hz[1] and cpu[0] <= 1.1 * cpu[1]
            lines.append(
                f"  goal: server no worse than simple: median {hz[0]:.1f} vs {hz[1]:.1f} Hz, "
                f"{cpu[0]:.0f} vs {cpu[1]:.0f} µs/robot-step: {'met' if met else 'NOT met'}"
            )
    return lines


def print_table(rows: list[Row]) -> None:
    cells = [HEADER, *(r.cells() for r in rows)]
    widths = [max(len(c[i]) for c in cells) for i in range(len(HEADER))]
    for line in cells:
        print("  ".join(c.rjust(w) for c, w in zip(line, widths, strict=True)))


def write_csv(rows: list[Row], path: Path) -> None:
    names = list(Row.__dataclass_fields__)
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(names)
        for r in rows:
            writer.writerow([getattr(r, n) for n in names])


def plot(rows: list[Row], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    groups: dict[tuple[str, str, str], list[Row]] = {}
    for r in rows:
        groups.setdefault((r.source, r.layout, r.discovery), []).append(r)
    for (source, layout, discovery), group in groups.items():
        for rate in sorted({r.rate for r in group}):
            sel = sorted((r for r in group if r.rate == rate), key=lambda r: r.robots)
            if len(sel) < 2 and len(groups) > 1 and layout != "per-core":
                style = dict(marker="s", linestyle="none")
            else:
                style = dict(marker="o")
            label = f"{source}, {layout}, {rate:g} Hz" + (
                f", {discovery} discovery" if discovery != "simple" else ""
            )
            n = [r.robots for r in sel]
            axes[0].plot(n, [r.rtf for r in sel], label=label, **style)
            axes[1].plot(n, [r.rate_median_hz / r.rate for r in sel], label=label, **style)
            axes[2].plot(n, [r.p99_ms for r in sel], label=label, **style)
    axes[0].axhline(0.99, color="k", lw=0.8, ls="--")
    axes[0].set_ylabel("real-time factor")
    axes[1].axhline(0.99, color="k", lw=0.8, ls="--")
    axes[1].set_ylabel("median achieved rate / target rate")
    axes[2].set_ylabel("p99 latency pose → cmd_vel at bridge [ms]")
    axes[2].set_yscale("log")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_xlabel("robots")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("aes-swarm ROS 2 system on this machine (kinematic bridge, combined setup)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


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
    parser.add_argument("--warmup", type=float, default=3.0, help="wall seconds before measuring")
    parser.add_argument("--window", type=float, default=10.0, help="wall seconds measured")
    parser.add_argument("--out", type=Path, default=Path("out/bench_ros"))
    args = parser.parse_args(argv)

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
        (run, *config, mode) for run in range(1, args.runs + 1) for config in grid for mode in modes
    ]
    configs = tqdm(runs, desc="configurations", file=sys.stderr) if tqdm else runs
    for run, n, rate, source, layout, mode in configs:
        try:
            row = measure(n, rate, source, layout, args.warmup, args.window, mode, run)
        except Exception as exc:  # one failing configuration must not lose the others
            print(f"{n} robots {rate} Hz {source} {layout} {mode}: FAILED: {exc}", flush=True)
            continue
        rows.append(row)
        print("  ".join(row.cells()), flush=True)
    if not rows:
        print("RESULT failed: no configuration measured")
        return 1
    key = _row(rows, *REFERENCE) or rows[0]
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
                found = _row(rows, base_n, base_rate, source)
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

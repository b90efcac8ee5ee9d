"""Benchmark of the real ROS 2 system: control rate, real-time factor, latency, CPU, memory.

For every configuration (robot count, control rate, neighbour source, layout)
it starts the system exactly as ``aes-swarm launch`` does (bridge in kinematic
mode, supervisor, robot hosts; combined setup), waits until every robot moves
(``start_s``: wall time from launching the first process), lets it run for a
warm-up, then measures over a steady window of wall time:

- ``rate_min_hz`` / ``rate_median_hz``: ``cmd_vel`` messages per robot per wall
  second, counted where they arrive, at the bridge (``/sim/stats``);
- ``rtf``: sim seconds per wall second of the bridge;
- ``p50_ms`` / ``p99_ms``: latency from the bridge publishing a state (poses and
  odometry, stamped with its sim time) to each ``cmd_vel`` arriving at the
  bridge, counted against the newest state published before it;
- CPU of each process [% of one core] and total memory (PSS) [MB].

Usage::

    python bench/bench_ros.py                       # the standard grid (~15 min)
    python bench/bench_ros.py --robots 100 --rates 50 --sources poses --layouts per-core
    python bench/bench_ros.py --quick               # smoke version for CI (~30 s)
    python bench/bench_ros.py --physics             # only the bridge physics line

Writes ``bench_ros.csv`` and ``bench_ros.png`` to ``--out`` (default
``out/bench_ros``), prints a table and, as its last line,
``RESULT rate_hz=… rtf=… p99_ms=… start_s=…`` for 100 robots, 50 Hz, poses
(or the first configuration measured if that one is not in the grid).

The ``physics`` line runs 100 Mona robots in ``dynamic`` mode at 240 Hz
physics with no ROS at all and reports the real-time factor of pybullet alone.
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

CLK_TCK = os.sysconf("SC_CLK_TCK")
#: The standard grid: (robots, rate [Hz], source, layout).
STANDARD_GRID = [
    *[(n, r, "poses", "per-core") for n in (16, 100, 400, 1000) for r in (10, 20, 50)],
    *[(n, r, "odom", "per-core") for n in (16, 100) for r in (10, 20, 50)],
    (400, 10, "odom", "per-core"),
    (16, 20, "poses", "single"),
    (100, 20, "poses", "single"),
    (16, 20, "poses", "per-robot"),
    (16, 20, "odom", "per-robot"),
]
QUICK_GRID = [(16, 20, "poses", "per-core")]


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
        ]


HEADER = [
    "robots", "Hz", "source", "layout", "start [s]", "RTF", "rate min", "rate med",
    "p50 [ms]", "p99 [ms]", "CPU bridge %", "CPU sup %", "CPU robots %", "CPU launch %",
    "mem [MB]",
]  # fmt: skip


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
    robots: int, rate: float, source: str, layout: str, warmup: float, window: float
) -> Row:
    from aes_ros.ros.launch import LaunchConfig, Launcher

    sc = scenario_mod.load("combined", {"dt": 1.0 / rate}).with_robots(robots)
    config = LaunchConfig(
        sc, label="bench", layout=layout, neighbor_source=source, mode="kinematic",
        duration=0.0, start_timeout=600.0,
    )  # fmt: skip
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
    return Row(
        robots, rate, source, layout, start_s, stats["real_time_factor"],
        stats["rate_min_hz"], stats["rate_median_hz"],
        stats["latency_p50_ms"] or float("nan"), stats["latency_p99_ms"] or float("nan"),
        cpu["sim_bridge"], cpu["supervisor"], robot_cpu, cpu["launcher"], memory,
        len(pids) - 1,
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
    groups: dict[tuple[str, str], list[Row]] = {}
    for r in rows:
        groups.setdefault((r.source, r.layout), []).append(r)
    for (source, layout), group in groups.items():
        for rate in sorted({r.rate for r in group}):
            sel = sorted((r for r in group if r.rate == rate), key=lambda r: r.robots)
            if len(sel) < 2 and len(groups) > 1 and layout != "per-core":
                style = dict(marker="s", linestyle="none")
            else:
                style = dict(marker="o")
            label = f"{source}, {layout}, {rate:g} Hz"
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
    parser.add_argument("--layouts", default="per-core", help="single,per-core,per-robot")
    parser.add_argument("--quick", action="store_true", help="one small configuration (CI smoke)")
    parser.add_argument("--physics", action="store_true", help="only the bridge physics line")
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
    rows: list[Row] = []
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        tqdm = None
    configs = tqdm(grid, desc="configurations", file=sys.stderr) if tqdm else grid
    for n, rate, source, layout in configs:
        try:
            row = measure(n, rate, source, layout, args.warmup, args.window)
        except Exception as exc:  # one failing configuration must not lose the others
            print(f"{n} robots {rate} Hz {source} {layout}: FAILED: {exc}", flush=True)
            continue
        rows.append(row)
        print("  ".join(row.cells()), flush=True)
    if not rows:
        print("RESULT failed: no configuration measured")
        return 1
    print()
    print_table(rows)
    print(line)
    write_csv(rows, args.out / "bench_ros.csv")
    plot(rows, args.out / "bench_ros.png")
    (args.out / "physics.txt").write_text(line + "\n")
    reference = (100, 50, "poses", "per-core")
    key = next((r for r in rows if (r.robots, r.rate, r.source, r.layout) == reference), rows[0])
    print(
        f"RESULT robots={key.robots} hz={key.rate:g} source={key.source} "
        f"rate_hz={key.rate_median_hz:.2f} rate_min_hz={key.rate_min_hz:.2f} rtf={key.rtf:.3f} "
        f"p99_ms={key.p99_ms:.1f} start_s={key.start_s:.1f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

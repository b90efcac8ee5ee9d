"""What bench/bench_ros.py does with its rows: the goals they judge (:func:`goal_lines`,
:func:`discovery_lines`), the table, ``bench_ros.csv`` and ``bench_ros.png``."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

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


def find_row(
    rows: list[Row], robots: int, rate: float, source: str, design: str = "aes"
) -> Row | None:
    """The first row of ``design`` measured at ``robots``, ``rate`` [Hz] and ``source``."""
    return next(
        (r for r in rows
         if (r.robots, r.rate, r.source, r.design) == (robots, rate, source, design)),
        None,
    )  # fmt: skip


def goal_lines(rows: list[Row]) -> list[str]:
    """Issue #13's goals that this run's rows can judge, one line each: the goal, the
    measured figure, ``met`` or ``NOT met`` and then where the bound is shown."""
    lines = []

    def judge(goal: str, figure: str, met: bool, bound: str) -> None:
        lines.append(f"{goal:<44} {figure:<30} {'met' if met else 'NOT met; bound: ' + bound}")

    naive = next((r for r in rows if r.design == "naive"), None)
    for source, least in (("poses", 5.0), ("odom", 3.0)):
        ours = naive and find_row(rows, naive.robots, naive.rate, source)
        if naive and ours:
            ratio = naive.cpu_us_per_robot_step / ours.cpu_us_per_robot_step
            judge(f"efficiency_ratio ({source}) >= {least:g}", f"{ratio:.2f}", ratio >= least,
                  FLOOR)  # fmt: skip
    if odom := find_row(rows, 100, 50, "odom"):
        judge("odom, 100 robots at 50 Hz: >= 49 Hz answered",
              f"{odom.rate_median_hz:.1f} Hz (min {odom.rate_min_hz:.1f})",
              odom.rate_median_hz >= 49.0, PROFILE)  # fmt: skip
    thousand = [r for r in rows if r.robots == 1000 and r.design == "aes"]
    if thousand:
        start = min(r.start_s for r in thousand)
        judge("1000 robots: every one moving <= 15 s", f"{start:.0f} s", start <= 15.0, DISCOVERY)
    if big := find_row(rows, 1000, 20, "poses"):
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


def per_robot_step(cpu_pct: float, stats: dict, robots: int) -> float:
    """µs of CPU (bridge + supervisor + robot processes) per robot per control step
    answered: CPU [% of a core] over the commands the bridge received per second."""
    commands_per_s = stats["rate_median_hz"] * robots
    return 1e6 * (cpu_pct / 100.0) / commands_per_s if commands_per_s > 0 else float("nan")

"""How busy a process is and how fast this machine is now, for the ROS benchmarks
(``bench_ros``, ``bench_tracking``, ``bench_dashboard``): CPU seconds and memory of a
process from ``/proc``, and ``machine_ref_us``, the figure every result line carries so that
runs on machines of different speed can be compared."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from aes_ros import scenario as scenario_mod

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sim import direct_port  # a sibling script, not a package

CLK_TCK = os.sysconf("SC_CLK_TCK")


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

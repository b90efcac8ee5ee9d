"""A soak of the launched swarm: memory, files and threads of every process over a long
run, with or without processes killed on purpose (chaos).

Starts ``aes-swarm launch`` (combined setup, real time, rotating bag segments, the
dashboard on) in a ROS domain of its own, samples RSS, open files and threads of each of
its processes every ``--every`` s and, with ``--chaos PERIOD``, SIGKILLs a random one
every PERIOD s. At the end it judges memory growth, recoveries, gaps in ``metrics.csv``,
messages lost outside the recovery windows, processes and shared-memory files left and
the bag segments; how each is judged: docs/reliability.md#how-bench_soak-judges-a-run.

Usage::

    python bench/bench_soak.py --duration 3600                  # the one-hour soak
    python bench/bench_soak.py --duration 3600 --chaos 60       # ... killing a process a minute
    python bench/bench_soak.py --duration 120 --robots 50 --warmup 30   # what CI runs

Prints a table per process and a last ``RESULT`` line ending ``ok=<yes|no>``; writes
``soak_samples.csv``, ``soak.json`` and ``soak.png`` to ``--out``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import random
import re
import signal
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from aes_ros.cli.options import duration_type
from aes_ros.ros.bag import bag_segments
from aes_ros.ros.launch import processes as launch_processes
from aes_ros.ros.launch.events import read_events

sys.path.insert(0, str(Path(__file__).resolve().parent))
from soak_analysis import (  # a sibling script's module, not a package
    Growth,
    Sample,
    bag_losses,
    growth,
    metric_gaps,
    readable,
    recorder_lost,
)

BIN = Path(sys.executable).parent
#: Recovery targets of docs/reliability.md [s] (the window after a death in which gaps
#: and losses are expected); processes not named here get DEFAULT_WINDOW.
WINDOWS = {"robot_host": 3.0, "supervisor": 3.0, "sim_bridge": 5.0}
DEFAULT_WINDOW = 3.0
#: What the chaos picks from (a robot host stands for all of them).
CHAOS_TARGETS = ("robot_host", "supervisor", "sim_bridge", "recorder", "dashboard")


@dataclass
class Kill:
    wall: float  # time.time() of the kill
    t: float  # wall seconds since every robot moved
    process: str
    pid: int


@dataclass
class Verdict:
    growth: list[Growth] = field(default_factory=list)
    faults: int = 0
    recovered: int = 0
    gaps: list[tuple[float, float]] = field(default_factory=list)
    lost_outside: int = 0
    lost_inside: int = 0
    #: Lost in all segments, the deleted ones too (the recorder's own count).
    lost_total: int = 0
    #: (topic, wall time before, after, lost) of the losses outside recovery windows.
    lost_where: list[tuple[str, float, float, int]] = field(default_factory=list)
    orphans: list[str] = field(default_factory=list)
    shm_left: list[str] = field(default_factory=list)
    segments: int = 0
    segments_readable: int = 0
    #: The launcher's largest RSS [MB] after the run: while it stops and writes the outputs.
    launcher_finish_mb: float = 0.0


# --------------------------------------------------------------------- processes


def process_name(cmdline: list[str]) -> str | None:
    """Which process of a launch a command line is (None: not one of them)."""
    text = " ".join(cmdline)
    node = re.search(r"__node:=(\S+)", text)
    for needle, name in (
        ("aes-sim-bridge", "sim_bridge"), ("aes-supervisor", "supervisor"),
        ("aes-robot-host", "robot_host"), ("aes_ros.ros.recorder", "recorder"),
        ("aes-dashboard", "dashboard"), ("aes-tracker", "tracker"),
        ("aes-arena-camera", "arena_camera"), ("reaper", "reaper"),
    ):  # fmt: skip
        if needle in text:
            return node.group(1) if name == "robot_host" and node else name
    if "aes-swarm" in text and "launch" in cmdline:
        return "launcher"
    return None


def domain_processes(domain: str) -> dict[int, str]:
    """pid -> name of the live processes of ``domain``."""
    return {
        pid: process_name(argv) or Path(argv[0]).name
        for pid, argv in launch_processes.domain_processes(domain).items()
    }


def measure(pid: int) -> tuple[float, int, int] | None:
    """(RSS [MB], open files, threads) of ``pid``; None once it is gone."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
        files = len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return None
    rss = int(re.search(r"VmRSS:\s+(\d+)", status).group(1)) / 1024
    threads = int(re.search(r"Threads:\s+(\d+)", status).group(1))
    return rss, files, threads


def shm_files() -> set[str]:
    return {p.name for p in Path("/dev/shm").glob("*fastrtps*")}


def abandoned_shm(before: set[str]) -> list[str]:
    """Fast DDS shared-memory files made since ``before`` that belong to nobody: of a
    segment or port (its data, ``_el``/``_sl`` lock and ``sem.…_mutex`` files) that no
    live process maps or holds a lock on. Another swarm on the machine meanwhile keeps
    its own files mapped or locked."""
    from aes_ros.ros.launch.shared_memory import SHM_DIR, locked, mapped

    groups: dict[str, list[Path]] = {}
    for path in SHM_DIR.glob("*fastrtps*"):
        key = re.sub(r"^sem\.|(_el|_sl|_mutex)$", "", path.name)
        groups.setdefault(key, []).append(path)

    def used(path: Path) -> bool:
        try:
            return mapped(path) or locked(path) or not path.exists()
        except OSError:
            return True  # gone meanwhile: not left

    left = []
    for files in groups.values():
        if not any(used(p) for p in files):
            left += [p.name for p in files if p.name not in before]
    return sorted(left)


# --------------------------------------------------------------------------- run


def soak(
    args: argparse.Namespace, domain: str, out: Path
) -> tuple[list[Sample], list[Kill], Verdict]:
    """Run the launch, sample its processes (and kill some); the verdict at the end."""
    run_dir, bag = out / "run", out / "bag" / "run.mcap"
    bag.parent.mkdir(parents=True, exist_ok=True)
    shm_before = shm_files()
    cmd = [
        str(BIN / "aes-swarm"), "launch", "--setup", "combined", "--robots", str(args.robots),
        "--set", f"dt={1.0 / args.rate:g}", "--duration", str(args.duration),
        "--record", str(bag), "--dashboard", "0", "--out", str(run_dir),
        "--overwrite",  # the bench's own directory: every run of the bench replaces the last
    ]  # fmt: skip
    if args.bag_split != "none":
        cmd += ["--bag-split", args.bag_split, "--bag-keep", str(args.bag_keep)]
    log = out / "launch.log"
    with open(log, "w") as fh:
        launcher = subprocess.Popen(
            cmd, stdout=fh, stderr=subprocess.STDOUT, start_new_session=True
        )
    samples: list[Sample] = []
    kills: list[Kill] = []
    rng = random.Random(args.seed)
    try:
        deadline = time.monotonic() + 180
        while "robots moving" not in log.read_text():
            if time.monotonic() > deadline or launcher.poll() is not None:
                raise RuntimeError(f"the launch did not start:\n{log.read_text()[-3000:]}")
            time.sleep(0.2)
        t0 = time.monotonic()
        next_kill = args.chaos if args.chaos > 0 else float("inf")
        next_report = 0.0
        while launcher.poll() is None:
            now = time.monotonic() - t0
            for pid, name in domain_processes(domain).items():
                if (m := measure(pid)) is not None:
                    samples.append(Sample(now, name, pid, *m))
            if now >= next_kill and now < args.duration - args.chaos / 2:
                kills.append(chaos_kill(domain, rng, now))
                next_kill += args.chaos
            if now >= next_report:
                total = sum(s.rss_mb for s in samples if s.t == now)
                print(f"  t = {now:6.0f} s  {len(kills)} killed  RSS of all {total:.0f} MB",
                      flush=True)  # fmt: skip
                next_report += max(60.0, args.duration / 20)
            time.sleep(max(0.0, args.every - (time.monotonic() - t0 - now)))
    finally:
        if launcher.poll() is None:
            os.killpg(launcher.pid, signal.SIGINT)
        code = launcher.wait(300)
    print(f"launch exit code {code}; tail of its log:\n{log.read_text()[-600:]}", flush=True)
    verdict = judge(args, domain, run_dir, bag, samples, kills, shm_before)
    return samples, kills, verdict


def chaos_kill(domain: str, rng: random.Random, now: float) -> Kill:
    """SIGKILL a random process of CHAOS_TARGETS (a random robot host for that one)."""
    live = domain_processes(domain)
    choices = [(pid, name) for pid, name in live.items()
               if any(name.startswith(t) for t in CHAOS_TARGETS)]  # fmt: skip
    pid, name = rng.choice(sorted(choices))
    os.kill(pid, signal.SIGKILL)
    # the wall clock too: the losses outside recovery are placed by it
    print(f"  t = {now:6.0f} s  killed {name} (pid {pid}) at {time.strftime('%H:%M:%S')}",
          flush=True)  # fmt: skip
    return Kill(time.time(), now, name, pid)


def window_of(name: str) -> float:
    return next((w for k, w in WINDOWS.items() if name.startswith(k)), DEFAULT_WINDOW)


def judge(
    args: argparse.Namespace, domain: str, run_dir: Path, bag: Path,
    samples: list[Sample], kills: list[Kill], shm_before: set[str],
) -> Verdict:  # fmt: skip
    end = args.duration - 2 * args.every
    v = Verdict(growth=growth(samples, args.warmup, end), faults=len(kills))
    v.launcher_finish_mb = max(
        (s.rss_mb for s in samples if s.process == "launcher" and s.t > end), default=0.0
    )
    events = read_events(run_dir / "events.csv") if (run_dir / "events.csv").exists() else []
    v.recovered = sum(e["event"] == "recovered" for e in events)
    sim_windows = [
        (float(e["sim_time"]), float(e["sim_time"]) + window_of(e["process"]))
        for e in events if e["event"] == "died" and e["sim_time"]
    ]  # fmt: skip
    v.gaps = metric_gaps(run_dir / "metrics.csv", 1.0 / args.rate, sim_windows)
    wall_windows = [(k.wall, k.wall + window_of(k.process)) for k in kills]
    segments = bag_segments(bag)
    v.segments = len(segments)
    v.segments_readable = sum(readable(s) for s in segments)
    v.lost_outside, v.lost_inside = bag_losses(segments, wall_windows, v.lost_where)
    # segments --bag-keep deleted are not there to read: the recorder's own count of
    # everything it recorded; what the kept segments cannot place counts as outside
    v.lost_total = recorder_lost(run_dir / "logs" / "recorder.log", bag)
    v.lost_outside = max(v.lost_outside, v.lost_total - v.lost_inside)
    deadline = time.monotonic() + 15
    while domain_processes(domain) and time.monotonic() < deadline:
        time.sleep(0.5)
    v.orphans = [f"{name} ({pid})" for pid, name in domain_processes(domain).items()]
    v.shm_left = abandoned_shm(shm_before)
    return v


def ok(v: Verdict, args: argparse.Namespace) -> bool:
    bound = 1.0 + args.max_growth / 100.0
    launcher = [g.warm_mb * bound for g in v.growth if g.process == "launcher"]
    return (
        all(g.growth_pct <= args.max_growth and g.slope_mb_h <= args.max_slope for g in v.growth)
        and all(v.launcher_finish_mb <= b for b in launcher)
        and v.recovered >= v.faults and not v.gaps and v.lost_outside == 0
        and not v.orphans and not v.shm_left and v.segments > 0
        and v.segments_readable == v.segments
    )  # fmt: skip


def plot(samples: list[Sample], kills: list[Kill], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 5))
    for name in sorted({s.process for s in samples}):
        rows = [s for s in samples if s.process == name]
        ax.plot([s.t / 60 for s in rows], [s.rss_mb for s in rows], ".", ms=2, label=name)
    for k in kills:
        ax.axvline(k.t / 60, color="0.8", lw=0.8, zorder=0)
    ax.set_xlabel("minutes since every robot moved (grey: a process killed)")
    ax.set_ylabel("RSS [MB]")
    ax.set_title("Memory of every process of the launch")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--duration", type=duration_type(open_ended=False), default=3600.0, metavar="S",
        help="sim seconds [s] (default 3600)",
    )  # fmt: skip
    parser.add_argument("--chaos", type=float, default=0.0, metavar="PERIOD",
                        help="kill a random process every PERIOD s (0: none)")  # fmt: skip
    parser.add_argument("--robots", type=int, default=100)
    parser.add_argument("--rate", type=float, default=50.0, help="control rate [Hz]")
    parser.add_argument("--warmup", type=float, default=120.0, help="[s] after every robot moved")
    parser.add_argument("--every", type=float, default=5.0, help="sampling period [s]")
    parser.add_argument("--bag-split", default="10min", help="none: one bag")
    parser.add_argument("--bag-keep", type=int, default=3)
    parser.add_argument("--max-growth", type=float, default=10.0, help="[%%] after warm-up")
    parser.add_argument("--max-slope", type=float, default=float("inf"), help="[MB/h]")
    parser.add_argument("--seed", type=int, default=1, help="of the chaos's choices")
    parser.add_argument("--domain", default=None, help="ROS_DOMAIN_ID (default: 120 + pid %% 50)")
    parser.add_argument("--out", type=Path, default=Path("out/bench_soak"))
    args = parser.parse_args(argv)
    domain = args.domain or str(120 + os.getpid() % 50)
    os.environ["ROS_DOMAIN_ID"] = domain
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    args.out.mkdir(parents=True, exist_ok=True)
    chaos = f"every {args.chaos:g} s" if args.chaos else "off"
    print(f"soak: {args.robots} robots at {args.rate:g} Hz for {args.duration:g} s, "
          f"chaos {chaos}, domain {domain}, "
          f"outputs in {args.out}", flush=True)  # fmt: skip
    samples, kills, v = soak(args, domain, args.out)

    with open(args.out / "soak_samples.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(asdict(samples[0])) if samples else ["t"])
        writer.writeheader()
        writer.writerows(asdict(s) for s in samples)
    (args.out / "soak.json").write_text(json.dumps(
        {"args": {k: str(x) for k, x in vars(args).items()}, "kills": [asdict(k) for k in kills],
         "verdict": asdict(v)}, indent=1))  # fmt: skip
    if samples:
        plot(samples, kills, args.out / "soak.png")

    print(f"\n{'process':<16}{'warm MB':>9}{'end MB':>9}{'growth %':>10}{'MB/h':>8}"
          f"{'span s':>8}{'files':>10}{'threads':>10}")  # fmt: skip
    for g in v.growth:
        print(f"{g.process:<16}{g.warm_mb:>9.1f}{g.end_mb:>9.1f}{g.growth_pct:>10.1f}"
              f"{g.slope_mb_h:>8.1f}{g.span_s:>8.0f}{'{}->{}'.format(*g.files):>10}"
              f"{'{}->{}'.format(*g.threads):>10}")  # fmt: skip
    if v.gaps:
        print(f"gaps in metrics.csv outside recovery: {v.gaps[:10]}")
    for topic, before, after, lost in v.lost_where[:10]:
        print(f"lost outside recovery: {lost} of {topic} between "
              f"{time.strftime('%H:%M:%S', time.localtime(before))} and "
              f"{time.strftime('%H:%M:%S', time.localtime(after))}")  # fmt: skip
    rss = " ".join(f"rss_{g.process}={g.warm_mb:.0f}->{g.end_mb:.0f}MB "
                   f"slope_{g.process}={g.slope_mb_h:.1f}" for g in v.growth)  # fmt: skip
    worst = max((g.growth_pct for g in v.growth), default=float("nan"))
    print(
        f"RESULT duration_s={args.duration:g} robots={args.robots} rate_hz={args.rate:g} "
        f"chaos_s={args.chaos:g} {rss} launcher_finish_mb={v.launcher_finish_mb:.0f} "
        f"max_growth_pct={worst:.1f} faults={v.faults} "
        f"recovered={v.recovered} gaps={len(v.gaps)} lost_outside={v.lost_outside} "
        f"lost_inside={v.lost_inside} lost_total={v.lost_total} orphans={len(v.orphans)} "
        f"shm_left={len(v.shm_left)} "
        f"segments={v.segments} segments_readable={v.segments_readable} "
        f"ok={'yes' if ok(v, args) else 'no'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

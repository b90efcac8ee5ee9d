"""Benchmark of camera-in-the-loop tracking: the simulated overhead camera and the ArUco
tracker as real processes, measured against the bridge's exact poses.

For each configuration (robots, camera size, arena) it starts the system as
``aes-swarm launch --tracking camera`` does, waits until every robot moves and prints one
``RESULT`` line: tracked frames per second, detection rate, position and heading error,
latency from exposure to ``/swarm/poses`` (and its camera and tracker parts), RTF, CPU and
``machine_ref_us``; with ``--closed-loop`` (the default unless ``--quick``) also ψ̄ of
interleaved tracked and exact launches. The targets are printed beside the values. What
each figure means and how it is measured: docs/real_robots.md#how-bench_trackingpy-measures.

Usage::

    python bench/bench_tracking.py --out docs/perf/tracking  # both configurations, closed loop
    python bench/bench_tracking.py --quick                   # 25 robots 1280x960, no closed loop
    python bench/bench_tracking.py --robots 9 --camera-size 640x480 --arena 1.2x0.9 \\
        --duration 5 --quick

Writes ``bench_tracking.txt`` and ``bench_tracking.csv`` to ``--out`` (default
``out/bench_tracking``). Run it in a ROS domain of its own.
"""

from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from aes_ros import scenario as scenario_mod
from aes_ros.cli.deprecated import add_deprecated

sys.path.insert(0, str(Path(__file__).resolve().parent))
from process_stats import cpu_seconds, machine_reference_us  # a sibling script, not a package
from tracking_probe import Probe, analyse, in_process_times
from tracking_report import print_row, print_targets, result_line, say, write_csv

#: (robots, camera (W, H) [px], arena (W, H) [m]): the issue's two configurations.
CONFIGS = [(25, (1280, 960), (2.0, 1.5)), (100, (2048, 1536), (4.0, 3.0))]


# ------------------------------------------------------------------------------ measuring


def centred_arena(sc, size: tuple[float, float]) -> tuple[float, float, float, float]:
    """``(x_min, x_max, y_min, y_max)`` [m] of ``size`` centred on the formation."""
    cx, cy = sc.nominal_positions().mean(axis=0)
    w, h = size
    return (round(cx - w / 2, 3), round(cx + w / 2, 3), round(cy - h / 2, 3), round(cy + h / 2, 3))


def measure(
    n: int, size, arena_size, warmup: float, window: float, seed: int, preset: str = "none"
) -> dict:
    """One configuration, robots moving on the tracker's poses (module docstring)."""
    from aes_ros.ros.launch import LaunchConfig, Launcher
    from aes_ros.ros.launch.tracking_arena import tracking_arena

    sc = scenario_mod.load("combined").with_robots(n)
    arena = centred_arena(sc, arena_size) if arena_size else tracking_arena(sc)
    # bodies touch, as real Monas do: overlapping rims are what loses a marker
    sc = sc.with_overrides({"arena": list(arena), "contacts": True}, "bench_tracking")
    config = LaunchConfig(
        sc, label="bench_tracking", tracking="camera", camera_size=tuple(size), duration=0.0,
        seed=seed, start_timeout=180.0, camera_preset=preset,
    )  # fmt: skip
    launcher = Launcher(config, say=lambda _text: None)
    probe = Probe(n)
    t0 = time.monotonic()
    try:
        launcher.start()
        launcher.wait_until_moving()
        start_s = time.monotonic() - t0
        launcher.spin_for(warmup)
        pids = {c.name: c.proc.pid for c in launcher.procs.children}
        cpu0 = {name: cpu_seconds(pid) for name, pid in pids.items()}
        w0 = time.monotonic()
        launcher.spin_for(window)
        w1 = time.monotonic()
        cpu = {name: 100.0 * (cpu_seconds(pid) - cpu0[name]) / (w1 - w0)
               for name, pid in pids.items()}  # fmt: skip
    finally:
        launcher.stop()
        probe.close()
        launcher.cleanup(True)
    row = {"kind": "tracking", "robots": n, "resolution": f"{size[0]}x{size[1]}", "preset": preset,
           "arena": f"{arena[1] - arena[0]:g}x{arena[3] - arena[2]:g}"}  # fmt: skip
    row.update(analyse(probe.got, w0, w1, n))
    frames_exposed = config.camera_rate * row["sim_s"]
    truth = [probe.got.truth[k] for k in sorted(probe.got.truth)]
    render_ms, detect_ms = in_process_times(
        arena, size, np.array([p for _, p, _ in truth]), np.array([h for _, _, h in truth])
    )
    row.update(
        start_s=start_s,
        cpu_tracker_pct=cpu["tracker"],
        cpu_camera_pct=cpu["arena_camera"],
        cpu_bridge_pct=cpu["sim_bridge"],
        cpu_supervisor_pct=cpu["supervisor"],
        cpu_robots_pct=sum(v for k, v in cpu.items() if k.startswith("robot")),
        cpu_system_pct=sum(cpu.values()),
        tracker_ms_per_frame=10.0 * cpu["tracker"] * (w1 - w0) / max(row["frames"], 1),
        camera_ms_per_frame=10.0 * cpu["arena_camera"] * (w1 - w0) / max(frames_exposed, 1),
        render_ms=render_ms,
        detect_ms=detect_ms,
    )
    return row


def closed_loop_run(n: int, arena, seed: int, seconds: float, camera, tracking: bool,
                    out: Path) -> dict[str, np.ndarray]:  # fmt: skip
    """One ``aes-swarm launch`` of the combined scenario; its metrics.csv as columns."""
    from aes_ros.ros.launch.param_files import ros_value
    from aes_ros.ros.programs import executable

    argv = [
        executable("aes-swarm"), "launch", "--setup", "combined", "--robots", str(n),
        "--seed", str(seed), "--set", f"arena={ros_value(list(arena))}",
        "--duration", f"{seconds:g}", "--out", str(out),
    ]  # fmt: skip
    if tracking:
        argv += ["--tracking", "camera", "--camera-size", f"{camera[0]}x{camera[1]}"]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(argv[1:])} failed:\n{done.stdout[-2000:]}{done.stderr}")
    with (out / "metrics.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def compare(a: dict[str, np.ndarray], b: dict[str, np.ndarray], n: int) -> dict[str, float]:
    """|Δψ̄|, |Δψ̄_heading|, |Δ(F̄/N)| and the RMS distance [mm] of the centroid tracks at
    equal times since each run's start (b interpolated onto a's times, common span)."""
    ta, tb = a["t"] - a["t"][0], b["t"] - b["t"][0]
    keep = ta <= tb[-1]
    bx = np.interp(ta[keep], tb, b["centroid_x"])
    by = np.interp(ta[keep], tb, b["centroid_y"])
    d = np.hypot(a["centroid_x"][keep] - bx, a["centroid_y"][keep] - by)
    return {
        "dpsi": abs(a["alignment"].mean() - b["alignment"].mean()),
        "dpsi_heading": abs(a["heading_order"].mean() - b["heading_order"].mean()),
        "dforce_per_n": abs(a["total_force"].mean() - b["total_force"].mean()) / n,
        "centroid_rms_mm": 1e3 * float(np.sqrt(np.mean(d**2))),
    }


def closed_loop(n: int, arena_size, camera, seed: int, seconds: float, runs: int) -> dict:
    """``runs`` tracked runs and ``max(runs, 2)`` exact ones, interleaved (exact first) so
    that a drift of the machine's load touches both alike; the RESULT row (module
    docstring)."""
    sc = scenario_mod.load("combined").with_robots(n)
    arena = centred_arena(sc, arena_size)
    order = [kind for k in range(max(runs, 2))
             for kind in (("truth", "camera") if k < runs else ("truth",))]  # fmt: skip
    done: dict[str, list[dict[str, np.ndarray]]] = {"truth": [], "camera": []}
    with tempfile.TemporaryDirectory(prefix="aes-bench-tracking-") as tmp:
        for k, kind in enumerate(order):
            t0 = time.monotonic()
            m = closed_loop_run(n, arena, seed, seconds, camera, kind == "camera",
                                Path(tmp) / f"{k}_{kind}")  # fmt: skip
            done[kind].append(m)
            say(f"closed loop {kind:<6} run {len(done[kind])}: psi {m['alignment'].mean():.4f}  "
                f"psi_heading {m['heading_order'].mean():.4f}  F/N "
                f"{m['total_force'].mean() / n:.4f}  {len(m['t'])} samples over "
                f"{m['t'][-1] - m['t'][0]:.1f} s sim  "
                f"[{time.monotonic() - t0:.0f} s wall]")  # fmt: skip
    row = {"kind": "closed_loop", "robots": n, "resolution": f"{camera[0]}x{camera[1]}",
           "arena": f"{arena_size[0]:g}x{arena_size[1]:g}", "seed": seed, "seconds": seconds,
           "runs_truth": len(done["truth"]), "runs_camera": len(done["camera"])}  # fmt: skip
    columns = {"psi": "alignment", "psi_heading": "heading_order", "force_per_n": "total_force"}
    for key, column in columns.items():
        scale = 1.0 / n if key == "force_per_n" else 1.0
        for kind, found in done.items():
            means = np.array([scale * m[column].mean() for m in found])
            row[f"{key}_{kind}"] = means.mean()
            row[f"{key}_{kind}_sd"] = means.std(ddof=1) if len(means) > 1 else float("nan")
        row[f"d{key}"] = abs(row[f"{key}_camera"] - row[f"{key}_truth"])
        sd = np.nanmean([row[f"{key}_truth_sd"], row[f"{key}_camera_sd"]])  # pooled
        row[f"d{key}_se"] = sd * np.sqrt(1 / len(done["truth"]) + 1 / len(done["camera"]))
    truth = done["truth"]
    across = [compare(a, b, n) for a in truth for b in done["camera"]]
    within = [compare(a, b, n) for i, a in enumerate(truth) for b in truth[i + 1 :]]
    for key in ("dpsi", "dpsi_heading", "centroid_rms_mm"):
        row[f"{key}_pairs_camera"] = float(np.mean([c[key] for c in across]))
        row[f"{key}_pairs_truth"] = float(np.mean([c[key] for c in within]))
    return row


# ------------------------------------------------------------------------------ main


def _list(kind):
    def parse(text: str) -> list:
        return [kind(v) for v in text.split(",") if v]

    return parse


def _pair(kind):
    def parse(text: str) -> tuple:
        a, b = text.lower().split("x")
        return kind(a), kind(b)

    return parse


def configurations(args) -> list[tuple[int, tuple[int, int], tuple[float, float] | None]]:
    """(robots, camera, arena) from the options: lists zipped, a single value repeated;
    a missing camera or arena from the issue's configuration with that many robots
    (camera 1280x960, the launch's arena otherwise)."""
    if not (args.robots or args.camera_size or args.arena):
        return CONFIGS[:1] if args.quick else CONFIGS
    robots = args.robots or [c[0] for c in CONFIGS]
    count = max(len(robots), len(args.camera_size or []), len(args.arena or []))

    def pick(values, k):
        return None if not values else values[k if len(values) > 1 else 0]

    known = {c[0]: c for c in CONFIGS}
    out = []
    for k in range(count):
        n = pick(robots, k)
        default = known.get(n, (n, (1280, 960), None))
        camera = pick(args.camera_size, k) or default[1]
        out.append((n, tuple(camera), pick(args.arena, k) or default[2]))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=_list(int), help="robot counts, e.g. 25,100")
    parser.add_argument(
        "--camera-size", type=_list(_pair(int)), metavar="WxH,…",
        help="image sizes [px], one per configuration, e.g. 1280x960",
    )  # fmt: skip
    add_deprecated(parser, "--camera", "--camera-size")
    parser.add_argument("--arena", type=_list(_pair(float)), help="WxH [m] each, e.g. 2.0x1.5")
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        help="wall seconds measured per configuration (default 20, quick 8)",
    )
    add_deprecated(parser, "--seconds", "--duration")
    parser.add_argument(
        "--warmup",
        type=float,
        default=None,
        help="wall seconds after every robot moves (default 5, quick 2)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the initial state")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="one configuration, short window, no closed loop (< 2 min)",
    )
    parser.add_argument(
        "--closed-loop",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="the closed-loop comparison (default: on, off with --quick)",
    )
    parser.add_argument("--closed-loop-robots", type=int, default=25)
    parser.add_argument(
        "--closed-loop-duration", type=float, default=30.0,
        help="sim seconds of each closed-loop launch (default 30)",
    )  # fmt: skip
    add_deprecated(parser, "--closed-loop-seconds", "--closed-loop-duration")
    parser.add_argument(
        "--closed-loop-runs", type=int, default=3,
        help="tracked runs of the closed loop (exact runs: as many, at least 2)",
    )  # fmt: skip
    parser.add_argument(
        "--camera-preset", default="none", choices=("none", "realistic"),
        help="the simulated camera's effects (default none; realistic: motion blur, "
        "uneven lighting, sensor noise)",
    )  # fmt: skip
    parser.add_argument("--out", type=Path, default=Path("out/bench_tracking"))
    args = parser.parse_args(argv)  # fmt: skip
    window = args.duration if args.duration is not None else (8.0 if args.quick else 20.0)
    warmup = args.warmup if args.warmup is not None else (2.0 if args.quick else 5.0)
    closed = args.closed_loop if args.closed_loop is not None else not args.quick
    args.out.mkdir(parents=True, exist_ok=True)

    started = time.monotonic()
    say(f"bench_tracking: ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')}, "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at the start")  # fmt: skip
    ref_before = machine_reference_us()
    rows: list[dict] = []
    for n, camera, arena in configurations(args):
        try:
            row = measure(n, camera, arena, warmup, window, args.seed, args.camera_preset)
        except Exception as exc:  # one failing configuration must not lose the others
            say(f"{n} robots {camera[0]}x{camera[1]}: FAILED: {exc}")
            continue
        rows.append(row)
        print_row(row)
    if closed:
        size = {c[0]: c for c in CONFIGS}.get(args.closed_loop_robots, CONFIGS[0])
        try:
            rows.append(closed_loop(args.closed_loop_robots, size[2], size[1], args.seed,
                                    args.closed_loop_duration, args.closed_loop_runs))  # fmt: skip
        except Exception as exc:
            say(f"closed loop: FAILED: {exc}")
    ref_after = machine_reference_us()
    ref = 0.5 * (ref_before + ref_after)
    say(f"machine: bench_sim per-agent loop {ref:.2f} µs per agent-step "
        f"(before {ref_before:.2f}, after {ref_after:.2f})")  # fmt: skip
    for row in rows:
        row["machine_ref_us"] = ref
    say()
    print_targets(rows)
    say(
        f"wall time {time.monotonic() - started:.0f} s; load average {os.getloadavg()[0]:.2f} "
        "at the end (other users of the machine's cores count in it)"
    )
    if not rows:
        say("RESULT failed: nothing measured")
        return 1
    for row in rows:
        say(result_line(row))
    write_csv(rows, args.out / "bench_tracking.csv")
    (args.out / "bench_tracking.txt").write_text("\n".join(say.lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

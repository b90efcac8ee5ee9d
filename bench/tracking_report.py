"""What bench/bench_tracking.py prints and writes: the issue's targets beside each
configuration's figures, the ``RESULT`` lines, and the CSV (a sibling script's module)."""

from __future__ import annotations

import csv
import os
from pathlib import Path

#: Targets of issue #21 per (robots, resolution).
TARGETS = {
    (25, (1280, 960)): {"fps": 20.0, "detected": 0.995, "pos_mm": 2.0, "head_deg": 1.0,
                        "p99_ms": 50.0},
    (100, (2048, 1536)): {"fps": 10.0, "detected": 0.99, "pos_mm": 4.0, "head_deg": 2.0,
                          "p99_ms": 100.0, "rtf": 0.98},
}  # fmt: skip
#: |Δψ̄| and |Δψ̄_heading| of the closed loop, tracked against exact.
CLOSED_LOOP_TARGET = 0.03


class Output:
    """Everything printed also goes to a file (``bench_tracking.txt``)."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def __call__(self, text: str = "") -> None:
        print(text, flush=True)
        self.lines.append(text)


say = Output()


def judge(goal: str, figure: str, met: bool) -> str:
    return f"  {goal:<46} {figure:<26} {'met' if met else 'NOT met'}"


def target_lines(row: dict) -> list[str]:
    """The issue's targets for this configuration beside the measured values."""
    size = tuple(int(v) for v in row["resolution"].split("x"))
    goal = TARGETS.get((row["robots"], size))
    if goal is None:
        return ["  (no target of issue #21 for this configuration)"]
    lines = [
        judge(f">= {goal['fps']:g} frames/s tracked (per sim s)",
              f"{row['fps_sim']:.2f} (wall {row['fps']:.2f})",
              row["fps_sim"] >= goal["fps"] - 1e-6),
        judge(f">= {100 * goal['detected']:g} % detected", f"{100 * row['detection_rate']:.2f} %",
              row["detection_rate"] >= goal["detected"]),
        judge("  the same, of robots not overlapping another",
              f"{100 * row['detection_rate_clear']:.2f} %",
              row["detection_rate_clear"] >= goal["detected"]),
        judge(f"position RMS <= {goal['pos_mm']:g} mm", f"{row['pos_rms_mm']:.2f} mm",
              row["pos_rms_mm"] <= goal["pos_mm"]),
        judge(f"heading RMS <= {goal['head_deg']:g} deg", f"{row['heading_rms_deg']:.2f} deg",
              row["heading_rms_deg"] <= goal["head_deg"]),
        judge(f"latency p99 <= {goal['p99_ms']:g} ms", f"{row['latency_p99_ms']:.1f} ms",
              row["latency_p99_ms"] <= goal["p99_ms"]),
    ]  # fmt: skip
    if "rtf" in goal:
        lines.append(judge(f"real-time factor >= {goal['rtf']:g}", f"{row['rtf']:.3f}",
                           row["rtf"] >= goal["rtf"]))  # fmt: skip
    return lines


def print_row(row: dict) -> None:
    say(f"{row['robots']} robots, {row['resolution']} px over {row['arena']} m: "
        f"{row['frames']} tracked frames in the window ({row['sim_s']:.1f} s sim), "
        f"every robot moving after {row['start_s']:.1f} s")  # fmt: skip
    say(f"  tracked {row['fps']:.2f} frames/s wall, {row['fps_sim']:.2f} per sim s; RTF "
        f"{row['rtf']:.3f}; detected {100 * row['detection_rate']:.2f} % (diagnostics "
        f"{100 * row['diag_detection_rate']:.2f} %), of the robots whose body overlaps no "
        f"other's {100 * row['detection_rate_clear']:.2f} % ({100 * row['overlapping']:.2f} % "
        f"touch or overlap one)")  # fmt: skip
    say(f"  error: position RMS {row['pos_rms_mm']:.3f} mm (max {row['pos_max_mm']:.2f}), "
        f"heading RMS {row['heading_rms_deg']:.3f} deg")  # fmt: skip
    say(f"  latency exposure -> /swarm/poses: p50 {row['latency_p50_ms']:.1f} ms, p99 "
        f"{row['latency_p99_ms']:.1f} ms (after the exact poses: p50 "
        f"{row['latency_truth_p50_ms']:.1f}, p99 "
        f"{row['latency_truth_p99_ms']:.1f} ms)")  # fmt: skip
    say(f"    of which exposure -> camera published (camera_info here): p50 "
        f"{row['camera_part_p50_ms']:.1f}, p99 {row['camera_part_p99_ms']:.1f} ms; camera "
        f"published -> tracked poses here: p50 {row['tracker_part_p50_ms']:.1f}, p99 "
        f"{row['tracker_part_p99_ms']:.1f} ms")  # fmt: skip
    say(f"  CPU [% of a core]: tracker {row['cpu_tracker_pct']:.0f}, camera "
        f"{row['cpu_camera_pct']:.0f}, bridge {row['cpu_bridge_pct']:.0f}, supervisor "
        f"{row['cpu_supervisor_pct']:.0f}, robots {row['cpu_robots_pct']:.0f}; system "
        f"{row['cpu_system_pct']:.0f} of {100 * (os.cpu_count() or 1)}")  # fmt: skip
    say(f"  per frame: tracker {row['tracker_ms_per_frame']:.1f} ms CPU (detection alone "
        f"{row['detect_ms']:.1f} ms in-process), camera {row['camera_ms_per_frame']:.1f} ms "
        f"CPU (render alone {row['render_ms']:.1f} ms in-process)")  # fmt: skip


RESULT_FIELDS = [
    ("fps", 2), ("fps_sim", 2), ("detection_rate", 4), ("detection_rate_clear", 4),
    ("overlapping", 4), ("diag_detection_rate", 4),
    ("pos_rms_mm", 3), ("heading_rms_deg", 3), ("latency_p50_ms", 1), ("latency_p99_ms", 1),
    ("latency_truth_p50_ms", 1), ("latency_truth_p99_ms", 1), ("camera_part_p50_ms", 1),
    ("camera_part_p99_ms", 1), ("tracker_part_p50_ms", 1), ("tracker_part_p99_ms", 1), ("rtf", 3),
    ("cpu_tracker_pct", 0), ("cpu_camera_pct", 0), ("cpu_system_pct", 0),
    ("tracker_ms_per_frame", 1), ("camera_ms_per_frame", 1), ("render_ms", 1), ("detect_ms", 1),
]  # fmt: skip
CLOSED_FIELDS = [
    f"{key}_{kind}{sd}"
    for key in ("psi", "psi_heading", "force_per_n")
    for kind in ("truth", "camera")
    for sd in ("", "_sd")
] + [
    "dpsi", "dpsi_se", "dpsi_heading", "dpsi_heading_se", "dforce_per_n",
    "dpsi_pairs_camera", "dpsi_pairs_truth", "dpsi_heading_pairs_camera",
    "dpsi_heading_pairs_truth", "centroid_rms_mm_pairs_camera", "centroid_rms_mm_pairs_truth",
]  # fmt: skip


def result_line(row: dict) -> str:
    if row.get("kind") == "closed_loop":
        head = (f"RESULT closed_loop robots={row['robots']} resolution={row['resolution']} "
                f"arena={row['arena']} seed={row['seed']} seconds={row['seconds']:g} "
                f"runs_camera={row['runs_camera']} runs_truth={row['runs_truth']}")  # fmt: skip
        return (
            head
            + "".join(f" {k}={row[k]:.4f}" for k in CLOSED_FIELDS)
            + (f" machine_ref_us={row['machine_ref_us']:.2f}")
        )
    head = f"RESULT robots={row['robots']} resolution={row['resolution']} arena={row['arena']}"
    body = "".join(f" {k}={row[k]:.{digits}f}" for k, digits in RESULT_FIELDS)
    return head + body + f" machine_ref_us={row['machine_ref_us']:.2f}"


def write_csv(rows: list[dict], path: Path) -> None:
    names: list[str] = []
    for row in rows:
        names += [k for k in row if k not in names]
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, names)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: f"{v:.6g}" if isinstance(v, float) else v for k, v in row.items()})


def print_targets(rows: list[dict]) -> None:
    """Issue #21's targets beside the values of every row (configurations, closed loop)."""
    say("issue #21's targets beside this run's values:")
    for row in rows:
        if row.get("kind") == "closed_loop":
            say(f"closed loop, {row['robots']} robots, {row['seconds']:g} s of sim time, "
                f"{row['runs_camera']} tracked and {row['runs_truth']} exact runs: the mean "
                f"of the tracked runs against that of the exact ones (± its standard error); "
                f"beside it how far two runs differ on average, tracked against exact and "
                f"exact against exact (the spread of runs that are not lockstep):")  # fmt: skip
            for key, label in (("dpsi", "|Δψ̄|"), ("dpsi_heading", "|Δψ̄_heading|")):
                value = row[key]
                figure = (f"{value:.4f} ± {row[key + '_se']:.4f} (pairs "
                          f"{row[key + '_pairs_camera']:.4f}, exact pairs "
                          f"{row[key + '_pairs_truth']:.4f})")  # fmt: skip
                say(judge(f"{label} <= {CLOSED_LOOP_TARGET:g}", figure,
                          value <= CLOSED_LOOP_TARGET))  # fmt: skip
            say(f"  ψ̄ {row['psi_truth']:.4f} exact, {row['psi_camera']:.4f} tracked; "
                f"ψ̄_heading {row['psi_heading_truth']:.4f} / {row['psi_heading_camera']:.4f}; "
                f"F̄/N {row['force_per_n_truth']:.4f} / "
                f"{row['force_per_n_camera']:.4f}")  # fmt: skip
            say(f"  centroid tracks RMS apart at equal times: tracked-exact pairs "
                f"{row['centroid_rms_mm_pairs_camera']:.1f} mm, exact-exact pairs "
                f"{row['centroid_rms_mm_pairs_truth']:.1f} mm")  # fmt: skip
        else:
            say(f"{row['robots']} robots, {row['resolution']}:")
            for line in target_lines(row):
                say(line)

"""bench/bench_tracking.py: a quick run against the real camera, tracker and bridge
processes (9 robots, 640x480, a few seconds, no closed loop) so the benchmark cannot rot,
and its arithmetic (the sim/wall offset of a stamp, the closed-loop comparison) on
made-up inputs."""

from __future__ import annotations

import csv
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from helpers.bench import bench_module

REPO = Path(__file__).resolve().parents[2]
BENCH = REPO / "bench" / "bench_tracking.py"


@pytest.fixture(scope="module")
def bench() -> Iterator[ModuleType]:
    with bench_module("bench_tracking") as module:
        yield module


@pytest.mark.alone  # a benchmark: rates, latency, CPU
def test_quick_run_tracks_every_robot(ros_env, tmp_path) -> None:
    out = subprocess.run(
        [sys.executable, str(BENCH), "--quick", "--robots", "9", "--camera-size", "640x480",
         "--arena", "1.2x0.9", "--duration", "4", "--warmup", "1", "--out", str(tmp_path)],
        env=ros_env, capture_output=True, text=True, timeout=150,
    )  # fmt: skip
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    results = [line for line in out.stdout.splitlines() if line.startswith("RESULT ")]
    assert len(results) == 1, out.stdout[-3000:]
    fields = dict(item.split("=") for item in results[0].split()[1:])
    assert (fields["robots"], fields["resolution"], fields["arena"]) == ("9", "640x480", "1.2x0.9")
    values = {k: float(v) for k, v in fields.items() if k not in ("resolution", "arena")}
    assert values["detection_rate"] > 0.9
    assert values["detection_rate_clear"] > 0.9
    assert 0.0 <= values["pos_rms_mm"] < 5.0
    assert 0.0 <= values["heading_rms_deg"] < 2.0
    assert values["fps"] > 5.0 and values["fps_sim"] > 5.0  # the camera runs at 20 Hz
    assert 0.0 < values["latency_p50_ms"] <= values["latency_p99_ms"] < 2000.0
    assert 0.0 < values["latency_truth_p50_ms"] < 2000.0
    assert 0.5 < values["rtf"] < 1.5
    assert values["cpu_tracker_pct"] > 0.0 and values["cpu_camera_pct"] > 0.0
    assert values["render_ms"] > 0.0 and values["detect_ms"] > 0.0
    assert values["machine_ref_us"] > 0.0
    assert "closed_loop" not in out.stdout  # --quick leaves it out
    assert "no target of issue #21 for this configuration" in out.stdout
    rows = list(csv.DictReader((tmp_path / "bench_tracking.csv").open()))
    assert len(rows) == 1 and rows[0]["kind"] == "tracking" and rows[0]["robots"] == "9"
    assert results[0] in (tmp_path / "bench_tracking.txt").read_text()


def test_stamp_offset_is_the_fastest_clock_nearby(bench) -> None:
    sim = np.arange(0.0, 5.0, 0.05)
    delay = np.where(np.arange(len(sim)) % 3 == 0, 0.001, 0.02)  # a few come through fast
    clock = np.column_stack([100.0 + sim + delay, sim])
    with bench_module("tracking_probe") as probe:
        offsets = probe.stamp_offsets(clock, np.array([1.0, 2.5, 4.9, 20.0]))
    assert offsets[:3] == pytest.approx([100.001] * 3)
    assert np.isnan(offsets[3])  # no /clock within the window


def test_closed_loop_comparison(bench) -> None:
    t = np.arange(0.0, 10.0, 0.05)
    run = {"t": 3.0 + t, "alignment": np.full_like(t, 0.8), "heading_order": np.full_like(t, 0.7),
           "total_force": np.full_like(t, 5.0), "centroid_x": -0.05 * t,
           "centroid_y": np.zeros_like(t)}  # fmt: skip
    same = bench.compare(run, {**run, "t": 7.0 + t}, 25)  # started later, same track
    assert same == pytest.approx(
        {"dpsi": 0.0, "dpsi_heading": 0.0, "dforce_per_n": 0.0, "centroid_rms_mm": 0.0}
    )
    moved = {**run, "centroid_y": run["centroid_y"] + 0.01, "alignment": run["alignment"] - 0.02}
    diff = bench.compare(run, moved, 25)
    assert diff["centroid_rms_mm"] == pytest.approx(10.0)
    assert diff["dpsi"] == pytest.approx(0.02)

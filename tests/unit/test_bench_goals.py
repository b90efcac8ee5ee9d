"""bench/bench_ros.py's choices from its rows: issue #13's goals it judges and the size it
measures the straightforward baseline at (a script, loaded by path; no ROS)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from helpers.bench import bench_module


@pytest.fixture(scope="module")
def bench() -> Iterator[ModuleType]:
    with bench_module("bench_ros") as module:
        yield module


def row(
    bench: ModuleType, robots: int, rate: float, source: str, *, us: float, median: float,
    start: float = 5.0, rtf: float = 1.0, design: str = "aes", discovery: str = "simple",
    run: int = 1,
) -> Any:  # fmt: skip
    return bench.Row(
        robots, rate, source, "single", start, rtf, median - 0.5, median,
        10.0, 20.0, 30.0, 8.0, 60.0, 5.0, 400.0, 3, us, design, discovery, run,
    )  # fmt: skip


def test_goals_are_judged_from_the_rows_and_unmet_ones_name_their_bound(bench: ModuleType) -> None:
    rows = [
        row(bench, 100, 50, "poses", us=200.0, median=50.0),
        row(bench, 100, 50, "odom", us=1000.0, median=48.0),
        row(bench, 100, 50, "odom", us=3600.0, median=5.0, design="naive"),
        row(bench, 1000, 20, "poses", us=230.0, median=8.4, start=86.0, rtf=0.98),
    ]
    lines = bench.goal_lines(rows)
    assert len(lines) == 5
    poses, odom_ratio, odom_rate, start, thousand = lines
    assert poses.startswith("efficiency_ratio (poses) >= 5") and "18.00" in poses
    assert poses.endswith(" met")
    assert "3.60" in odom_ratio and odom_ratio.endswith(" met")  # 3600 / 1000 >= 3
    assert "48.0 Hz" in odom_rate and "NOT met; bound: docs/performance.md" in odom_rate
    assert "86 s" in start and "NOT met; bound: bench/bench_startup.py" in start
    assert "42 %" in thousand and "NOT met; bound: one robot host's Python" in thousand


def test_a_run_without_the_rows_judges_nothing(bench: ModuleType) -> None:
    assert bench.goal_lines([row(bench, 16, 20, "poses", us=200.0, median=20.0)]) == []


@pytest.mark.parametrize(
    ("robots", "rate", "expected"),
    [(16, 20, (16, 20)), (100, 50, (100, 50)), (100, 10, (100, 10)), (400, 10, (100, 50)),
     (1000, 20, (100, 50))],
)  # fmt: skip
def test_the_baseline_runs_at_the_result_size_up_to_its_limit_else_at_the_reference(
    bench: ModuleType, robots: int, rate: float, expected: tuple[int, float]
) -> None:
    assert bench.baseline_size(robots, rate) == expected
    assert bench.baseline_size(robots, rate)[0] <= bench.BASELINE_MAX_ROBOTS


def run_main(
    bench: ModuleType, monkeypatch, tmp_path: Path, *argv: str, naive_fails: bool = False,
    measure: Any = None,
) -> tuple[list, str]:  # fmt: skip
    """``bench_ros.main`` with every measurement faked (this design's by ``measure`` if
    given); returns what it measured and printed."""
    measured: list[tuple] = []

    def measure_aes(robots, rate, source, layout, warmup, window, discovery="auto", run=1,
                    contacts=None, bodies=None):  # fmt: skip
        measured.append(("aes", robots, rate, source))
        us = {"poses": 200.0, "odom": 500.0}[source] * (0.5 if robots == 1000 else 1.0)
        return row(bench, robots, rate, source, us=us, median=rate)

    def measure_naive(robots, rate, warmup, window):
        measured.append(("naive", robots, rate, "odom"))
        if naive_fails:
            raise RuntimeError("the naive swarm did not start within 120 s")
        return row(bench, robots, rate, "odom", us=3000.0, median=6.0, design="naive")

    monkeypatch.setattr(bench, "measure", measure or measure_aes)
    monkeypatch.setattr(bench, "measure_naive", measure_naive)
    monkeypatch.setattr(bench, "physics_rtf", lambda seconds: 3.0)
    monkeypatch.setattr(bench, "machine_reference_us", lambda: 10.0)
    monkeypatch.setattr(bench, "plot", lambda rows, path: None)
    printed: list[str] = []
    monkeypatch.setattr("builtins.print", lambda *a, **k: printed.append(" ".join(map(str, a))))
    assert bench.main([*argv, "--out", str(tmp_path)]) == 0
    return measured, "\n".join(printed)


def result_fields(text: str) -> dict[str, str]:
    last = text.strip().splitlines()[-1]
    assert last.startswith("RESULT ")
    return dict(item.split("=") for item in last.split()[1:])


def test_1000_robots_get_their_baseline_at_100_robots_against_this_design_there(
    bench: ModuleType, monkeypatch, tmp_path: Path
) -> None:
    measured, text = run_main(bench, monkeypatch, tmp_path, "--robots", "1000", "--rates", "20")
    # no naive swarm (nor odometry) at 1000 robots: both designs at the reference size
    assert measured == [
        ("aes", 1000, 20, "poses"), ("aes", 100, 50, "poses"), ("aes", 100, 50, "odom"),
        ("naive", 100, 50, "odom"),
    ]  # fmt: skip
    assert "baseline: not at 1000 robots (100 processes" in text
    fields = result_fields(text)
    assert (fields["robots"], fields["hz"], fields["source"]) == ("1000", "20", "poses")
    assert fields["cpu_us_per_robot_step"] == "100.0"  # the 1000-robot line's own figure
    assert (fields["baseline_robots"], fields["baseline_hz"]) == ("100", "50")
    assert float(fields["efficiency_ratio"]) == pytest.approx(3000.0 / 200.0)
    assert float(fields["efficiency_ratio_odom"]) == pytest.approx(3000.0 / 500.0)
    assert "CPU per robot-step, 100 robots at 50 Hz" in text


def test_a_small_run_measures_its_baseline_at_its_own_size_and_reuses_its_rows(
    bench: ModuleType, monkeypatch, tmp_path: Path
) -> None:
    measured, text = run_main(
        bench, monkeypatch, tmp_path, "--robots", "16", "--rates", "20", "--sources", "poses,odom"
    )
    assert measured == [
        ("aes", 16, 20, "poses"), ("aes", 16, 20, "odom"), ("naive", 16, 20, "odom")
    ]  # fmt: skip
    assert "baseline: not at" not in text
    fields = result_fields(text)
    assert (fields["baseline_robots"], fields["baseline_hz"]) == ("16", "20")
    assert float(fields["efficiency_ratio"]) == pytest.approx(15.0)


def test_no_baseline_measures_only_the_grid(bench: ModuleType, monkeypatch, tmp_path: Path) -> None:
    measured, text = run_main(
        bench, monkeypatch, tmp_path, "--robots", "1000", "--rates", "20", "--no-baseline"
    )
    assert measured == [("aes", 1000, 20, "poses")]
    assert "efficiency_ratio" not in result_fields(text)


def test_a_failed_baseline_keeps_the_measured_rows_and_says_so(
    bench: ModuleType, monkeypatch, tmp_path: Path
) -> None:
    argv = ("--robots", "1000", "--rates", "20")
    measured, text = run_main(bench, monkeypatch, tmp_path, *argv, naive_fails=True)
    assert [m[1] for m in measured] == [1000, 100, 100, 100]  # the naive one was tried
    assert "baseline: FAILED, no efficiency ratio in this run: the naive swarm" in text
    fields = result_fields(text)
    assert fields["robots"] == "1000" and "efficiency_ratio" not in fields
    assert (tmp_path / "bench_ros.csv").read_text().count("\n") == 1 + 3  # header, 3 rows


def test_discovery_modes_are_measured_interleaved_and_judged_side_by_side(
    bench: ModuleType, monkeypatch, tmp_path: Path
) -> None:
    measured: list[tuple] = []
    # through a server 1000 robots start in 12 s and answer 19.5 Hz; simply, 43 s and 17.6 Hz
    figures = {"simple": (43.0, 17.6), "server": (12.0, 19.5)}

    def measure(robots, rate, source, layout, warmup, window, discovery="auto", run=1,
                contacts=None, bodies=None):  # fmt: skip
        measured.append((run, discovery))
        start, median = figures[discovery]
        return row(bench, robots, rate, source, us=200.0, median=median, start=start + run,
                   discovery=discovery, run=run)  # fmt: skip

    argv = ["--robots", "1000", "--rates", "20", "--discovery", "simple,server", "--runs", "2"]
    _, text = run_main(bench, monkeypatch, tmp_path, *argv, "--no-baseline", measure=measure)
    assert measured == [(1, "simple"), (1, "server"), (2, "simple"), (2, "server")]
    assert "  simple  moving after 44.0/45.0 s; answered 17.6/17.6 Hz" in text
    assert "  server  moving after 13.0/14.0 s; answered 19.5/19.5 Hz" in text
    assert "worst 14.0 s, 98 %: met" in text
    assert result_fields(text)["discovery"] == "simple"  # the first row measured

    figures["server"] = (16.0, 19.5)  # one run at 17 s: the goal holds for every run
    assert "worst 17.0 s, 98 %: NOT met" in "\n".join(bench.discovery_lines(
        [measure(1000, 20, "poses", "auto", 0, 0, mode, run)
         for run in (1, 0) for mode in ("simple", "server")]
    ))  # fmt: skip


def test_server_discovery_at_100_robots_is_judged_against_simple(bench: ModuleType) -> None:
    def at(discovery: str, median: float, us: float) -> Any:
        return row(bench, 100, 50, "poses", us=us, median=median, discovery=discovery)

    same = bench.discovery_lines([at("simple", 50.0, 200.0), at("server", 49.8, 210.0)])
    assert same[-1].endswith("median 49.8 vs 50.0 Hz, 210 vs 200 µs/robot-step: met")
    slower = bench.discovery_lines([at("simple", 50.0, 200.0), at("server", 49.0, 200.0)])
    assert slower[-1].endswith(": NOT met")  # 2 % fewer steps answered
    costlier = bench.discovery_lines([at("simple", 50.0, 200.0), at("server", 50.0, 240.0)])
    assert costlier[-1].endswith(": NOT met")
    assert bench.discovery_lines([at("simple", 50.0, 200.0)]) == []  # one mode: nothing to judge

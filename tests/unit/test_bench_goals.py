"""bench/bench_ros.py judges issue #13's goals from its rows (a script, loaded by path)."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench" / "bench_ros.py"


@pytest.fixture(scope="module")
def bench() -> Iterator[ModuleType]:
    spec = importlib.util.spec_from_file_location("bench_ros", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_ros"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    yield module
    del sys.modules["bench_ros"]


def row(
    bench: ModuleType, robots: int, rate: float, source: str, *, us: float, median: float,
    start: float = 5.0, rtf: float = 1.0, design: str = "aes",
) -> Any:  # fmt: skip
    return bench.Row(
        robots, rate, source, "auto", start, rtf, median - 0.5, median,
        10.0, 20.0, 30.0, 8.0, 60.0, 5.0, 400.0, 3, us, design,
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

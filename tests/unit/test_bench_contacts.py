"""bench_ros's contacts A/B (bench/ros_contacts.py): the --contacts values and the lines that
put contacts off and on side by side against issue #34's 10 % goal."""

from __future__ import annotations

import pytest
from helpers.bench import bench_module


def row(rows, cpu_us: float, rate: float = 50.0):
    return rows.Row(
        100, rate, "poses", "auto", 5.0, 1.0, 49.0, 50.0, 1.0, 5.0,
        90.0, 10.0, 100.0, 5.0, 900.0, 5, cpu_us,
    )  # fmt: skip


def test_contacts_values_are_checked_with_the_allowed_ones() -> None:
    with bench_module("ros_rows"), bench_module("ros_contacts") as ab:
        assert ab.contacts_modes("") == [None]
        assert ab.contacts_modes("off,on") == [False, True]
        with pytest.raises(ValueError, match="--contacts: 'yes' is not allowed; use off, on"):
            ab.contacts_modes("off,yes")


def test_off_and_on_side_by_side_judge_the_goal() -> None:
    with bench_module("ros_rows") as rows, bench_module("ros_contacts") as ab:
        stats = {"contacts_per_s": 12.5, "min_centre_distance_m": 0.0799}
        measured = [
            (row(rows, 100.0), False, {"contacts_per_s": 0.0, "min_centre_distance_m": 0.15}),
            (row(rows, 108.0), True, stats),
            (row(rows, 50.0, rate=20.0), False, {}),  # no "on" for this one: no line
            (row(rows, 70.0, rate=10.0), None, {}),
        ]
        lines = ab.contacts_lines(measured)
        assert lines[0] == "100 robots at 50 Hz (poses, auto, simple):"
        assert "contacts off: CPU 100.0 µs/robot-step; 0.0 contacts/s" in lines[1]
        assert lines[2].endswith("12.5 contacts/s; closest centres 79.9 mm")
        assert lines[3] == "  goal: on within 10 % of off: 1.080x: met"
        assert len(lines) == 4
        measured[1] = (row(rows, 115.0), True, stats)
        assert ab.contacts_lines(measured)[3].endswith("1.150x: NOT met")
